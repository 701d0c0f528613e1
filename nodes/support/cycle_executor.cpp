#include "cycle_executor.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

#include <poll.h>

namespace pmlsm::node {

namespace {

std::int64_t to_ns(std::chrono::duration<double> d) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(d).count();
}

/// One component as the executor sees it.
struct Entry {
  CycleComponent* component;
  CycleWait wait;
  std::int64_t batch_ns;   ///< its wakeup's batch: updated at most this often while it waits (0: on arrival)
  std::uint64_t seen = 0;  ///< its wakeup's generation before its last update
  CycleWait::Next next = CycleWait::Next::kUpdate;
  std::int64_t wake_ns = 0;  ///< kSleep: by then at the latest; kSleepUntil: not before
  std::int64_t spin_ns = 0;  ///< kSleepUntil: the last stretch polled
  /// It went to sleep to a time since it last ran: whoever else can go goes first (a drive catching
  /// up on ticks after the host held the thread never starves the controller that answers them).
  bool yielding = false;
  bool done = false;
};

bool can_go(const Entry& e, std::int64_t now_ns) {
  if (e.done) return false;
  switch (e.next) {
    case CycleWait::Next::kUpdate: return true;
    case CycleWait::Next::kSleepUntil: return now_ns >= e.wake_ns;
    case CycleWait::Next::kSleep:
      return (e.batch_ns == 0 && e.component->wakeup().generation() != e.seen) || now_ns >= e.wake_ns;
    default: return false;
  }
}

class Executor {
 public:
  Executor(const std::vector<CycleComponent*>& cycles, const CycleEnded& ended, const CycleFailed& failed,
           const CycleFinisher& finisher)
      : ended_(ended), failed_(failed), finisher_(finisher), running_(cycles.size()) {
    entries_.reserve(cycles.size());
    watches_.reserve(cycles.size());
    for (CycleComponent* c : cycles) {
      entries_.push_back({c, CycleWait(0, 0), c->wakeup().batch().count()});
      if (c->input_fd() >= 0 && cycles.size() > 1) {
        throw std::logic_error("run_cycles: a component waiting on descriptor " + std::to_string(c->input_fd()) +
                               " runs alone in its process, not beside " + std::to_string(cycles.size() - 1) +
                               " other(s)");
      }
    }
    if (cycles.size() == 1) input_fd_ = cycles.front()->input_fd();
  }

  void run() {
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      Entry& e = entries_[i];
      guarded(i, [&] {
        e.component->activate();
        e.wait = CycleWait(to_ns(e.component->input_timeout()), monotonic_ns());
      });
    }
    while (running_ > 0) {
      if (dds::stop_requested()) {
        for (std::size_t i = 0; i < entries_.size(); ++i) {
          if (!entries_[i].done) end(i, kExitOk);
        }
        break;
      }
      const std::int64_t now = monotonic_ns();
      if (const std::size_t pick = first_to_go(now, false); pick < entries_.size()) {
        guarded(pick, [&] { update(pick, now); });
      } else if (const std::size_t woken = first_to_go(now, true); woken < entries_.size()) {
        // Its time came; the others of the thread (in a container, the other fibers) go first.
        pass_turn();
        guarded(woken, [&] { update(woken, monotonic_ns()); });
      } else {
        sleep(now);
      }
    }
  }

 private:
  template <typename Body>
  void guarded(std::size_t index, Body&& body) {
    if (entries_[index].done) return;
    try {
      body();
    } catch (...) {
      const int code = failed_(index, std::current_exception());
      finished(index, code);
    }
  }

  /// The first in order that can go, among those yielding or not; entries_.size() for none.
  std::size_t first_to_go(std::int64_t now_ns, bool yielding) const {
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      if (entries_[i].yielding == yielding && can_go(entries_[i], now_ns)) return i;
    }
    return entries_.size();
  }

  /// The wakeup the executor waits through: a running component's (in a container all of them
  /// share the scheduler). Called only while one runs.
  dds::Wakeup& home() {
    for (Entry& e : entries_) {
      if (!e.done) return e.component->wakeup();
    }
    return entries_.front().component->wakeup();  // unreachable: running_ > 0
  }

  /// In a container's fiber: hands the thread to whichever other fiber can go, and back.
  void pass_turn() { home().wait_any(nullptr, 0, std::chrono::nanoseconds(0)); }

  /// `now`: read just before (one clock read an update: the input timeout counts from the start of
  /// the update that worked, microseconds early on a timeout of seconds).
  void update(std::size_t index, std::int64_t now) {
    Entry& e = entries_[index];
    e.yielding = false;
    e.seen = e.component->wakeup().generation();
    const CycleStep step = e.component->update();
    e.next = e.wait.after(step, now);
    switch (e.next) {
      case CycleWait::Next::kUpdate:
        // Its timeout may change once it worked (realtime: the plant-lost timeout once the plant ticks).
        e.wait.set_timeout_ns(to_ns(e.component->input_timeout()));
        break;
      case CycleWait::Next::kFinished: end(index, step.exit_code); break;
      case CycleWait::Next::kInputsLost:
        end(index, dds::stop_requested() ? kExitOk : e.component->inputs_lost());
        break;
      case CycleWait::Next::kSleep:
        e.wake_ns = e.wait.wake_ns();
        if (e.batch_ns > 0) e.wake_ns = std::min(e.wake_ns, now + e.batch_ns);
        break;
      case CycleWait::Next::kSleepUntil:
        e.wake_ns = e.wait.wake_ns();
        e.spin_ns = step.spin_ns;
        e.yielding = true;
        break;
    }
  }

  /// No component can go: waits for an input of one (not those asleep to a time, nor the batched)
  /// or the earliest time one named; the last stretch to a time asked to the nanosecond is polled.
  void sleep(std::int64_t now) {
    std::int64_t earliest = std::numeric_limits<std::int64_t>::max();
    std::int64_t spin_ns = 0;
    watches_.clear();
    for (Entry& e : entries_) {
      if (e.done) continue;
      if (e.wake_ns < earliest) {
        earliest = e.wake_ns;
        spin_ns = e.next == CycleWait::Next::kSleepUntil ? e.spin_ns : 0;
      }
      if (e.next == CycleWait::Next::kSleep && e.batch_ns == 0) watches_.push_back(e.component->wakeup().watch(e.seen));
    }
    const std::int64_t sleep_until = earliest - spin_ns;
    if (input_fd_ >= 0 && entries_.front().next == CycleWait::Next::kSleep) {
      if (sleep_until > now && wait_fd(sleep_until - now)) return;
    } else if (sleep_until > now &&
               home().wait_any(watches_.data(), watches_.size(), std::chrono::nanoseconds(sleep_until - now))) {
      return;
    }
    // No yield while polling: the poll is short, and at SCHED_FIFO a yield would hand the core to
    // this process's own threads just when the tick must start.
    while (monotonic_ns() < earliest && !input_moved()) {
    }
  }

  /// Alone with a descriptor: sleeps on it (to the nanosecond, unlike poll's milliseconds). True
  /// when it became readable (the component then goes at once).
  bool wait_fd(std::int64_t timeout_ns) {
    pollfd fds{input_fd_, POLLIN, 0};
    const timespec timeout = to_timespec(timeout_ns);
    if (::ppoll(&fds, 1, &timeout, nullptr) <= 0) return false;  // a signal (EINTR) or the time
    entries_.front().next = CycleWait::Next::kUpdate;
    return true;
  }

  bool input_moved() const {
    return std::any_of(watches_.begin(), watches_.end(), [](const dds::GenerationWatch& w) {
      return w.generation->load(std::memory_order_acquire) != w.seen;
    });
  }

  void end(std::size_t index, int exit_code) {
    Entry& e = entries_[index];
    if (finisher_) {
      // Its finish may wait (for acknowledgments): elsewhere, while the others go on.
      e.done = true;
      --running_;
      finisher_(index, exit_code);
      return;
    }
    int code = exit_code;
    try {
      code = e.component->finish(exit_code);
    } catch (...) {
      code = failed_(index, std::current_exception());
    }
    finished(index, code);
  }

  void finished(std::size_t index, int exit_code) {
    Entry& e = entries_[index];
    if (e.done) return;
    e.done = true;
    --running_;
    ended_(index, exit_code);
  }

  const CycleEnded& ended_;
  const CycleFailed& failed_;
  const CycleFinisher& finisher_;
  std::vector<Entry> entries_;
  std::vector<dds::GenerationWatch> watches_;
  std::size_t running_;
  int input_fd_ = -1;  ///< the lone component's descriptor, if it waits on one
};

}  // namespace

void run_cycles(const std::vector<CycleComponent*>& cycles, const CycleEnded& ended, const CycleFailed& failed,
                const CycleFinisher& finisher) {
  Executor(cycles, ended, failed, finisher).run();
}

int CycleComponent::run() {
  int exit_code = kExitOk;
  run_cycles(
      {this}, [&](std::size_t /*index*/, int code) { exit_code = code; },
      [](std::size_t /*index*/, std::exception_ptr error) -> int { std::rethrow_exception(error); });
  return exit_code;
}

}  // namespace pmlsm::node
