// The WebSocket server of the bridge in-process, without DDS or a client: binding, the
// errors a user sees for a bad address or a taken port, and a stop with nobody connected.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

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
  Server server(loopback_any_port(), one_channel(), [](const std::string&) {}, [] {});
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
  Server first(loopback_any_port(), one_channel(), [](const std::string&) {}, [] {});
  first.start();
  ServerOptions same = loopback_any_port();
  same.port = first.port();
  Server second(same, one_channel(), [](const std::string&) {}, [] {});
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
  Server server(o, one_channel(), [](const std::string&) {}, [] {});
  try {
    server.start();
    FAIL() << "accepted a bad address";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'not-an-address' is not an IP address"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pmlsm::foxglove
