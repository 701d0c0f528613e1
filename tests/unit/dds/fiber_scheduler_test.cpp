// FiberScheduler and the container's in-process queues: the order a container steps its
// components in, how a component waits (a generation, a deadline, a wake-up from another
// thread) and what a local queue keeps when full. No DDS participant.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "pmlsm/dds/fiber_scheduler.hpp"
#include "pmlsm/dds/local_bus.hpp"
#include "pmlsm/dds/participant.hpp"
#include "pmlsm/util/clock.hpp"

namespace {

using pmlsm::monotonic_ns;
using pmlsm::dds::FiberScheduler;
using pmlsm::dds::Guid;
using pmlsm::dds::LocalQueue;
using pmlsm::dds::Wakeup;

TEST(FiberScheduler, AFiberSpawnedByARunningOneRunsBesideIt) {
  // A container's executor hands a component's finish (a wait for acknowledgments) to a fiber of
  // its own while it goes on.
  FiberScheduler scheduler;
  std::vector<std::string> trace;
  scheduler.spawn("executor", [&] {
    scheduler.spawn("finishing", [&] { trace.push_back("finished"); });
    trace.push_back("spawned");
    scheduler.sleep_until(monotonic_ns());  // hands the thread on
    trace.push_back("went on");
  });
  scheduler.run();
  EXPECT_EQ(trace, (std::vector<std::string>{"spawned", "finished", "went on"}));
  std::thread other([&] { EXPECT_NO_THROW(scheduler.spawn("after the run", [] {})); });
  other.join();
}

TEST(FiberScheduler, TwoFibersHandTheThreadToEachOtherInLockstep) {
  // A plant and a controller over two generations: the plant writes tick k and waits for the
  // answer; the controller answers. The trace is the same interleaving every time.
  FiberScheduler scheduler;
  std::atomic<std::uint64_t> feedback{0}, command{0};
  std::vector<std::string> trace;
  scheduler.spawn("plant", [&] {
    for (int k = 0; k < 3; ++k) {
      trace.push_back("feedback " + std::to_string(k));
      const std::uint64_t seen = command.load();
      feedback.fetch_add(1);
      ASSERT_TRUE(scheduler.wait(command, seen, monotonic_ns() + 10'000'000'000));
    }
  });
  scheduler.spawn("controller", [&] {
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t seen = static_cast<std::uint64_t>(k);
      if (feedback.load() == seen) {
        ASSERT_TRUE(scheduler.wait(feedback, seen, monotonic_ns() + 10'000'000'000));
      }
      trace.push_back("command " + std::to_string(k));
      command.fetch_add(1);
    }
  });
  scheduler.run();
  const std::vector<std::string> expected = {"feedback 0", "command 0",  "feedback 1",
                                             "command 1",  "feedback 2", "command 2"};
  EXPECT_EQ(trace, expected);
  EXPECT_GE(scheduler.switches(), 6u);
}

TEST(FiberScheduler, AWaitWhoseGenerationNeverMovesEndsAtItsDeadline) {
  FiberScheduler scheduler;
  std::atomic<std::uint64_t> generation{0};
  bool moved = true;
  std::int64_t waited_ns = 0;
  scheduler.spawn("waiter", [&] {
    const std::int64_t start = monotonic_ns();
    moved = scheduler.wait(generation, 0, start + 20'000'000);
    waited_ns = monotonic_ns() - start;
  });
  scheduler.run();
  EXPECT_FALSE(moved);
  EXPECT_GE(waited_ns, 20'000'000);  // never early
}

TEST(FiberScheduler, SleepingFibersWakeInDeadlineOrder) {
  FiberScheduler scheduler;
  std::vector<std::string> order;
  const std::int64_t start = monotonic_ns();
  scheduler.spawn("late", [&] {
    scheduler.sleep_until(start + 30'000'000);
    order.push_back("late");
  });
  scheduler.spawn("early", [&] {
    scheduler.sleep_until(start + 10'000'000);
    order.push_back("early");
  });
  scheduler.run();
  EXPECT_EQ(order, (std::vector<std::string>{"early", "late"}));
  EXPECT_GE(monotonic_ns() - start, 30'000'000);
}

TEST(FiberScheduler, AFiberBehindItsDeadlinesDoesNotStarveTheOthers) {
  // A drive catching up after the host held the thread: every tick's deadline has passed. The
  // controller that answers must still get the thread between two of the drive's ticks.
  FiberScheduler scheduler;
  std::atomic<std::uint64_t> feedback{0};
  std::vector<int> answered_after;  // the drive's ticks done when the controller ran
  int drive_ticks = 0;
  scheduler.spawn("drive", [&] {
    const std::int64_t long_ago = monotonic_ns() - 1'000'000'000;
    for (int k = 0; k < 5; ++k) {
      ++drive_ticks;
      feedback.fetch_add(1);
      scheduler.sleep_until(long_ago);  // the next tick is overdue already
    }
  });
  scheduler.spawn("controller", [&] {
    for (int k = 0; k < 5; ++k) {
      const std::uint64_t seen = static_cast<std::uint64_t>(k);
      if (feedback.load() == seen) {
        ASSERT_TRUE(scheduler.wait(feedback, seen, monotonic_ns() + 10'000'000'000));
      }
      answered_after.push_back(drive_ticks);
    }
  });
  scheduler.run();
  EXPECT_EQ(answered_after, (std::vector<int>{1, 2, 3, 4, 5}));
}

TEST(FiberScheduler, TheChainGoesBeforeAnObserverThatCouldAlsoGo) {
  // The evaluator's report (long work) must not run while the drive could take its command.
  FiberScheduler scheduler;
  std::vector<std::string> order;
  scheduler.spawn(
      "observer", [&] { order.push_back("observer"); }, 2);
  scheduler.spawn(
      "estimator", [&] { order.push_back("estimator"); }, 1);
  scheduler.spawn(
      "drive",
      [&] {
        order.push_back("drive");
        scheduler.sleep_until(0);  // overdue: can go again at once, and goes before the others
        order.push_back("drive again");
      },
      0);
  scheduler.run();
  EXPECT_EQ(order, (std::vector<std::string>{"drive", "drive again", "estimator", "observer"}));
}

TEST(FiberScheduler, AWakeFromAnotherThreadEndsAnIdleWait) {
  // Fast DDS's listener threads deliver samples from outside the container this way.
  FiberScheduler scheduler;
  Wakeup wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  bool moved = false;
  std::int64_t waited_ns = 0;
  std::thread outside;
  scheduler.spawn("reader", [&] {
    const std::uint64_t seen = wakeup.generation();
    outside = std::thread([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      wakeup.notify();
    });
    const std::int64_t start = monotonic_ns();
    moved = wakeup.wait_for(seen, std::chrono::seconds(20));
    waited_ns = monotonic_ns() - start;
  });
  scheduler.run();
  outside.join();
  EXPECT_TRUE(moved);
  EXPECT_LT(waited_ns, 10'000'000'000);
}

TEST(FiberScheduler, AWakeupOutsideAFiberStillBlocksItsThread) {
  // A component's wakeup used before the container runs (or on another thread) waits as a
  // node alone does.
  FiberScheduler scheduler;
  Wakeup wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(wakeup.wait_for(wakeup.generation(), std::chrono::milliseconds(10)));
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(10));
}

TEST(FiberScheduler, RefusesATinyStackAndASpawnFromAnotherThreadWhileRunning) {
  EXPECT_THROW(FiberScheduler(1024), std::invalid_argument);
  FiberScheduler scheduler;
  bool refused = false;
  scheduler.spawn("a", [&] {
    // The scheduler runs (this fiber holds its thread) while another thread tries.
    std::thread other([&] {
      try {
        scheduler.spawn("b", [] {});
      } catch (const std::logic_error&) {
        refused = true;
      }
    });
    other.join();
  });
  scheduler.run();
  EXPECT_TRUE(refused);
}

Guid writer_guid(std::uint8_t id) {
  Guid guid;
  guid.guidPrefix.value[0] = id;
  guid.entityId.value[3] = 3;
  return guid;
}

TEST(LocalQueue, KeepLastDropsTheOldestWhenFullAndCountsIt) {
  Wakeup wakeup;
  LocalQueue<int> queue(3, false, wakeup);
  const auto now = pmlsm::dds::wall_clock_now();
  for (int i = 1; i <= 5; ++i) queue.push(i, writer_guid(1), now);
  EXPECT_EQ(queue.overwritten(), 2u);
  int out = 0;
  std::vector<int> got;
  while (queue.pop(out, nullptr)) got.push_back(out);
  EXPECT_EQ(got, (std::vector<int>{3, 4, 5}));
}

TEST(LocalQueue, KeepAllRefusesTheNewestWhenFullAndCountsIt) {
  Wakeup wakeup;
  LocalQueue<int> queue(2, true, wakeup);
  const auto now = pmlsm::dds::wall_clock_now();
  for (int i = 1; i <= 4; ++i) queue.push(i, writer_guid(1), now);
  EXPECT_EQ(queue.refused(), 2u);
  int out = 0;
  std::vector<int> got;
  while (queue.pop(out, nullptr)) got.push_back(out);
  EXPECT_EQ(got, (std::vector<int>{1, 2}));
}

TEST(LocalQueue, TheTopicsLossesSumEveryReadersQueue) {
  Wakeup wakeup;
  pmlsm::dds::LocalLosses topic;
  LocalQueue<int> fast(2, false, wakeup, &topic);
  LocalQueue<int> slow(1, false, wakeup, &topic);
  LocalQueue<int> keep_all(1, true, wakeup, &topic);
  const auto now = pmlsm::dds::wall_clock_now();
  for (int i = 1; i <= 3; ++i) {
    fast.push(i, writer_guid(1), now);
    slow.push(i, writer_guid(1), now);
    keep_all.push(i, writer_guid(1), now);
  }
  EXPECT_EQ(topic.overwritten, 1u + 2u);
  EXPECT_EQ(topic.refused, 2u);
}

TEST(LocalQueue, EverySampleSignalsTheReadersWakeupAndCarriesItsWriter) {
  Wakeup wakeup;
  LocalQueue<int> queue(4, false, wakeup);
  const std::uint64_t seen = wakeup.generation();
  queue.push(7, writer_guid(9), pmlsm::dds::wall_clock_now());
  EXPECT_NE(wakeup.generation(), seen);
  int out = 0;
  eprosima::fastdds::dds::SampleInfo info;
  ASSERT_TRUE(queue.pop(out, &info));
  EXPECT_EQ(out, 7);
  EXPECT_TRUE(info.valid_data);
  EXPECT_EQ(info.sample_identity.writer_guid(), writer_guid(9));
  EXPECT_THROW(LocalQueue<int>(0, false, wakeup), std::invalid_argument);
}

}  // namespace
