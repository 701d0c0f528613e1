#include "foxglove_bridge_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_foxglove_bridge_command_line(int argc, char** argv, FoxgloveBridgeOptions& opt) {
  CLI::App app{"Foxglove WebSocket bridge: the system's topics live in Foxglove (foxglove.websocket.v1)"};
  add_dds_options(app, opt.dds);
  app.add_option("--address", opt.address, "IP address to listen on")->capture_default_str();
  app.add_option("--port", opt.port, "TCP port to listen on (0: any free one, printed at start)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--topics", opt.topics, "Topics to offer, comma separated (default: every project topic)")
      ->delimiter(',');
  app.add_option("--reader-profile", opt.reader_profile,
                 "DDS reader profile of the bridged topics (default: best-effort, volatile, built in)")
      ->capture_default_str();
  app.add_option("--queue-frames", opt.queue_frames, "Frames queued per client before the oldest are dropped")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 20))
      ->capture_default_str();
  app.add_option("--client-buffer-kib", opt.client_buffer_kib, "Unsent data per client before frames are dropped [KiB]")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 20))
      ->capture_default_str();
  app.add_option("--max-clients", opt.max_clients, "Clients served at once")
      ->check(CLI::Range(std::size_t{1}, std::size_t{256}))
      ->capture_default_str();
  app.add_option("--status-period-s", opt.status_period_s, "NodeStatus heartbeat period [s]")
      ->check(CLI::Range(0.05, 60.0))
      ->capture_default_str();
  app.add_option("--batch-ms", opt.batch_ms,
                 "Forward samples at most this often [ms]: fewer wake-ups on the control machine, that much "
                 "later in Foxglove (0: at once)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--nice", opt.nice, "Scheduling niceness of the bridge (0: unchanged): the control loop goes first")
      ->check(CLI::Range(0, 19))
      ->capture_default_str();
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node
