// A container: several components in one process. Every component keeps its own name,
// options, participant (identity, permissions), NodeStatus and exit code; their loops run as
// fibers of one chain thread (pmlsm/dds/fiber_scheduler.hpp) and their samples to each other go
// through the in-process path (pmlsm/dds/local_bus.hpp), while every topic still reaches the
// rest of the domain.
//
// Lifecycle: every component is made first, in order (parse, config, participant, endpoints);
// if one fails, those made are destroyed and the container ends with that component's exit
// code (2 for bad options or config) before anything runs. Then all run; a component that ends
// is destroyed at once (its participant leaves the domain, as a process that exits), so its
// peers see it gone exactly as they would see a process go. The container's exit code is the
// first non-zero exit of a component, in the order they ended (as the launcher's).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "component.hpp"
#include "component_registry.hpp"
#include "container_spec.hpp"
#include "pmlsm/dds/outbox.hpp"
#include "realtime_setup.hpp"

namespace pmlsm::container {

/// A component type the container can make: a registered component (component_registry.hpp) with
/// its priority on the chain thread (lower first: 0 the chain, drive and controller; 1 the
/// estimator and the compensators, which feed the next tick; 2 the observers). See
/// pmlsm/dds/fiber_scheduler.hpp.
using ComponentType = node::RegisteredComponent;

/// Every registered component that may share a chain thread (not those that run alone).
/// @throws ContainerSpecError naming a name registered twice.
const std::vector<ComponentType>& component_types();
std::vector<std::string> component_type_names();

struct ComponentExit {
  std::string name;
  std::string type;
  int exit_code = 0;
};

struct ContainerResult {
  int exit_code = 0;                 ///< the first non-zero exit, in the order they ended
  std::vector<ComponentExit> exits;  ///< in the order they ended
  double cpu_user_s = 0.0, cpu_system_s = 0.0, wall_s = 0.0;
  std::uint64_t switches = 0;
  std::uint64_t local_losses = 0;  ///< samples the in-process readers lost (printed per topic)
  /// Realtime: samples for readers outside the process that the publisher thread did not hand
  /// to DDS (queue full, refused, still queued at the writer's close; printed per topic).
  std::uint64_t outbox_losses = 0;
};

struct ContainerOptions {
  std::string name = "container";
  /// The keystore identity the container's one participant authenticates as when its components
  /// are secure (empty: its name); its permissions must be its components' union
  /// (configs/security/policy.yaml, containers:).
  std::string identity;
  std::size_t stack_bytes = std::size_t{2} << 20;
  /// For the chain thread alone, applied once every component is made: Fast DDS's threads keep
  /// normal scheduling (in a container they carry nothing of the chain, and a real-time thread
  /// of theirs that spins would starve the kernel's own workers on a 2-core machine).
  node::RealtimeOptions realtime;
  /// Realtime: how often the publisher thread hands what the chain wrote for readers outside the
  /// process to DDS (0: the chain thread writes it to DDS itself, as before the publisher thread).
  std::chrono::microseconds publish_period = dds::Outbox::kDefaultPeriod;
};

/// Makes and runs the components of `specs` (types already checked); prints one line per
/// component exit and a summary. Exceptions of a component are mapped to its exit code.
ContainerResult run_container(const ContainerOptions& options, const std::vector<ComponentSpec>& specs);

}  // namespace pmlsm::container
