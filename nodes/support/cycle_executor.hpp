// The executor of components with a cycle (cycle_component.hpp), one or many on one thread: it
// activates them in order, updates whichever can go (the first in order: the chain before the
// estimator and the compensators, those before the observers), sleeps when none can until an
// input of one moves or the earliest time one named (a tick's command deadline, the next tick of
// a drive's clock, polled to the nanosecond when the drive asks), applies each one's input
// timeout (pmlsm/util/cycle.hpp) and ends each with finish(). A component that worked is updated
// again at once; one waiting is updated again when its wakeup moved or its time came; one with a
// batched wakeup (an observer off the chain) at most once per batch. A component alone that waits
// on a descriptor (a device's CAN socket: CycleComponent::input_fd) is slept on that instead.
#pragma once

#include <cstddef>
#include <exception>
#include <functional>
#include <vector>

#include "cycle_component.hpp"

namespace pmlsm::node {

/// Called as a component ends, with its index in `cycles` and its exit code (after finish()). It
/// may destroy the component: the executor does not touch it again.
using CycleEnded = std::function<void(std::size_t index, int exit_code)>;
/// Called when a component's activate(), update(), inputs_lost() or finish() threw: returns the
/// exit code the exception maps to (run_node), or rethrows it. The component is not finished;
/// `ended` follows with that code.
using CycleFailed = std::function<int(std::size_t index, std::exception_ptr error)>;

/// Ends a component whose run is over with `exit_code`: its finish() (which may wait for its
/// writers' readers to acknowledge), then what `ended` does. A container hands that to a fiber
/// of its own, so the others go on meanwhile; none given: the executor does it in place.
using CycleFinisher = std::function<void(std::size_t index, int exit_code)>;

/// Runs `cycles` (in their order of precedence) until each has ended; a stop request ends every
/// one still running with finish(kExitOk). In a container's fiber their waits are one suspension;
/// outside a container there may be only one (Wakeup::wait_any).
void run_cycles(const std::vector<CycleComponent*>& cycles, const CycleEnded& ended, const CycleFailed& failed,
                const CycleFinisher& finisher = nullptr);

}  // namespace pmlsm::node
