// The executor of components with a cycle (nodes/support/cycle_executor.hpp), over scripted
// components: the order it updates them in, a drive waking late that lets the others go first,
// a sleep to a time kept, a lost input and an exception ending only their component. The several
// components of a container run in a fiber, as there; no DDS participant.
#include "cycle_executor.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include "pmlsm/dds/fiber_scheduler.hpp"
#include "pmlsm/util/clock.hpp"

namespace pmlsm::node {
namespace {

using Trace = std::vector<std::string>;

/// A component whose update() is the script's answer to its n-th call; every call is traced.
class Scripted final : public CycleComponent {
 public:
  using Script = std::function<Update(int call)>;
  Scripted(std::string name, Trace& trace, dds::Wakeup& wakeup, Script script, double input_timeout_s = 10.0)
      : name_(std::move(name)),
        trace_(trace),
        wakeup_(wakeup),
        script_(std::move(script)),
        input_timeout_s_(input_timeout_s) {}

  Update update() override {
    trace_.push_back(name_ + " " + std::to_string(calls_));
    return script_(calls_++);
  }
  std::chrono::duration<double> input_timeout() const override {
    return std::chrono::duration<double>(input_timeout_s_);
  }
  int inputs_lost() override {
    trace_.push_back(name_ + " lost");
    return kExitPeerLost;
  }
  int finish(int exit_code) override {
    trace_.push_back(name_ + " finish " + std::to_string(exit_code));
    return exit_code;
  }
  dds::Wakeup& wakeup() override { return wakeup_; }
  int input_fd() const override { return input_fd_; }
  void set_input_fd(int fd) { input_fd_ = fd; }

 private:
  std::string name_;
  Trace& trace_;
  dds::Wakeup& wakeup_;
  Script script_;
  double input_timeout_s_;
  int calls_ = 0;
  int input_fd_ = -1;
};

struct Ended {
  std::size_t index;
  int exit_code;
};

/// Runs `cycles` on one fiber of a container's scheduler, as a container does; what ended, in order.
std::vector<Ended> run_in_a_container(dds::FiberScheduler& scheduler, const std::vector<CycleComponent*>& cycles,
                                      int code_for_exceptions = kExitError) {
  std::vector<Ended> ended;
  scheduler.spawn("cycles", [&] {
    run_cycles(
        cycles,
        [&](std::size_t index, int code) {
          ended.push_back({index, code});
        },
        [&](std::size_t /*index*/, std::exception_ptr /*error*/) { return code_for_exceptions; });
  });
  scheduler.run();
  return ended;
}

TEST(CycleExecutor, TheFirstInOrderThatCanGoGoesFirstAndAComponentThatWorkedGoesAgainAtOnce) {
  dds::FiberScheduler scheduler;
  dds::Wakeup drive_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  dds::Wakeup observer_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  Trace trace;
  // The drive works two ticks, then waits for the observer's signal; the observer, later in
  // order, goes only while the drive waits, and its notify lets the drive go on.
  Scripted drive("drive", trace, drive_wakeup, [](int call) {
    if (call < 2) return CycleStep::worked();
    if (call == 2) return CycleStep::waiting();
    return CycleStep::finished(kExitOk);
  });
  Scripted observer("observer", trace, observer_wakeup, [&](int call) {
    if (call == 0) {
      drive_wakeup.notify();
      return CycleStep::waiting();
    }
    return CycleStep::finished(kExitOk);
  });
  const auto ended = run_in_a_container(scheduler, {&drive, &observer});
  const Trace expected = {"drive 0", "drive 1", "drive 2", "observer 0", "drive 3", "drive finish 0"};
  ASSERT_GE(trace.size(), expected.size());
  EXPECT_EQ(Trace(trace.begin(), trace.begin() + static_cast<std::ptrdiff_t>(expected.size())), expected);
  ASSERT_EQ(ended.size(), 2u);
  EXPECT_EQ(ended[0].index, 0u);
  EXPECT_EQ(ended[0].exit_code, kExitOk);
  EXPECT_EQ(ended[1].index, 1u);
}

TEST(CycleExecutor, ADriveWakingLateLetsTheOthersThatCanGoGoFirst) {
  // A realtime drive whose next tick is already due (the host held the thread) must not run its
  // ticks back to back before the controller answers the one it published: the controller, later
  // in order, goes first.
  dds::FiberScheduler scheduler;
  dds::Wakeup drive_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  dds::Wakeup controller_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  Trace trace;
  Scripted drive("drive", trace, drive_wakeup, [&](int call) {
    // Its tick done, the next one already past.
    return call == 0 ? CycleStep::sleeping_until(monotonic_ns() - 1'000'000) : CycleStep::finished(kExitOk);
  });
  Scripted controller("controller", trace, controller_wakeup,
                      [](int call) { return call == 0 ? CycleStep::waiting() : CycleStep::finished(kExitOk); });
  run_in_a_container(scheduler, {&drive, &controller});
  // The controller, due since the start, goes before the drive's next tick (then waits, and ends
  // a slice later).
  const Trace expected = {"drive 0",        "controller 0", "drive 1",
                          "drive finish 0", "controller 1", "controller finish 0"};
  EXPECT_EQ(trace, expected);
}

TEST(CycleExecutor, ASleepToATimeIsKeptWhateverArrivesAndAWaitEndsAtItsDeadline) {
  dds::Wakeup wakeup;  // alone in its process
  Trace trace;
  std::int64_t wake_ns = 0;
  std::int64_t deadline_ns = 0;
  std::int64_t slept_to_ns = 0;
  std::int64_t waited_to_ns = 0;
  Scripted drive("drive", trace, wakeup, [&](int call) {
    if (call == 0) {
      wake_ns = monotonic_ns() + 3'000'000;
      wakeup.notify();  // an input meanwhile does not cut the sleep short
      return CycleStep::sleeping_until(wake_ns, 500'000);
    }
    if (call == 1) {
      slept_to_ns = monotonic_ns();
      deadline_ns = slept_to_ns + 2'000'000;
      return CycleStep::waiting_until(deadline_ns);
    }
    waited_to_ns = monotonic_ns();
    return CycleStep::finished(kExitOk);
  });
  EXPECT_EQ(drive.run(), kExitOk);
  EXPECT_GE(slept_to_ns, wake_ns);
  EXPECT_GE(waited_to_ns, deadline_ns) << "nothing arrived: updated again at its deadline, not before";
  EXPECT_EQ(trace.size(), 4u);
}

TEST(CycleExecutor, LostInputsAndAnExceptionEndOnlyTheirOwnComponent) {
  dds::FiberScheduler scheduler;
  dds::Wakeup a_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  dds::Wakeup b_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  dds::Wakeup c_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  Trace trace;
  std::int64_t start_ns = monotonic_ns();
  // a: its inputs never come (10 ms timeout); b: throws on its first update; c: goes on for 30 ms.
  Scripted a(
      "a", trace, a_wakeup, [](int) { return CycleStep::waiting(); }, 0.01);
  Scripted b("b", trace, b_wakeup, [](int) -> CycleStep { throw std::runtime_error("broken"); });
  Scripted c("c", trace, c_wakeup, [&](int) {
    return monotonic_ns() - start_ns < 30'000'000 ? CycleStep::waiting_until(monotonic_ns() + 1'000'000)
                                                  : CycleStep::finished(kExitOk);
  });
  const auto ended = run_in_a_container(scheduler, {&a, &b, &c}, 42);
  ASSERT_EQ(ended.size(), 3u);
  EXPECT_EQ(ended[0].index, 1u);
  EXPECT_EQ(ended[0].exit_code, 42) << "the exception's code, from the container's mapping";
  EXPECT_EQ(ended[1].index, 0u);
  EXPECT_EQ(ended[1].exit_code, kExitPeerLost);
  EXPECT_EQ(ended[2].index, 2u);
  EXPECT_EQ(ended[2].exit_code, kExitOk);
  EXPECT_NE(std::find(trace.begin(), trace.end(), "a lost"), trace.end());
  EXPECT_TRUE(std::none_of(trace.begin(), trace.end(), [](const std::string& line) {
    return line.rfind("b finish", 0) == 0;
  })) << "a component that threw is not finished";
}

TEST(CycleExecutor, AFinishThatWaitsHoldsNoneOfTheOthersInAContainer) {
  // The controller ends first and its finish waits (as a writer's flush waits for readers outside
  // to acknowledge) for what only the drive's last tick gives: the drive must go on meanwhile, as
  // the container hands that finish to a fiber of its own. Were the finish run in place, the drive
  // would never get there and the wait would end at its 10 s deadline without it.
  dds::FiberScheduler scheduler;
  dds::Wakeup controller_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  dds::Wakeup drive_wakeup(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0), &scheduler);
  Trace trace;
  bool last_tick_done = false;
  bool finish_saw_the_last_tick = false;
  Scripted controller("controller", trace, controller_wakeup, [](int) { return CycleStep::finished(kExitOk); });
  Scripted drive("drive", trace, drive_wakeup, [&](int call) {
    if (call < 3) return CycleStep::sleeping_until(monotonic_ns() + 1'000'000);
    last_tick_done = true;
    controller_wakeup.notify();
    return CycleStep::finished(kExitOk);
  });
  std::vector<Ended> ended;
  scheduler.spawn("cycles", [&] {
    const std::vector<CycleComponent*> cycles{&controller, &drive};
    run_cycles(
        cycles,
        [&](std::size_t index, int code) {
          ended.push_back({index, code});
        },
        [](std::size_t, std::exception_ptr error) -> int { std::rethrow_exception(error); },
        [&](std::size_t index, int code) {
          scheduler.spawn("finishing", [&, cycle = cycles[index], index, code] {
            const std::int64_t deadline = monotonic_ns() + 10'000'000'000;
            while (index == 0 && !last_tick_done && monotonic_ns() < deadline) {  // its flush
              controller_wakeup.wait_for(controller_wakeup.generation(), std::chrono::milliseconds(50));
            }
            if (index == 0) finish_saw_the_last_tick = last_tick_done;
            ended.push_back({index, cycle->finish(code)});
          });
        });
  });
  scheduler.run();
  ASSERT_EQ(ended.size(), 2u);
  EXPECT_TRUE(finish_saw_the_last_tick) << "the drive's last tick came while the controller's finish waited";
  EXPECT_EQ(std::count(trace.begin(), trace.end(), "controller finish 0"), 1);
  EXPECT_EQ(std::count(trace.begin(), trace.end(), "drive finish 0"), 1);
}

TEST(CycleExecutor, OutsideAContainerOnlyOneComponentWaits) {
  dds::Wakeup a_wakeup;
  dds::Wakeup b_wakeup;
  Trace trace;
  Scripted a("a", trace, a_wakeup, [](int) { return CycleStep::waiting(); });
  Scripted b("b", trace, b_wakeup, [](int) { return CycleStep::waiting(); });
  EXPECT_THROW(run_cycles(
                   {&a, &b}, [](std::size_t, int) {},
                   [](std::size_t, std::exception_ptr error) -> int { std::rethrow_exception(error); }),
               std::logic_error);
}

TEST(CycleExecutor, AComponentAloneWithADescriptorIsWokenByItAndNeverComposed) {
  // A device on a bus (the virtual drive's CAN socket): its executor sleeps on the descriptor, so a
  // frame wakes it long before the wake time it named. Here each update writes the byte itself
  // before it asks to wait 10 s. Without the descriptor the executor could not update again before
  // its slice (kCycleSliceNs, 50 ms) ends; with it, at once: the quickest of three wakes shows which.
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  dds::Wakeup wakeup;
  Trace trace;
  std::int64_t asked_ns = 0;
  std::int64_t quickest_ns = std::numeric_limits<std::int64_t>::max();
  Scripted device("device", trace, wakeup, [&](int call) {
    char byte = 0;
    if (call > 0) {
      quickest_ns = std::min(quickest_ns, monotonic_ns() - asked_ns);
      EXPECT_EQ(::read(pipe_fds[0], &byte, 1), 1);
    }
    if (call == 3) return CycleStep::finished(kExitOk);
    EXPECT_EQ(::write(pipe_fds[1], "x", 1), 1);
    asked_ns = monotonic_ns();
    return CycleStep::waiting_until(asked_ns + 10'000'000'000);
  });
  device.set_input_fd(pipe_fds[0]);
  EXPECT_EQ(device.run(), kExitOk);
  EXPECT_LT(quickest_ns, kCycleSliceNs);
  EXPECT_EQ(trace, (Trace{"device 0", "device 1", "device 2", "device 3", "device finish 0"}));

  // Beside another component (a container's thread) it could hold them all: refused.
  dds::Wakeup other_wakeup;
  Scripted other("other", trace, other_wakeup, [](int) { return CycleStep::waiting(); });
  EXPECT_THROW(run_cycles(
                   {&other, &device}, [](std::size_t, int) {},
                   [](std::size_t, std::exception_ptr error) -> int { std::rethrow_exception(error); }),
               std::logic_error);
  ::close(pipe_fds[0]);
  ::close(pipe_fds[1]);
}

}  // namespace
}  // namespace pmlsm::node
