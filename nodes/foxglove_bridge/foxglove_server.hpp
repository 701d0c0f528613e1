// The WebSocket side of the Foxglove bridge, without DDS: a websocketpp server on its own
// network thread that greets every client (serverInfo, advertise), keeps its subscriptions and
// sends it MessageData frames. The bridge thread hands samples in through publish(), which
// never waits on the network: each client has a bounded queue and a cap on what the socket
// may buffer; beyond them frames are dropped and counted. websocketpp stays out of this
// header, so the bridge's other files and the tests compile without it.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "foxglove_protocol.hpp"

namespace pmlsm::foxglove {

struct ServerOptions {
  std::string address = "0.0.0.0";
  std::uint16_t port = 8765;  // 0: any free port (see Server::port())
  std::string name = "pmlsm foxglove_bridge";
  std::map<std::string, std::string> metadata;
  /// Frames waiting between the bridge thread and a client's socket.
  std::size_t queue_frames = 1024;
  /// What websocketpp may hold unsent for one client before frames are dropped, and the
  /// size of the client socket's kernel send buffer [bytes].
  std::size_t max_buffered_bytes = 1024 * 1024;
  std::size_t max_clients = 8;
  /// Largest client message accepted; a subscribe to every channel is under 1 KiB [bytes].
  std::size_t max_request_bytes = 64 * 1024;
};

struct ServerCounters {
  std::uint64_t clients_connected = 0;  // now
  std::uint64_t clients_peak = 0;       // most connected at once since start (<= max_clients)
  std::uint64_t connections_total = 0;  // opened since start
  std::uint64_t handshakes_failed = 0;  // not a WebSocket, wrong subprotocol, server full
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_dropped = 0;        // slow clients: queue full or socket backlog over the cap
  std::uint64_t bad_requests = 0;          // client messages answered with an error or warning status
  std::uint64_t closed_for_bad_input = 0;  // connections the server ended for malformed input
};

class Server {
 public:
  /// `log` gets one line per notable event (connections, refusals); it is called on the network
  /// thread. `on_demand_change` is called (network thread) whenever a channel gains its first or
  /// loses its last subscriber: the bridge thread then opens or closes that topic's reader.
  Server(ServerOptions options, std::vector<Channel> channels, std::function<void(const std::string&)> log,
         std::function<void()> on_demand_change);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Binds and starts the network thread.
  /// @throws std::invalid_argument for an address that is not an IP address,
  ///         std::runtime_error when the address/port cannot be bound.
  void start();
  /// The bound port (the chosen one when options.port was 0).
  std::uint16_t port() const;
  /// Closes every connection ("going away"), waits up to `close_grace` for the clients to
  /// answer, then ends the network thread. Idempotent.
  void stop(std::chrono::milliseconds close_grace = std::chrono::milliseconds(1000));
  /// True when the network thread ended on an error.
  bool failed() const;

  /// Clients subscribed to `channel` now (any thread).
  std::size_t subscriber_count(ChannelId channel) const;
  /// Queues one sample for every client subscribed to `channel` (any one thread; never blocks
  /// on the network). `payload` is the CDR sample with its encapsulation header.
  void publish(ChannelId channel, std::uint64_t receive_time_ns, const std::uint8_t* payload, std::size_t bytes);

  ServerCounters counters() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pmlsm::foxglove
