#include "cycle_component.hpp"

namespace pmlsm::node {

int CycleComponent::run() {
  activate();
  CycleWait wait(std::chrono::duration_cast<std::chrono::nanoseconds>(input_timeout()).count(), monotonic_ns());
  int exit_code = kExitOk;
  while (!dds::stop_requested()) {
    // Read before the update: what arrives during it wakes the wait below at once.
    const std::uint64_t seen = wakeup().generation();
    const Update update_result = update();
    const std::int64_t now_ns = monotonic_ns();
    const CycleWait::Next next = wait.after(update_result.progress, now_ns);
    if (next == CycleWait::Next::kUpdate) {
      // Its timeout may change once it worked (realtime: the plant-lost timeout once the plant ticks).
      wait.set_timeout_ns(std::chrono::duration_cast<std::chrono::nanoseconds>(input_timeout()).count());
      continue;
    }
    if (next == CycleWait::Next::kFinished) {
      exit_code = update_result.exit_code;
      break;
    }
    if (next == CycleWait::Next::kInputsLost) {
      exit_code = dds::stop_requested() ? kExitOk : inputs_lost();
      break;
    }
    wakeup().wait_for(seen, std::chrono::nanoseconds(wait.sleep_ns(now_ns)));
  }
  return finish(exit_code);
}

}  // namespace pmlsm::node
