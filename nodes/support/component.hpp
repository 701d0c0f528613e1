// Every node is a component: a class with one lifecycle. It is made from its command line
// and config (parse, load, create its participant, endpoints and state: anything wrong is
// found here, before anything runs), then run once, which returns its exit code. A component
// runs alone in its process (the node's executable is a thin main: run_standalone), or beside
// others in a container process (nodes/container), where its loop is a fiber of the chain
// thread and its samples to the others go through the in-process path (pmlsm/dds/local_bus.hpp).
// Nothing in a component knows which: a component alone behaves exactly as the node did.
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

// The components of this project (one per node executable; defined with their node).
MadeComponent make_plant_sim(const ComponentContext& context, int argc, char** argv);
MadeComponent make_controller(const ComponentContext& context, int argc, char** argv);
MadeComponent make_kalman_estimator(const ComponentContext& context, int argc, char** argv);
MadeComponent make_rnn_compensator(const ComponentContext& context, int argc, char** argv);
MadeComponent make_accel_feedback(const ComponentContext& context, int argc, char** argv);
MadeComponent make_state_feedback(const ComponentContext& context, int argc, char** argv);
MadeComponent make_evaluator(const ComponentContext& context, int argc, char** argv);
MadeComponent make_drive_bridge(const ComponentContext& context, int argc, char** argv);
MadeComponent make_virtual_drive(const ComponentContext& context, int argc, char** argv);
MadeComponent make_de_worker(const ComponentContext& context, int argc, char** argv);
// Components that block their thread (minutes of computing, a network server's batches, child
// processes): each runs alone in its process, never on a container's chain thread.
MadeComponent make_de_trainer(const ComponentContext& context, int argc, char** argv);
MadeComponent make_foxglove_bridge(const ComponentContext& context, int argc, char** argv);
MadeComponent make_launch_agent(const ComponentContext& context, int argc, char** argv);

}  // namespace pmlsm::node
