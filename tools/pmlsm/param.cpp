// `pmlsm param list|get|set NODE [KEY [VALUE]]` and `pmlsm param load NODE FILE`: a running
// node's live parameters (its gains, its filter slots), as `ros2 param` does for ROS 2 nodes. The node
// (nodes/support/parameter_service) checks a change as the system file is checked and takes it at its next tick
// boundary; a refused one leaves the old value and comes back with the reason. Requests go out on
// rt/pmlsm/parameter_request, addressed by node name, each with a request_id of ours, and are
// repeated every 200 ms until the node answers on rt/pmlsm/parameter_event (a request written
// before the node's reader matched ours is lost; the node answers a repeat without applying it
// twice).
//
// `load` sets every live parameter of the node whose value differs from a system file's (a
// commissioning's result) in one request, taken together at one tick boundary or not at all.
//
// Exit 0 when the node answered and took the request, 2 when it refused it (the reason on
// stderr) or the file does not load, 3 when no node of that name answered within the timeout.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ParameterEventPubSubTypes.h"
#include "ParameterRequestPubSubTypes.h"
#include "commands.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/sim/live_parameters.hpp"

namespace pmlsm::tools {
namespace {

using Clock = std::chrono::steady_clock;
namespace msg = pmlsm_msgs::msg;
namespace ops = pmlsm_msgs::msg::ParameterRequest_Constants;

constexpr auto kRepeat = std::chrono::milliseconds(200);

struct ParamOptions {
  std::string node;
  std::string key;
  std::string value;
  double timeout_s = 5.0;
  std::string requester;
  std::string file;      ///< load: the system file
  bool dry_run = false;  ///< load: print the differences, change nothing
};

/// Sends the request (repeated until answered) and waits for the node's answer.
std::optional<msg::ParameterEvent> ask(const dds::ParticipantOptions& dds_options, const ParamOptions& o,
                                       std::uint8_t operation, const std::vector<std::string>& entries = {}) {
  dds::Wakeup wakeup;
  dds::Participant participant(with_node_name(dds_options, "pmlsm_param", "pmlsm_param"));
  auto events = participant.make_reader(dds::topics::kParameterEvent, wakeup, "pmlsm_monitor");
  auto requests = participant.make_writer(dds::topics::kParameterRequest);
  msg::ParameterRequest request;
  request.node(o.node.substr(0, 64));
  request.operation(operation);
  request.key(o.key.substr(0, 128));
  request.value(o.value.substr(0, 64));
  const auto wall_us =
      std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count();
  request.request_id((static_cast<std::uint64_t>(getpid() & 0xFFFF) << 48) |
                     (static_cast<std::uint64_t>(wall_us) & 0xFFFFFFFFFFFFULL) | 1);
  request.requester((o.requester.empty() ? user_at_host() : o.requester).substr(0, 64));
  for (const std::string& entry : entries) request.entries().push_back(entry.substr(0, 192));
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.timeout_s));
  auto next_send = Clock::now();
  msg::ParameterEvent event;
  while (!dds::stop_requested() && Clock::now() < deadline) {
    const auto seen = wakeup.generation();
    while (events.take(event)) {
      if (event.request_id() == request.request_id() && event.node().to_string() == o.node) return event;
    }
    if (Clock::now() >= next_send && requests.matched_readers() > 0) {
      requests.write(request);
      next_send = Clock::now() + kRepeat;
    }
    wakeup.wait_for(seen, std::chrono::milliseconds(20));
  }
  return std::nullopt;
}

int run_param(const dds::ParticipantOptions& dds_options, const ParamOptions& o, std::uint8_t operation) {
  if (o.node.empty() || o.node == "*")
    throw UsageError("param: name one node (as pmlsm topic echo /pmlsm/node_status shows it)");
  const auto event = ask(dds_options, o, operation);
  if (!event) {
    std::cerr << "pmlsm param: node '" << o.node << "' did not answer on domain " << dds_options.domain_id << " within "
              << o.timeout_s << " s\n";
    return kExitPeerMissing;
  }
  if (!event->accepted()) {
    // A key the node does not take live has no value to name.
    std::cerr << "pmlsm param: " << o.node << " refused: " << event->reason();
    if (event->value().size() > 0) std::cerr << " (" << o.key << " stays " << event->value() << ")";
    std::cerr << "\n";
    return kExitBadConfig;
  }
  if (operation == ops::OPERATION_LIST) {
    for (const auto& entry : event->entries()) std::cout << entry << "\n";
    std::cout << "(version " << event->version() << ")\n";
  } else if (operation == ops::OPERATION_GET) {
    std::cout << event->value() << "\n";
  } else {
    std::cout << o.node << ": " << o.key << " " << event->old_value() << " -> " << event->value() << " from tick "
              << event->effective_tick() << " (version " << event->version() << ")\n";
  }
  return kExitOk;
}

/// The node's live parameters whose values differ from the file's, as "key = value" (the file's).
std::vector<std::string> differences(const msg::ParameterEvent& listed, const SystemParams& file,
                                     std::vector<std::pair<std::string, std::string>>& node_values) {
  std::vector<std::string> entries;
  for (const auto& entry : listed.entries()) {
    const std::string text = entry.to_string();
    const auto equals = text.find(" = ");
    if (equals == std::string::npos) continue;
    const std::string key = text.substr(0, equals), now = text.substr(equals + 3);
    const std::string wanted = parameter_text(file, key);
    if (wanted == now) continue;
    entries.push_back(key + " = " + wanted);
    node_values.emplace_back(key, now);
  }
  return entries;
}

int run_load(const dds::ParticipantOptions& dds_options, const ParamOptions& o) {
  if (o.node.empty() || o.node == "*")
    throw UsageError("param: name one node (as pmlsm topic echo /pmlsm/node_status shows it)");
  SystemParams file;
  try {
    file = load_system_params(o.file);
  } catch (const ConfigError& e) {
    std::cerr << "pmlsm param: " << e.what() << " (nothing sent)\n";
    return kExitBadConfig;
  }
  const auto listed = ask(dds_options, o, ops::OPERATION_LIST);
  if (!listed) {
    std::cerr << "pmlsm param: node '" << o.node << "' did not answer on domain " << dds_options.domain_id << " within "
              << o.timeout_s << " s\n";
    return kExitPeerMissing;
  }
  std::vector<std::pair<std::string, std::string>> node_values;
  const std::vector<std::string> entries = differences(*listed, file, node_values);
  if (entries.empty()) {
    std::cout << o.node << ": its " << listed->entries().size() << " live parameters are already as in " << o.file
              << " (version " << listed->version() << ")\n";
    return kExitOk;
  }
  if (o.dry_run) {
    for (std::size_t i = 0; i < entries.size(); ++i) {
      std::cout << o.node << ": " << node_values[i].first << " " << node_values[i].second << " -> "
                << entries[i].substr(node_values[i].first.size() + 3) << " (not sent: --dry-run)\n";
    }
    return kExitOk;
  }
  const auto event = ask(dds_options, o, ops::OPERATION_SET_MANY, entries);
  if (!event) {
    std::cerr << "pmlsm param: node '" << o.node << "' did not answer the change within " << o.timeout_s << " s\n";
    return kExitPeerMissing;
  }
  if (!event->accepted()) {
    std::cerr << "pmlsm param: " << o.node << " refused the " << entries.size() << " changes from " << o.file << ": "
              << event->reason() << " (nothing changed)\n";
    return kExitBadConfig;
  }
  for (const auto& change : event->entries()) std::cout << o.node << ": " << change << "\n";
  std::cout << o.node << ": " << entries.size() << " parameters from " << o.file << " from tick "
            << event->effective_tick() << " (version " << event->version() << ")\n";
  return kExitOk;
}

}  // namespace

void add_param_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto* param = app.add_subcommand("param", "A running node's live parameters: list, get, set, load");
  param->require_subcommand(1);
  auto o = std::make_shared<ParamOptions>();
  const auto common = [o](CLI::App* sub) {
    sub->add_option("node", o->node, "The node (its name as node_status shows it, e.g. controller)")->required();
    sub->add_option("--timeout-s", o->timeout_s, "How long to wait for the node's answer")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 3600.0));
    sub->add_option("--requester", o->requester, "Who asks, for the node's log (default: user@host)");
  };
  auto* list = param->add_subcommand("list", "Every live parameter of the node with its value");
  common(list);
  list->callback([&dds_options, o, &exit_code] { exit_code = run_param(dds_options, *o, ops::OPERATION_LIST); });
  auto* get = param->add_subcommand("get", "One live parameter's value");
  common(get);
  get->add_option("key", o->key, "The system file's key path")->required();
  get->callback([&dds_options, o, &exit_code] { exit_code = run_param(dds_options, *o, ops::OPERATION_GET); });
  auto* set = param->add_subcommand("set", "Changes one live parameter at the node's next tick boundary");
  common(set);
  set->add_option("key", o->key, "The system file's key path")->required();
  set->add_option("value", o->value, "The new value, as the system file writes it")->required();
  set->callback([&dds_options, o, &exit_code] { exit_code = run_param(dds_options, *o, ops::OPERATION_SET); });
  auto* load = param->add_subcommand(
      "load", "Sets every live parameter whose value differs from a system file's, together at one tick boundary");
  common(load);
  load->add_option("file", o->file, "The system file (e.g. pmlsm commission's -o)")
      ->required()
      ->check(CLI::ExistingFile);
  load->add_flag("--dry-run", o->dry_run, "Print what differs, change nothing");
  load->callback([&dds_options, o, &exit_code] { exit_code = run_load(dds_options, *o); });
}

}  // namespace pmlsm::tools
