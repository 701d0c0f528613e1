// The WebSocket server of the bridge in-process, without DDS: binding, the errors a user sees
// for a bad address or a taken port, a stop with nobody connected, and the client limit under
// a burst of raw WebSocket handshakes.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <stdexcept>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "foxglove_server.hpp"

namespace pmlsm::foxglove {
namespace {

std::vector<Channel> one_channel() {
  Channel c;
  c.id = 1;
  c.topic = "/pmlsm/motor_feedback";
  c.schema_name = "pmlsm_msgs::msg::MotorFeedback";
  c.schema = "module pmlsm_msgs { module msg { struct MotorFeedback { double x; }; }; };";
  return {c};
}

ServerOptions loopback_any_port() {
  ServerOptions o;
  o.address = "127.0.0.1";
  o.port = 0;
  return o;
}

TEST(FoxgloveServer, PortZeroBindsAFreePortAndStops) {
  Server server(
      loopback_any_port(), one_channel(), [](const std::string&) {}, [] {});
  server.start();
  EXPECT_NE(server.port(), 0);
  EXPECT_EQ(server.subscriber_count(1), 0u);
  EXPECT_EQ(server.subscriber_count(99), 0u);
  // Nobody subscribed: publishing is a no-op, not an error.
  const std::uint8_t sample[] = {0, 1, 0, 0};
  server.publish(1, 1, sample, sizeof sample);
  server.stop();
  server.stop();  // idempotent
  EXPECT_FALSE(server.failed());
  EXPECT_EQ(server.counters().frames_sent, 0u);
}

TEST(FoxgloveServer, ATakenPortIsAClearError) {
  Server first(
      loopback_any_port(), one_channel(), [](const std::string&) {}, [] {});
  first.start();
  ServerOptions same = loopback_any_port();
  same.port = first.port();
  Server second(
      same, one_channel(), [](const std::string&) {}, [] {});
  try {
    second.start();
    FAIL() << "bound a port already in use";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1:" + std::to_string(first.port())),
              std::string::npos)
        << e.what();
  }
}

TEST(FoxgloveServer, AnAddressThatIsNotAnIpAddressIsABadOption) {
  ServerOptions o = loopback_any_port();
  o.address = "not-an-address";
  Server server(
      o, one_channel(), [](const std::string&) {}, [] {});
  try {
    server.start();
    FAIL() << "accepted a bad address";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'not-an-address' is not an IP address"), std::string::npos) << e.what();
  }
}

// A TCP connection to the server that has sent a WebSocket handshake and reads the answer's
// status line ("101" admitted, "503" server full).
class RawClient {
 public:
  explicit RawClient(std::uint16_t port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = fd_ >= 0 && ::connect(fd_, reinterpret_cast<const sockaddr*>(&to), sizeof to) == 0;
  }
  ~RawClient() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;

  bool connected() const { return connected_; }
  int fd() const { return fd_; }
  void send_handshake() const {
    const std::string request =
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
        "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n";
    ASSERT_EQ(::send(fd_, request.data(), request.size(), MSG_NOSIGNAL), static_cast<ssize_t>(request.size()));
  }
  /// Reads what has arrived; the status code once the status line is complete, else "".
  std::string status() {
    char buffer[4096];
    const ssize_t n = ::recv(fd_, buffer, sizeof buffer, MSG_DONTWAIT);
    if (n > 0) received_.append(buffer, static_cast<std::size_t>(n));
    if (n == 0) closed_ = true;
    if (received_.size() < 12 || received_.compare(0, 5, "HTTP/") != 0) return "";
    return received_.substr(9, 3);
  }
  bool closed() const { return closed_; }

 private:
  int fd_;
  bool connected_ = false;
  bool closed_ = false;
  std::string received_;
};

// Opens `count` connections, then sends every handshake at once, and waits (deadline) until
// each has its answer. Returns the number admitted (101); the others must be 503.
int burst(std::uint16_t port, std::vector<std::unique_ptr<RawClient>>& clients, int count) {
  const std::size_t first = clients.size();
  for (int i = 0; i < count; ++i) {
    clients.push_back(std::make_unique<RawClient>(port));
    EXPECT_TRUE(clients.back()->connected()) << i;
  }
  for (std::size_t i = first; i < clients.size(); ++i) clients[i]->send_handshake();
  int admitted = 0, answered = 0;
  std::vector<bool> done(clients.size() - first, false);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (answered < count && std::chrono::steady_clock::now() < deadline) {
    std::vector<pollfd> fds;
    for (std::size_t i = first; i < clients.size(); ++i) {
      if (!done[i - first]) fds.push_back(pollfd{clients[i]->fd(), POLLIN, 0});
    }
    ::poll(fds.data(), fds.size(), 100);
    for (std::size_t i = first; i < clients.size(); ++i) {
      if (done[i - first]) continue;
      const std::string code = clients[i]->status();
      if (code.empty() && !clients[i]->closed()) continue;
      done[i - first] = true;
      ++answered;
      if (code == "101") {
        ++admitted;
      } else {
        EXPECT_EQ(code, "503") << "connection " << i;
      }
    }
  }
  EXPECT_EQ(answered, count) << "handshakes unanswered after 20 s";
  return admitted;
}

// 200 handshakes at once against --max-clients 8: exactly 8 are served, never more at once;
// when 3 leave, a second burst gets exactly 3 places. (Before the limit counted handshakes
// admitted but not yet open, 200 at once got 34 and 29 clients past a limit of 8.)
TEST(FoxgloveServer, ClientLimitHoldsUnderABurstOfConnections) {
  ServerOptions options = loopback_any_port();
  options.max_clients = 8;
  Server server(
      options, one_channel(), [](const std::string&) {}, [] {});
  server.start();
  std::vector<std::unique_ptr<RawClient>> clients;
  EXPECT_EQ(burst(server.port(), clients, 200), 8);
  EXPECT_LE(server.counters().clients_peak, 8u);

  // Three admitted clients leave; wait until the server has seen them go.
  int left = 0;
  for (auto& c : clients) {
    if (left < 3 && c->status() == "101") {
      c.reset();
      ++left;
    }
  }
  ASSERT_EQ(left, 3);
  // The server's count follows a handshake's answer: a client reads "101" before the server has
  // opened its connection (websocketpp opens it once the answer's write completes), and sees its
  // close before the server does. So the count is polled for, with a deadline.
  const auto connected_reaches = [&](std::uint64_t n) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (server.counters().clients_connected != n && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // polling the server's count, bounded
    }
    return server.counters().clients_connected;
  };
  ASSERT_EQ(connected_reaches(5), 5u);
  EXPECT_EQ(burst(server.port(), clients, 50), 3);
  EXPECT_EQ(connected_reaches(8), 8u);
  EXPECT_LE(server.counters().clients_peak, 8u);
  server.stop();
}

}  // namespace
}  // namespace pmlsm::foxglove
