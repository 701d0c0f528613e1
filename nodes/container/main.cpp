// container: runs several components in one process (see container.hpp), e.g.
//   container --name chain --component plant_sim plant_sim --peers 1 --component controller controller
// The launcher builds this command line from a launch file's `containers:` entry.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "container.hpp"
#include "container_spec.hpp"
#include "node_support.hpp"

int main(int argc, char** argv) {
  using namespace pmlsm;
  return node::run_node("container", [&] {
    const std::vector<std::string> args(argv + 1, argv + argc);
    container::ContainerCommandLine line;
    bool help = false;
    for (const auto& a : args) {
      if (a == container::kComponentFlag) break;
      help = help || a == "-h" || a == "--help";
    }
    try {
      line = container::split_container_command_line(args, container::component_type_names());
    } catch (const container::ContainerSpecError& e) {
      if (!help) {
        std::fprintf(stderr, "container: %s\n", e.what());
        return static_cast<int>(kExitBadConfig);
      }
      line.own_args.assign(args.begin(), std::find(args.begin(), args.end(), container::kComponentFlag));
    }
    CLI::App app{"Runs several components (nodes) in one process: one chain thread, samples between them in-process"};
    container::ContainerOptions options;
    node::RealtimeOptions& realtime = options.realtime;
    std::size_t stack_kib = options.stack_bytes >> 10;
    app.add_option("--name", options.name,
                   "The container's name in its messages, and its participant's on the domain (its components are "
                   "its nodes)")
        ->capture_default_str();
    app.add_option("--identity", options.identity,
                   "Secure components: the keystore identity the container's participant authenticates as, "
                   "granted its components' union (default: --name; configs/security/policy.yaml, containers:)");
    app.add_option("--stack-kib", stack_kib, "Stack of each component's fiber")
        ->check(CLI::Range(64, 1 << 20))
        ->capture_default_str();
    app.add_option("--rt-priority", realtime.rt_priority,
                   "SCHED_FIFO priority 1..99 of the chain thread, memory locked (0: normal; Fast DDS's threads "
                   "stay normal; the components' own --rt-priority and --cpu-dma-latency-us are not applied)")
        ->check(CLI::Range(0, 99));
    app.add_option("--cpu-dma-latency-us", realtime.cpu_dma_latency_us,
                   "While the container runs, keep the cores out of idle states slower to leave than this (-1: none)")
        ->check(CLI::Range(-1, 10000000));
    long publish_period_us = static_cast<long>(options.publish_period.count());
    app.add_option("--publish-period-us", publish_period_us,
                   "Realtime: the publisher thread hands what the chain wrote for readers outside the process "
                   "(recorders, other hosts, ROS 2 tools) to DDS this often; 0: the chain thread writes to DDS "
                   "itself (to compare)")
        ->check(CLI::Number & (CLI::Range(0, 0) | CLI::Range(10, 100000)))
        ->capture_default_str();
    std::string types;
    for (const auto& t : container::component_type_names()) types += (types.empty() ? "" : ", ") + t;
    app.footer("Then: --component NAME TYPE [the node's own options]... (types: " + types + ")");
    std::vector<std::string> own = line.own_args;
    std::vector<char*> own_argv{argv[0]};
    for (auto& a : own) own_argv.push_back(a.data());
    if (const auto code = node::parse_command_line(app, static_cast<int>(own_argv.size()), own_argv.data()))
      return *code;
    options.stack_bytes = stack_kib << 10;
    options.publish_period = std::chrono::microseconds(publish_period_us);
    return container::run_container(options, line.components).exit_code;
  });
}
