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
  EXPECT_EQ(wait.sleep_ns(0), kCycleSliceNs) << "a stop request is seen within a slice";
  EXPECT_EQ(wait.sleep_ns(100 * kMs), 20 * kMs);
  EXPECT_EQ(wait.sleep_ns(130 * kMs), 0);
  wait.set_timeout_ns(10 * kMs);
  EXPECT_EQ(wait.after(Progress::kWaiting, 11 * kMs), CycleWait::Next::kInputsLost);
}

}  // namespace
}  // namespace pmlsm
