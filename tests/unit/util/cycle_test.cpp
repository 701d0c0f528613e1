// The executor's rule for a component's cycle (pmlsm/util/cycle.hpp), on given times: work resets
// the wait, a wait longer than the input timeout loses the inputs, sleeps are sliced.
#include "pmlsm/util/cycle.hpp"

#include <gtest/gtest.h>

namespace pmlsm {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(CycleWait, WorkResetsTheWaitAndTheTimeoutCountsFromTheLastWork) {
  CycleWait wait(1000 * kMs, 0);
  EXPECT_EQ(wait.after(Progress::kWaiting, 999 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.after(Progress::kWorked, 999 * kMs), CycleWait::Next::kUpdate);
  // 1.5 s after the start but 0.5 s after the work: still waiting.
  EXPECT_EQ(wait.after(Progress::kWaiting, 1500 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.after(Progress::kWaiting, 1998 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.after(Progress::kWaiting, 1999 * kMs), CycleWait::Next::kInputsLost);
  EXPECT_EQ(wait.after(Progress::kFinished, 1999 * kMs), CycleWait::Next::kFinished);
}

TEST(CycleWait, SleepsInSlicesAndNeverPastTheDeadline) {
  CycleWait wait(120 * kMs, 0);
  ASSERT_EQ(wait.after(Progress::kWaiting, 0), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.wake_ns(), kCycleSliceNs) << "a stop request is seen within a slice";
  ASSERT_EQ(wait.after(Progress::kWaiting, 100 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.wake_ns(), 120 * kMs) << "the timeout, before the slice";
  EXPECT_EQ(wait.after(Progress::kWaiting, 130 * kMs), CycleWait::Next::kInputsLost);
  wait.set_timeout_ns(10 * kMs);
  EXPECT_EQ(wait.after(Progress::kWaiting, 131 * kMs), CycleWait::Next::kInputsLost);
}

TEST(CycleWait, AWaitWithADeadlineEndsAtTheDeadlineAndTheInputTimeoutStillRuns) {
  CycleWait wait(1000 * kMs, 0);
  // A realtime drive waiting for its tick's command until the deadline 0.5 ms into the tick.
  ASSERT_EQ(wait.after(CycleStep::waiting_until(3 * kMs / 2), kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.wake_ns(), 3 * kMs / 2);
  // A deadline already past: update again at once, not later.
  ASSERT_EQ(wait.after(CycleStep::waiting_until(kMs), 2 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.wake_ns(), 2 * kMs) << "now, not the deadline behind it";
  // A deadline past the input timeout does not stretch it.
  ASSERT_EQ(wait.after(CycleStep::waiting_until(5000 * kMs), 990 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.wake_ns(), 1000 * kMs);
  EXPECT_EQ(wait.after(CycleStep::waiting_until(5000 * kMs), 1000 * kMs), CycleWait::Next::kInputsLost);
}

TEST(CycleWait, ASleepToATimeIsTheComponentsOwnAndTheInputTimeoutCountsFromItsEnd) {
  CycleWait wait(10 * kMs, 0);
  // A drive's next tick 50 ms away (a slow clock): no input is lost while it sleeps.
  const CycleStep tick = CycleStep::sleeping_until(50 * kMs, 20'000);
  ASSERT_EQ(wait.after(tick, 9 * kMs), CycleWait::Next::kSleepUntil);
  EXPECT_EQ(wait.wake_ns(), 50 * kMs);
  EXPECT_EQ(tick.spin_ns, 20'000);
  EXPECT_EQ(wait.after(Progress::kWaiting, 59 * kMs), CycleWait::Next::kSleep);
  EXPECT_EQ(wait.after(Progress::kWaiting, 60 * kMs), CycleWait::Next::kInputsLost);
}

}  // namespace
}  // namespace pmlsm
