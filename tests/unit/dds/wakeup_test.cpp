// Wakeup: how a node's loop thread waits for its readers. Lower time bounds
// are exact (sleeps never end early); upper bounds are loose, for a busy machine.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "pmlsm/dds/participant.hpp"

namespace {

using pmlsm::dds::Wakeup;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

TEST(Wakeup, ANotificationBeforeTheWaitIsNotLost) {
  Wakeup wakeup;
  const auto seen = wakeup.generation();
  wakeup.notify();
  EXPECT_TRUE(wakeup.wait_for(seen, std::chrono::seconds(10)));
}

TEST(Wakeup, NothingArrivingTimesOut) {
  Wakeup wakeup;
  const auto start = Clock::now();
  EXPECT_FALSE(wakeup.wait_for(wakeup.generation(), milliseconds(20)));
  EXPECT_GE(Clock::now() - start, milliseconds(20));
}

TEST(Wakeup, ANotificationFromAnotherThreadEndsTheWait) {
  Wakeup wakeup;
  const auto seen = wakeup.generation();
  std::thread notifier([&] { wakeup.notify(); });
  const auto start = Clock::now();
  EXPECT_TRUE(wakeup.wait_for(seen, std::chrono::seconds(30)));
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(20));
  notifier.join();
}

TEST(Wakeup, ABatchingWakeupSleepsItsBatchWhateverArrives) {
  Wakeup wakeup(std::chrono::nanoseconds(0), milliseconds(50));
  const auto seen = wakeup.generation();
  wakeup.notify();  // counted, wakes nobody
  EXPECT_NE(wakeup.generation(), seen);
  const auto start = Clock::now();
  EXPECT_TRUE(wakeup.wait_for(seen, std::chrono::seconds(30)));
  EXPECT_GE(Clock::now() - start, milliseconds(50));
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(20));
}

TEST(Wakeup, ABatchingWakeupNeverSleepsPastTheTimeout) {
  Wakeup wakeup(std::chrono::nanoseconds(0), std::chrono::seconds(60));
  const auto start = Clock::now();
  EXPECT_FALSE(wakeup.wait_for(wakeup.generation(), milliseconds(30)));
  const auto waited = Clock::now() - start;
  EXPECT_GE(waited, milliseconds(30));
  EXPECT_LT(waited, std::chrono::seconds(20));
}

}  // namespace
