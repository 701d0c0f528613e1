// Every node is a component: a class with one lifecycle. It is made from its command line
// and config (parse, load, create its participant, endpoints and state: anything wrong is
// found here, before anything runs), then run once, which returns its exit code. A component
// runs alone in its process (the node's executable is a thin main: run_standalone), or beside
// others in a container process (nodes/container), on the chain thread, where its samples to the
// others go through the in-process path (pmlsm/dds/local_bus.hpp). Nothing in a component knows
// which: a component alone behaves exactly as the node did. A component with a cycle
// (CycleComponent, cycle_component.hpp: every component of the chain and its observers) has no
// loop of its own: an executor (cycle_executor.hpp) calls its update() and owns the waiting.
#pragma once

#include <memory>
#include <string>

// Only declared: every node's main includes this file, and local_bus.hpp brings in Fast DDS (about
// 2 s of CPU per file); the components that use the bus include it through node_support.hpp.
namespace pmlsm::dds {
class LocalBus;
class SharedParticipant;
}  // namespace pmlsm::dds

namespace pmlsm::node {

/// What a container gives a component; the default is a component alone in its process.
struct ComponentContext {
  /// The container's in-process path (and through it the chain thread's scheduler).
  dds::LocalBus* local_bus = nullptr;
  /// The container's one DDS participant, which its components share.
  dds::SharedParticipant* participant = nullptr;
};

class Component {
 public:
  virtual ~Component() = default;
  /// The whole run; returns the exit code (pmlsm/util/exit_codes.hpp). May throw only what
  /// run_node maps to exit codes.
  virtual int run() = 0;
};

/// What making a component gave: the component, or (none made) the exit code its command line
/// ended with (--help: 0; bad options: 2), already printed.
struct MadeComponent {
  std::unique_ptr<Component> component;
  int exit_code = 0;
};

/// Makes a component from its command line (argv[0] is its name).
/// @throws ConfigError, dds::SecurityConfigError, std::invalid_argument (exit 2) or other
/// std::exception (exit 1), as run_node maps them.
using ComponentFactory = MadeComponent (*)(const ComponentContext& context, int argc, char** argv);

/// A node's main: makes the component alone in its process and runs it; failures are mapped to
/// exit codes with one line on stderr (run_node).
int run_standalone(const char* node_name, ComponentFactory make, int argc, char** argv);

/// The priority of a component that runs alone in its process, never on a container's chain
/// thread: it blocks its thread (minutes of computing, a network server's batches, a CAN socket
/// its executor sleeps on).
inline constexpr int kRunsAlone = -1;

}  // namespace pmlsm::node

/// Registers a component, once, in its own source file, at the start of a line inside
/// `namespace pmlsm::node` (it declares the factory):
///
///   PMLSM_COMPONENT(state_feedback, make_state_feedback, 1);
///
/// name: its program's and its container type's; factory: a ComponentFactory; priority: its place
/// on a container's chain thread (0 the chain's drive and controller, 1 the estimator and the
/// compensators, which feed the next tick, 2 the observers; pmlsm/dds/fiber_scheduler.hpp) or
/// kRunsAlone. The build reads these lines (cmake/PmlsmComponents.cmake): it makes the program
/// from a generated main and the registry (component_registry.hpp) the container, the launch
/// agent, the security tool and `container --help` list; a name registered twice stops it.
#define PMLSM_COMPONENT(name, factory, priority)                                  \
  MadeComponent factory(const ComponentContext& context, int argc, char** argv);  \
  static_assert((priority) == kRunsAlone || ((priority) >= 0 && (priority) <= 2), \
                #name ": priority is 0, 1, 2 (its place on the chain thread) or kRunsAlone")
