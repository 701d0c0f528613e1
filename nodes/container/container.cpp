#include "container.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "cycle_executor.hpp"
#include "node_support.hpp"
#include "pmlsm/dds/fiber_scheduler.hpp"
#include "pmlsm/dds/local_bus.hpp"
#include "pmlsm/dds/participant.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace pmlsm::container {

namespace {

std::vector<ComponentType> containable(const std::vector<node::RegisteredComponent>& registered) {
  std::vector<ComponentType> types;
  for (const node::RegisteredComponent& c : registered) {
    for (const node::RegisteredComponent& other : registered) {
      if (&other != &c && std::string(other.name) == c.name) {
        throw ContainerSpecError(std::string("component '") + c.name + "' is registered twice: in " + c.source +
                                 " and in " + other.source);
      }
    }
    if (c.priority != node::kRunsAlone) types.push_back(c);
  }
  return types;
}

}  // namespace

const std::vector<ComponentType>& component_types() {
  static const std::vector<ComponentType> kTypes = containable(node::registered_components());
  return kTypes;
}

std::vector<std::string> component_type_names() {
  std::vector<std::string> names;
  for (const auto& t : component_types()) names.emplace_back(t.name);
  return names;
}

namespace {

const ComponentType& type_of(const std::string& name) {
  for (const auto& t : component_types()) {
    if (name == t.name) return t;
  }
  throw ContainerSpecError("unknown component type '" + name + "'");
}

/// argv for a component: its name, then its args (valid while `args` lives).
std::vector<char*> argv_of(const std::string& name, std::vector<std::string>& args) {
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(name.c_str()));
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  return argv;
}

double seconds(const timeval& t) { return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_usec) * 1e-6; }

struct Slot {
  ComponentSpec spec;
  const ComponentType* type;
  std::unique_ptr<node::Component> component;
};

/// The slots of `specs`, the chain first (stable among equals: the file's order), so made and
/// spawned in that order.
std::vector<Slot> slots_by_priority(const std::vector<ComponentSpec>& specs) {
  std::vector<Slot> slots;
  for (const auto& spec : specs) slots.push_back({spec, &type_of(spec.type), nullptr});
  std::stable_sort(slots.begin(), slots.end(),
                   [](const Slot& a, const Slot& b) { return a.type->priority < b.type->priority; });
  return slots;
}

/// In reverse, before the bus and the scheduler.
void destroy_components(std::vector<Slot>& slots) {
  for (auto it = slots.rbegin(); it != slots.rend(); ++it) it->component.reset();
}

/// Makes every component before any runs: a bad one stops the container with nothing running
/// (those made are destroyed, its exit goes to `result`). False when one was not made.
bool make_components(const ContainerOptions& options, const node::ComponentContext& context, std::vector<Slot>& slots,
                     ContainerResult& result) {
  for (auto& slot : slots) {
    std::vector<std::string> args = slot.spec.args;
    std::vector<char*> argv = argv_of(slot.spec.name, args);
    bool made = false;
    const int code = node::run_node(slot.spec.type, [&] {
      node::MadeComponent m = slot.type->make(context, static_cast<int>(argv.size()) - 1, argv.data());
      made = m.component != nullptr;
      slot.component = std::move(m.component);
      return m.exit_code;
    });
    if (!made) {
      std::fprintf(stderr, "container %s: component %s (%s) was not made: exit %d (%s); nothing runs\n",
                   options.name.c_str(), slot.spec.name.c_str(), slot.spec.type.c_str(), code, exit_code_meaning(code));
      destroy_components(slots);
      result.exit_code = code;
      result.exits.push_back({slot.spec.name, slot.spec.type, code});
      return false;
    }
  }
  return true;
}

/// The chain thread's real-time setup, when asked for, into `realtime`; the exit code of its failure.
int set_up_chain_realtime(const ContainerOptions& options, std::optional<node::RealtimeSetup>& realtime) {
  if (options.realtime.rt_priority <= 0 && options.realtime.cpu_dma_latency_us < 0) return kExitOk;
  const int code = node::run_node("container", [&] {
    realtime.emplace(options.realtime);
    return 0;
  });
  if (code == kExitOk) {
    std::printf("container %s: real-time setup of the chain thread: %s\n", options.name.c_str(),
                realtime->summary().c_str());
  }
  return code;
}

/// A component that ended: destroyed at once (its participant leaves the domain now, as a process
/// that exits) and its exit recorded.
void component_ended(Slot& slot, int code, ContainerResult& result, const ContainerOptions& options) {
  node::run_node(slot.spec.type, [&] {
    slot.component.reset();
    return 0;
  });
  result.exits.push_back({slot.spec.name, slot.spec.type, code});
  if (code != kExitOk && result.exit_code == kExitOk) result.exit_code = code;
  std::printf("container %s: component %s (%s) exited %d (%s)\n", options.name.c_str(), slot.spec.name.c_str(),
              slot.spec.type.c_str(), code, exit_code_meaning(code));
}

/// The components with a cycle of one priority on one fiber: an executor calls their updates in
/// the slots' order. Each priority has its fiber: a component that blocks its thread inside an
/// update (a lockstep writer waiting for readers outside to acknowledge, which may need what a
/// later priority writes) hands the thread to the next priority's fiber. Any other component's
/// own loop is a fiber of its own.
void spawn_components(dds::FiberScheduler& scheduler, std::vector<Slot>& slots, ContainerResult& result,
                      const ContainerOptions& options) {
  struct Level {
    std::vector<Slot*> slots;
    std::vector<node::CycleComponent*> cycles;
  };
  std::map<int, Level> levels;  // by priority
  for (auto& slot : slots) {
    if (auto* cycle = dynamic_cast<node::CycleComponent*>(slot.component.get())) {
      Level& level = levels[slot.type->priority];
      level.slots.push_back(&slot);
      level.cycles.push_back(cycle);
      continue;
    }
    scheduler.spawn(
        slot.spec.name,
        [&slot, &result, &options] {
          const int code = node::run_node(slot.spec.type, [&] { return slot.component->run(); });
          component_ended(slot, code, result, options);
        },
        slot.type->priority);
  }
  for (auto& [priority, found] : levels) {
    scheduler.spawn(
        "cycles of priority " + std::to_string(priority),
        [&scheduler, level = found.slots, cycles = found.cycles, &result, &options, priority = priority] {
          const auto ended = [&](std::size_t index, int code) {
            component_ended(*level[index], code, result, options);
          };
          const auto failed = [&](std::size_t index, std::exception_ptr error) {
            return node::run_node(level[index]->spec.type, [&]() -> int { std::rethrow_exception(error); });
          };
          // A component's finish waits for its readers' acknowledgments: on a fiber of its own, so
          // the drive is not held by the controller's last flush.
          const auto finisher = [&](std::size_t index, int code) {
            scheduler.spawn(
                level[index]->spec.name + " (finishing)",
                [slot = level[index], cycle = cycles[index], code, &result, &options] {
                  const int final_code = node::run_node(slot->spec.type, [&] { return cycle->finish(code); });
                  component_ended(*slot, final_code, result, options);
                },
                priority);
          };
          node::run_cycles(cycles, ended, failed, finisher);
        },
        priority);
  }
}

/// Realtime: what the publisher thread handed to readers outside the process, per topic, and what
/// it could not (an observation lost is counted and named; it never held the chain).
void report_outbox(const ContainerOptions& options, const dds::Outbox& outbox, ContainerResult& result) {
  const auto totals = outbox.totals();
  if (totals.empty()) return;
  std::uint64_t queued = 0;
  std::uint64_t published = 0;
  for (const auto& [topic, c] : totals) {
    queued += c.queued;
    published += c.published;
    result.outbox_losses += c.lost();
    if (c.lost() == 0) continue;
    std::printf(
        "container %s: to readers outside: %s lost %llu of %llu sample(s) (%llu dropped, queue full; %llu refused by "
        "DDS; %llu undelivered at close)\n",
        options.name.c_str(), topic.c_str(), static_cast<unsigned long long>(c.lost()),
        static_cast<unsigned long long>(c.queued), static_cast<unsigned long long>(c.dropped),
        static_cast<unsigned long long>(c.refused), static_cast<unsigned long long>(c.undelivered));
  }
  std::printf("container %s: to readers outside (publisher thread): %llu sample(s) queued, %llu published, %s\n",
              options.name.c_str(), static_cast<unsigned long long>(queued), static_cast<unsigned long long>(published),
              result.outbox_losses == 0 ? "none lost" : (std::to_string(result.outbox_losses) + " lost").c_str());
}

/// The CPU the run took, the in-process losses and the first failure, into `result` and printed.
void report_container_run(const ContainerOptions& options, const dds::LocalBus& bus, ContainerResult& result) {
  std::printf("container %s: CPU %.3f s user + %.3f s system in %.3f s wall (%.3f cores), %llu fiber switches\n",
              options.name.c_str(), result.cpu_user_s, result.cpu_system_s, result.wall_s,
              result.wall_s > 0.0 ? (result.cpu_user_s + result.cpu_system_s) / result.wall_s : 0.0,
              static_cast<unsigned long long>(result.switches));
  // Losses between components: a reader that fell a whole history behind its writer.
  for (const auto& [topic, lost] : bus.losses()) {
    result.local_losses += lost.overwritten + lost.refused;
    std::printf(
        "container %s: in-process path: %s lost %llu sample(s) (%llu overwritten, keep last; %llu refused, "
        "keep all)\n",
        options.name.c_str(), topic.c_str(), static_cast<unsigned long long>(lost.overwritten + lost.refused),
        static_cast<unsigned long long>(lost.overwritten), static_cast<unsigned long long>(lost.refused));
  }
  if (result.local_losses == 0) std::printf("container %s: in-process path: no sample lost\n", options.name.c_str());
  report_outbox(options, bus.outbox(), result);
  for (const auto& e : result.exits) {
    if (e.exit_code != kExitOk) {
      std::fprintf(stderr, "container %s: exit %d: first failure %s (%s): %s\n", options.name.c_str(), result.exit_code,
                   e.name.c_str(), e.type.c_str(), exit_code_meaning(e.exit_code));
      break;
    }
  }
}

}  // namespace

ContainerResult run_container(const ContainerOptions& options, const std::vector<ComponentSpec>& specs) {
  ContainerResult result;
  // One DDS participant for the process, made by the first component; it outlives them all.
  dds::SharedParticipant participant(options.name, options.identity.empty() ? options.name : options.identity);
  dds::FiberScheduler scheduler(options.stack_bytes);
  dds::LocalBus bus(scheduler, options.publish_period);
  std::vector<Slot> slots = slots_by_priority(specs);
  const node::ComponentContext context{&bus, &participant};
  if (!make_components(options, context, slots, result)) return result;
  // The chain thread's real-time setup, now that every participant and its threads exist.
  std::optional<node::RealtimeSetup> realtime;
  if (const int code = set_up_chain_realtime(options, realtime); code != kExitOk) {
    destroy_components(slots);
    result.exit_code = code;
    return result;
  }
  std::printf("container %s: %zu components on one chain thread:", options.name.c_str(), slots.size());
  for (const auto& slot : slots) std::printf(" %s", slot.spec.name.c_str());
  std::printf("\n");

  rusage before{};
  getrusage(RUSAGE_SELF, &before);
  const auto wall_start = std::chrono::steady_clock::now();
  spawn_components(scheduler, slots, result, options);
  scheduler.run();
  rusage after{};
  getrusage(RUSAGE_SELF, &after);
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  result.cpu_user_s = seconds(after.ru_utime) - seconds(before.ru_utime);
  result.cpu_system_s = seconds(after.ru_stime) - seconds(before.ru_stime);
  result.switches = scheduler.switches();
  report_container_run(options, bus, result);
  return result;
}

}  // namespace pmlsm::container
