#include "foxglove_server.hpp"

// websocketpp on standalone asio (ASIO_STANDALONE, set by CMake), as the official Foxglove
// bridge uses it. Its headers are system headers here, so their warnings stay out of ours.
#include <websocketpp/config/asio_no_tls.hpp>
#include <websocketpp/server.hpp>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <set>
#include <shared_mutex>
#include <stdexcept>
#include <thread>
#include <utility>

namespace pmlsm::foxglove {

namespace {

using WsServer = websocketpp::server<websocketpp::config::asio>;
using websocketpp::connection_hdl;

// RFC 6455: a close reason fits in a control frame with the code, 123 bytes.
std::string close_reason(const std::string& reason) { return reason.substr(0, 120); }

// Close codes websocketpp itself sends when a client breaks the framing rules (bad UTF-8,
// message too big, protocol error): counted like our own closes for bad input.
bool is_bad_input_close(websocketpp::close::status::value code) {
  namespace status = websocketpp::close::status;
  return code == status::protocol_error || code == status::unsupported_data || code == status::invalid_payload ||
         code == status::policy_violation || code == status::message_too_big;
}

}  // namespace

class Server::Impl {
 public:
  Impl(ServerOptions options, std::vector<Channel> channels, std::function<void(const std::string&)> log,
       std::function<void()> on_demand_change)
      : options_(std::move(options)),
        channels_(std::move(channels)),
        log_(std::move(log)),
        on_demand_change_(std::move(on_demand_change)),
        subscribers_(channels_.size()) {
    for (std::size_t i = 0; i < channels_.size(); ++i) {
      index_of_channel_[channels_[i].id] = i;
      channel_ids_.push_back(channels_[i].id);
    }
    session_id_ = std::to_string(
        std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
    server_info_ = server_info_json(options_.name, session_id_, options_.metadata);
    advertise_ = advertise_json(channels_);
  }

  ~Impl() { stop(std::chrono::milliseconds(1000)); }

  void start() {
    asio::error_code address_error;
    const auto address = asio::ip::make_address(options_.address, address_error);
    if (address_error) {
      throw std::invalid_argument("--address '" + options_.address + "' is not an IP address (" +
                                  address_error.message() + ")");
    }
    // Our own log lines say what happened; websocketpp's access and error logs would repeat it per frame.
    ws_.clear_access_channels(websocketpp::log::alevel::all);
    ws_.clear_error_channels(websocketpp::log::elevel::all);
    ws_.init_asio();
    ws_.set_reuse_addr(true);  // a restarted bridge binds at once, not after TIME_WAIT
    ws_.set_max_message_size(options_.max_request_bytes);
    ws_.set_max_http_body_size(options_.max_request_bytes);
    ws_.set_open_handshake_timeout(5000);   // [ms] a client that connects and says nothing
    ws_.set_close_handshake_timeout(1000);  // [ms] a client that does not answer a close
    ws_.set_user_agent(options_.name);
    // The kernel's send buffer is part of a slow client's backlog too: left to autotuning it
    // grows to megabytes (tcp_wmem), seconds of stale data queued where nothing counts it.
    // Capped like websocketpp's buffer, the backlog stays bounded and the drops are ours.
    // Set once the connection is accepted (the socket-init handler runs before the socket is open).
    ws_.set_tcp_pre_init_handler([this](connection_hdl hdl) {
      asio::error_code ignored;  // a refused size leaves the kernel's default: still correct, less bounded
      ws_.get_con_from_hdl(hdl)->get_socket().set_option(
          asio::socket_base::send_buffer_size(static_cast<int>(options_.max_buffered_bytes)), ignored);
    });
    ws_.set_validate_handler([this](connection_hdl h) { return validate(h); });
    ws_.set_open_handler([this](connection_hdl h) { on_open(h); });
    ws_.set_close_handler([this](connection_hdl h) { on_close(h); });
    ws_.set_fail_handler([this](connection_hdl h) { on_fail(h); });
    ws_.set_message_handler([this](connection_hdl h, WsServer::message_ptr m) { on_message(h, m); });

    websocketpp::lib::error_code ec;
    ws_.listen(asio::ip::tcp::endpoint(address, options_.port), ec);
    if (ec) {
      throw std::runtime_error("cannot listen on " + options_.address + ":" + std::to_string(options_.port) + ": " +
                               ec.message());
    }
    asio::error_code endpoint_error;
    port_ = ws_.get_local_endpoint(endpoint_error).port();
    ws_.start_accept(ec);
    if (ec || endpoint_error) {
      throw std::runtime_error("cannot accept on " + options_.address + ":" + std::to_string(options_.port) + ": " +
                               (ec ? ec.message() : endpoint_error.message()));
    }
    network_thread_ = std::thread([this] {
      try {
        ws_.run();
      } catch (const std::exception& e) {
        log_(std::string("network thread failed: ") + e.what());
        failed_ = true;
      }
    });
  }

  void stop(std::chrono::milliseconds close_grace) {
    if (!network_thread_.joinable()) return;
    asio::post(ws_.get_io_service(), [this] {
      websocketpp::lib::error_code ec;
      ws_.stop_listening(ec);
      for (const auto& [hdl, client] : clients_) {
        client->closed_by_bridge = true;
        ws_.close(hdl, websocketpp::close::status::going_away, "bridge stopping", ec);
      }
    });
    const auto deadline = std::chrono::steady_clock::now() + close_grace;
    while (std::chrono::steady_clock::now() < deadline && !failed_) {
      {
        std::shared_lock<std::shared_mutex> lock(clients_mutex_);
        if (clients_.empty()) break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // polling a shutdown, bounded by the deadline
    }
    ws_.stop();
    network_thread_.join();
  }

  std::uint16_t port() const { return port_; }
  bool failed() const { return failed_; }

  std::size_t subscriber_count(ChannelId channel) const {
    const auto found = index_of_channel_.find(channel);
    return found == index_of_channel_.end() ? 0 : subscribers_[found->second].load(std::memory_order_acquire);
  }

  void publish(ChannelId channel, std::uint64_t receive_time_ns, const std::uint8_t* payload, std::size_t bytes) {
    if (subscriber_count(channel) == 0) return;
    std::shared_lock<std::shared_mutex> lock(clients_mutex_);
    for (const auto& [hdl, client] : clients_) {
      std::lock_guard<std::mutex> client_lock(client->mutex);
      const auto subscription = client->session.subscription_for(channel);
      if (!subscription) continue;
      if (!client->queue.push(message_data_frame(*subscription, receive_time_ns, payload, bytes))) {
        frames_dropped_.fetch_add(1, std::memory_order_relaxed);
      }
      if (!client->flush_pending) {
        // One pending flush per client at a time: the network thread sends the whole queue.
        client->flush_pending = true;
        asio::post(ws_.get_io_service(), [this, weak = std::weak_ptr<Client>(client)] {
          if (auto c = weak.lock()) flush(*c);
        });
      }
    }
  }

  ServerCounters counters() const {
    ServerCounters c;
    {
      std::shared_lock<std::shared_mutex> lock(clients_mutex_);
      c.clients_connected = clients_.size();
    }
    c.clients_peak = clients_peak_.load();
    c.connections_total = connections_total_.load();
    c.handshakes_failed = handshakes_failed_.load();
    c.frames_sent = frames_sent_.load();
    c.frames_dropped = frames_dropped_.load();
    c.bad_requests = bad_requests_.load();
    c.closed_for_bad_input = closed_for_bad_input_.load();
    return c;
  }

 private:
  struct Client {
    Client(std::uint64_t client_id, connection_hdl handle, std::string from, std::vector<ChannelId> channels,
           std::size_t queue_frames)
        : id(client_id),
          hdl(std::move(handle)),
          remote(std::move(from)),
          session(std::move(channels)),
          queue(queue_frames) {}
    const std::uint64_t id;
    const connection_hdl hdl;
    const std::string remote;
    std::mutex mutex;  // guards session, queue, flush_pending (network and bridge threads)
    ClientSession session;
    FrameQueue queue;
    bool flush_pending = false;
    // Network thread only:
    bool closed_by_bridge = false;
    bool closed_for_bad_input = false;
    std::uint64_t sent = 0;
    std::uint64_t dropped_at_socket = 0;
  };
  using ClientMap = std::map<connection_hdl, std::shared_ptr<Client>, std::owner_less<connection_hdl>>;

  std::shared_ptr<Client> find(const connection_hdl& hdl) const {
    std::shared_lock<std::shared_mutex> lock(clients_mutex_);
    const auto found = clients_.find(hdl);
    return found == clients_.end() ? nullptr : found->second;
  }

  // Handshake: the client must offer our subprotocol (spec), and there is room for it. Room
  // counts the clients admitted but not yet open too: websocketpp validates a handshake, then
  // writes its answer and opens the connection only when that write completes, so in a burst
  // many handshakes are validated before the first opens (200 at once let 34 past a limit of 8).
  bool validate(connection_hdl hdl) {
    auto con = ws_.get_con_from_hdl(hdl);
    std::size_t connected = 0;
    {
      std::shared_lock<std::shared_mutex> lock(clients_mutex_);
      connected = clients_.size();
    }
    if (connected + admitted_.size() >= options_.max_clients) {
      con->set_status(websocketpp::http::status_code::service_unavailable);
      con->set_body("server full: " + std::to_string(options_.max_clients) + " clients\n");
      return false;
    }
    const auto& offered = con->get_requested_subprotocols();
    if (std::find(offered.begin(), offered.end(), kSubprotocol) == offered.end()) {
      con->set_status(websocketpp::http::status_code::bad_request);
      con->set_body(std::string("WebSocket subprotocol ") + kSubprotocol + " required\n");
      return false;
    }
    con->select_subprotocol(kSubprotocol);
    admitted_.insert(hdl);
    return true;
  }

  void on_open(connection_hdl hdl) {
    admitted_.erase(hdl);
    auto con = ws_.get_con_from_hdl(hdl);
    auto client = std::make_shared<Client>(next_client_id_++, hdl, con->get_remote_endpoint(), channel_ids_,
                                           options_.queue_frames);
    std::size_t now = 0;
    {
      std::unique_lock<std::shared_mutex> lock(clients_mutex_);
      clients_[hdl] = client;
      now = clients_.size();
    }
    if (now > clients_peak_.load()) clients_peak_.store(now);
    connections_total_.fetch_add(1);
    con->send(server_info_, websocketpp::frame::opcode::text);
    con->send(advertise_, websocketpp::frame::opcode::text);
    log_("client " + std::to_string(client->id) + " connected from " + client->remote);
  }

  void on_fail(connection_hdl hdl) {
    admitted_.erase(hdl);  // admitted, then lost before it opened
    auto con = ws_.get_con_from_hdl(hdl);
    // stop_listening() cancels the accept waiting for the next client: no client, nothing refused.
    if (con->get_ec() == asio::error::operation_aborted || con->get_transport_ec() == asio::error::operation_aborted ||
        con->get_ec() == websocketpp::transport::error::operation_aborted) {
      return;
    }
    handshakes_failed_.fetch_add(1);
    log_("connection from " + con->get_remote_endpoint() + " refused: " + con->get_ec().message() + " (HTTP " +
         std::to_string(static_cast<int>(con->get_response_code())) + ")");
  }

  void on_close(connection_hdl hdl) {
    admitted_.erase(hdl);
    std::shared_ptr<Client> client;
    {
      std::unique_lock<std::shared_mutex> lock(clients_mutex_);
      const auto found = clients_.find(hdl);
      if (found == clients_.end()) return;
      client = found->second;
      clients_.erase(found);
    }
    std::vector<ChannelId> subscribed;
    std::uint64_t dropped_in_queue = 0;
    {
      std::lock_guard<std::mutex> lock(client->mutex);
      subscribed = client->session.subscribed_channels();
      dropped_in_queue = client->queue.dropped();
    }
    change_subscribers(subscribed, -1);
    auto con = ws_.get_con_from_hdl(hdl);
    const auto local_code = con->get_local_close_code();
    if (!client->closed_for_bad_input && is_bad_input_close(local_code)) {
      // websocketpp ended it for breaking the framing rules (bad UTF-8, too big, ...).
      bad_requests_.fetch_add(1);
      closed_for_bad_input_.fetch_add(1);
    }
    // websocketpp echoes a client's close with the client's code, so "who closed" is ours to know.
    const bool bridge_closed = client->closed_by_bridge || is_bad_input_close(local_code);
    const std::string how =
        bridge_closed ? "closed by the bridge: " + std::to_string(local_code) + " " + con->get_local_close_reason()
                      : "closed by the client: " + std::to_string(con->get_remote_close_code()) + " " +
                            con->get_remote_close_reason();
    log_("client " + std::to_string(client->id) + " disconnected (" + how + "), " + std::to_string(client->sent) +
         " frames sent, " + std::to_string(dropped_in_queue + client->dropped_at_socket) + " dropped");
  }

  void on_message(connection_hdl hdl, const WsServer::message_ptr& message) {
    auto client = find(hdl);
    if (!client) return;
    SessionReply reply;
    std::uint64_t bad_before = 0;
    std::uint64_t bad_after = 0;
    {
      std::lock_guard<std::mutex> lock(client->mutex);
      bad_before = client->session.bad_requests();
      const std::string& payload = message->get_payload();
      if (message->get_opcode() == websocketpp::frame::opcode::text) {
        reply = client->session.on_text(payload);
      } else {
        reply = client->session.on_binary(reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size());
      }
      bad_after = client->session.bad_requests();
    }
    bad_requests_.fetch_add(bad_after - bad_before);
    change_subscribers(reply.channels_subscribed, +1);
    change_subscribers(reply.channels_unsubscribed, -1);
    auto con = ws_.get_con_from_hdl(hdl);
    websocketpp::lib::error_code ec;
    for (const auto& text : reply.texts) con->send(text, websocketpp::frame::opcode::text);
    if (reply.close) {
      client->closed_by_bridge = true;
      client->closed_for_bad_input = true;
      closed_for_bad_input_.fetch_add(1);
      log_("client " + std::to_string(client->id) + ": " + reply.close->second);
      con->close(reply.close->first, close_reason(reply.close->second), ec);
    }
  }

  void change_subscribers(const std::vector<ChannelId>& channels, int delta) {
    bool demand_changed = false;
    for (const ChannelId channel : channels) {
      const auto found = index_of_channel_.find(channel);
      if (found == index_of_channel_.end()) continue;
      auto& count = subscribers_[found->second];
      const std::size_t before = delta > 0 ? count.fetch_add(1) : count.fetch_sub(1);
      if ((delta > 0 && before == 0) || (delta < 0 && before == 1)) demand_changed = true;
    }
    if (demand_changed) on_demand_change_();
  }

  // Network thread: hands the client's queued frames to websocketpp, unless the socket is
  // already backed up beyond the cap (a slow client), in which case they are dropped.
  void flush(Client& client) {
    std::deque<std::string> frames;
    {
      std::lock_guard<std::mutex> lock(client.mutex);
      frames = client.queue.take_all();
      client.flush_pending = false;
    }
    websocketpp::lib::error_code ec;
    auto con = ws_.get_con_from_hdl(client.hdl, ec);
    if (ec || con->get_state() != websocketpp::session::state::open) return;
    for (const auto& frame : frames) {
      if (con->get_buffered_amount() > options_.max_buffered_bytes) {
        ++client.dropped_at_socket;
        frames_dropped_.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      if (!con->send(frame.data(), frame.size(), websocketpp::frame::opcode::binary)) {
        ++client.sent;
        frames_sent_.fetch_add(1, std::memory_order_relaxed);
      }
    }
  }

  const ServerOptions options_;
  const std::vector<Channel> channels_;
  std::function<void(const std::string&)> log_;
  std::function<void()> on_demand_change_;
  std::map<ChannelId, std::size_t> index_of_channel_;
  std::vector<ChannelId> channel_ids_;
  std::vector<std::atomic<std::size_t>> subscribers_;  // per channel index: clients subscribed
  std::string session_id_;
  std::string server_info_;
  std::string advertise_;

  WsServer ws_;
  std::thread network_thread_;
  std::uint16_t port_ = 0;
  std::atomic<bool> failed_{false};

  mutable std::shared_mutex clients_mutex_;  // written by the network thread, read by both
  ClientMap clients_;
  std::uint64_t next_client_id_ = 1;  // network thread only

  std::atomic<std::uint64_t> connections_total_{0};
  std::atomic<std::uint64_t> clients_peak_{0};  // written on the network thread only
  // Handshakes validated whose connection has not opened (or failed) yet: network thread only.
  std::set<connection_hdl, std::owner_less<connection_hdl>> admitted_;
  std::atomic<std::uint64_t> handshakes_failed_{0};
  std::atomic<std::uint64_t> frames_sent_{0};
  std::atomic<std::uint64_t> frames_dropped_{0};
  std::atomic<std::uint64_t> bad_requests_{0};
  std::atomic<std::uint64_t> closed_for_bad_input_{0};
};

Server::Server(ServerOptions options, std::vector<Channel> channels, std::function<void(const std::string&)> log,
               std::function<void()> on_demand_change)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(channels), std::move(log),
                                   std::move(on_demand_change))) {}

Server::~Server() = default;

void Server::start() { impl_->start(); }
std::uint16_t Server::port() const { return impl_->port(); }
void Server::stop(std::chrono::milliseconds close_grace) { impl_->stop(close_grace); }
bool Server::failed() const { return impl_->failed(); }
std::size_t Server::subscriber_count(ChannelId channel) const { return impl_->subscriber_count(channel); }
void Server::publish(ChannelId channel, std::uint64_t receive_time_ns, const std::uint8_t* payload, std::size_t bytes) {
  impl_->publish(channel, receive_time_ns, payload, bytes);
}
ServerCounters Server::counters() const { return impl_->counters(); }

}  // namespace pmlsm::foxglove
