#include "pmlsm/dds/fiber_scheduler.hpp"

#include <boost/context/fiber.hpp>
#include <boost/context/protected_fixedsize_stack.hpp>

#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <utility>

#include "pmlsm/util/clock.hpp"

namespace pmlsm::dds {

namespace bctx = boost::context;

struct FiberScheduler::Fiber {
  std::string name;
  std::function<void()> body;
  int priority = 0;
  bctx::fiber context;  ///< the fiber's continuation while it is suspended
  bctx::fiber back;     ///< the scheduler's continuation while the fiber runs
  bool started = false;
  bool done = false;
  // What the fiber waits for: a generation to move past `seen` (when `generation` is set) or
  // CLOCK_MONOTONIC to reach `deadline_ns`.
  const std::atomic<std::uint64_t>* generation = nullptr;
  std::uint64_t seen = 0;
  // Or any of several (wait_any).
  const GenerationWatch* watches = nullptr;
  std::size_t watch_count = 0;
  std::int64_t deadline_ns = 0;
};

namespace {
bool moved(const GenerationWatch* watches, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    if (watches[i].generation->load(std::memory_order_acquire) != watches[i].seen) return true;
  }
  return false;
}
}  // namespace

FiberScheduler::FiberScheduler(std::size_t stack_bytes) : stack_bytes_(stack_bytes) {
  if (stack_bytes < (std::size_t{64} << 10)) {
    throw std::invalid_argument("FiberScheduler: stack of " + std::to_string(stack_bytes) +
                                " bytes: must be at least 64 KiB");
  }
}

FiberScheduler::~FiberScheduler() = default;

void FiberScheduler::spawn(std::string name, std::function<void()> body, int priority) {
  if (running_ && !on_scheduler_thread()) {
    throw std::logic_error("FiberScheduler::spawn(" + name + "): the scheduler is running on another thread");
  }
  auto fiber = std::make_unique<Fiber>();
  fiber->name = std::move(name);
  fiber->body = std::move(body);
  fiber->priority = priority;
  fibers_.push_back(std::move(fiber));
}

bool FiberScheduler::on_scheduler_thread() const {
  return running_.load(std::memory_order_acquire) && std::this_thread::get_id() == thread_;
}

bool FiberScheduler::runnable(const Fiber& fiber, std::int64_t now_ns) const {
  if (fiber.done) return false;
  if (!fiber.started) return true;
  if (fiber.generation != nullptr && fiber.generation->load(std::memory_order_acquire) != fiber.seen) return true;
  if (moved(fiber.watches, fiber.watch_count)) return true;
  return now_ns >= fiber.deadline_ns;
}

void FiberScheduler::run() {
  thread_ = std::this_thread::get_id();
  running_.store(true, std::memory_order_release);
  std::size_t next = 0;  // round robin among equals: where the next look for work starts
  for (;;) {
    const std::size_t n = fibers_.size();  // a fiber may have spawned another
    if (n == 0) break;
    next %= n;
    bool all_done = true;
    std::int64_t earliest = std::numeric_limits<std::int64_t>::max();
    const std::int64_t now = monotonic_ns();
    std::size_t chosen = n;
    for (std::size_t step = 0; step < n; ++step) {
      const std::size_t index = (next + step) % n;
      const Fiber& f = *fibers_[index];
      if (f.done) continue;
      all_done = false;
      if (!runnable(f, now)) {
        earliest = std::min(earliest, f.deadline_ns);
        continue;
      }
      if (chosen == n || f.priority < fibers_[chosen]->priority) chosen = index;
    }
    if (all_done) break;
    if (chosen == n) {
      idle_until(earliest);
      continue;
    }
    Fiber& f = *fibers_[chosen];
    current_ = &f;
    ++switches_;
    if (!f.started) {
      f.started = true;
      f.context =
          bctx::fiber(std::allocator_arg, bctx::protected_fixedsize_stack(stack_bytes_), [&f](bctx::fiber&& back) {
            f.back = std::move(back);
            f.body();
            f.done = true;
            return std::move(f.back);
          });
    }
    f.context = std::move(f.context).resume();
    current_ = nullptr;
    // Its equals that can go get the thread before it runs again.
    next = (chosen + 1) % fibers_.size();
  }
  running_.store(false, std::memory_order_release);
}

void FiberScheduler::suspend() {
  Fiber& f = *current_;
  f.back = std::move(f.back).resume();
}

bool FiberScheduler::wait(const std::atomic<std::uint64_t>& generation, std::uint64_t seen, std::int64_t deadline_ns) {
  if (current_ == nullptr) throw std::logic_error("FiberScheduler::wait: not called from a fiber");
  Fiber& f = *current_;
  f.generation = &generation;
  f.seen = seen;
  f.deadline_ns = deadline_ns;
  suspend();
  f.generation = nullptr;
  return generation.load(std::memory_order_acquire) != seen;
}

bool FiberScheduler::wait_any(const GenerationWatch* watches, std::size_t count, std::int64_t deadline_ns) {
  if (current_ == nullptr) throw std::logic_error("FiberScheduler::wait_any: not called from a fiber");
  Fiber& f = *current_;
  f.generation = nullptr;
  f.watches = watches;
  f.watch_count = count;
  f.deadline_ns = deadline_ns;
  suspend();
  f.watches = nullptr;
  f.watch_count = 0;
  return moved(watches, count);
}

void FiberScheduler::sleep_until(std::int64_t deadline_ns) {
  if (current_ == nullptr) throw std::logic_error("FiberScheduler::sleep_until: not called from a fiber");
  Fiber& f = *current_;
  f.generation = nullptr;
  f.deadline_ns = deadline_ns;
  suspend();
}

void FiberScheduler::wake() {
  if (on_scheduler_thread()) return;  // running: it looks at every generation before it idles
  {
    std::lock_guard<std::mutex> lock(idle_mutex_);
    woken_ = true;
  }
  idle_cv_.notify_one();
}

void FiberScheduler::idle_until(std::int64_t deadline_ns) {
  std::unique_lock<std::mutex> lock(idle_mutex_);
  if (!woken_) {
    // steady_clock is CLOCK_MONOTONIC, the clock of every deadline here.
    const auto deadline = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(deadline_ns));
    if (deadline_ns == std::numeric_limits<std::int64_t>::max()) {
      idle_cv_.wait(lock, [this] { return woken_; });
    } else {
      idle_cv_.wait_until(lock, deadline, [this] { return woken_; });
    }
  }
  woken_ = false;
}

}  // namespace pmlsm::dds
