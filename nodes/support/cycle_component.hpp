// A component with a cycle (pmlsm/util/cycle.hpp): its constructor configures it (parameters,
// topics, state: anything wrong is found there); then an executor (cycle_executor.hpp) activates
// it, calls update() until it finishes, a stop is requested or its inputs stop coming, and ends
// it with finish(). The component has no loop and no wait of its own: alone in its process, run()
// is the executor with this one component; in a container one executor runs all of them on the
// chain thread.
#pragma once

#include <chrono>

#include "node_support.hpp"
#include "pmlsm/util/cycle.hpp"

namespace pmlsm::node {

class CycleComponent : public Component {
 public:
  using Update = CycleStep;

  /// Alone: the executor with this component; returns finish()'s exit code.
  int run() final;

  /// Before the first update (NodeStatus running).
  virtual void activate() {}
  /// Takes what has arrived and does what it can with it, without waiting.
  virtual Update update() = 0;
  /// How long it may wait for its inputs since it last worked (asked again after each work).
  virtual std::chrono::duration<double> input_timeout() const = 0;
  /// Its inputs did not come within input_timeout(): says what is missing; returns the exit code.
  virtual int inputs_lost() = 0;
  /// After the last update, whatever ended the run (`exit_code`: 0 after a stop request): its
  /// counters, NodeStatus, the writers' flush. Returns the exit code to end with.
  virtual int finish(int exit_code) = 0;
  /// The wake-up its readers signal.
  virtual dds::Wakeup& wakeup() = 0;
  /// A descriptor that becomes readable when an input arrives outside DDS (a CAN socket), or -1.
  /// Only a component alone in its process may have one: its executor then sleeps on the
  /// descriptor instead of the wakeup, so its DDS inputs are seen by the wake time it names.
  virtual int input_fd() const { return -1; }
};

/// The input timeout of a component that may wait on its inputs as long as it runs (a device on a
/// bus, a server for clients): its own rules end it, not the executor's.
inline constexpr std::chrono::hours kNoInputTimeout{24 * 365};

}  // namespace pmlsm::node
