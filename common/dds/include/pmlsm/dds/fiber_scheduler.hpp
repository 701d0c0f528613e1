// Cooperative scheduling of a container's components on one thread (the chain thread).
//
// A container runs its components' executors (one per priority; a component with a loop of its
// own, one for it) each as a fiber (Boost.Context: a stack of its own, switched without a system
// call) that waits through the Wakeup, which hands the thread to the next fiber instead of
// blocking it. A hop from one fiber to the next is then a function-call-sized switch, not a
// thread wake-up (tens of microseconds of kernel time on a virtual machine), and a lockstep run
// is stepped in one fixed order: deterministic and fast.
//
// Order: every fiber has a priority (lower goes first). Among the fibers that can go, one of
// the lowest priority runs; among equals, round robin in the order they were spawned. A
// container gives the chain (the drive and the controller) the first priority, then the
// estimator and the compensators, then the observers: an observer's long work (the evaluator's
// report at the end) never holds a tick of the chain, and a drive catching up on ticks after
// the host held the thread never starves the controller that answers them.
//
// Threads: run() and every fiber run on the thread that called run(); wake() may be called
// from any thread (Fast DDS's listener threads when a sample arrives from outside).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace pmlsm::dds {

/// A generation counter a fiber may wait on, and the value it saw.
struct GenerationWatch {
  const std::atomic<std::uint64_t>* generation = nullptr;
  std::uint64_t seen = 0;
};

class FiberScheduler {
 public:
  /// @throws std::invalid_argument for a stack under 64 KiB.
  explicit FiberScheduler(std::size_t stack_bytes = std::size_t{2} << 20);
  ~FiberScheduler();
  FiberScheduler(const FiberScheduler&) = delete;
  FiberScheduler& operator=(const FiberScheduler&) = delete;

  /// Adds a fiber that runs `body` once run() starts (from a running fiber: at once, among the
  /// others), with `priority` (lower goes first). `body` must not throw (a fiber's exception
  /// cannot cross the switch: catch inside and report). @throws std::logic_error when called
  /// from another thread while running.
  void spawn(std::string name, std::function<void()> body, int priority = 0);

  /// Runs every fiber until each has returned, on the calling thread.
  void run();

  /// True on the thread inside run() (the fibers' thread).
  bool on_scheduler_thread() const;

  /// From a fiber: suspends it until `*generation` differs from `seen` or CLOCK_MONOTONIC reaches
  /// `deadline_ns`, whichever is first. Returns true when the generation moved.
  bool wait(const std::atomic<std::uint64_t>& generation, std::uint64_t seen, std::int64_t deadline_ns);
  /// From a fiber: suspends it until any of `count` watched generations moves past what it saw
  /// or CLOCK_MONOTONIC reaches `deadline_ns` (an executor of several components waits once for
  /// all their inputs). `watches` must stay valid until it returns. True when one moved.
  bool wait_any(const GenerationWatch* watches, std::size_t count, std::int64_t deadline_ns);
  /// From a fiber: suspends it until CLOCK_MONOTONIC reaches `deadline_ns`.
  void sleep_until(std::int64_t deadline_ns);

  /// Something a fiber may wait for happened. Any thread; from the scheduler's own thread it
  /// costs nothing (the thread is running, nobody to wake).
  void wake();

  /// Switches performed so far (to and from fibers), for the loop statistics.
  std::uint64_t switches() const { return switches_; }

 private:
  struct Fiber;
  bool runnable(const Fiber& fiber, std::int64_t now_ns) const;
  /// Suspends the current fiber, back to the scheduler loop.
  void suspend();
  /// Blocks the thread until wake() or `deadline_ns`.
  void idle_until(std::int64_t deadline_ns);

  std::size_t stack_bytes_;
  std::vector<std::unique_ptr<Fiber>> fibers_;
  Fiber* current_ = nullptr;
  std::thread::id thread_;
  std::atomic<bool> running_{false};
  std::uint64_t switches_ = 0;

  std::mutex idle_mutex_;
  std::condition_variable idle_cv_;
  bool woken_ = false;  ///< under idle_mutex_
};

}  // namespace pmlsm::dds
