// When a chain node's input writers leave: a run that ended with its last samples lost on a
// best-effort link, or a writer that stopped early (a lost peer).
#include "input_end.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace pmlsm::node {
namespace {

constexpr double kPeriodS = 1e-3;

/// `s` seconds as the watch's monotonic nanoseconds.
constexpr std::int64_t ns(double s) { return static_cast<std::int64_t>(s * 1e9); }

TEST(InputEnd, TheLastTickLostJustBeforeTheWriterLeftIsATailLost) {
  // Tick 2998 taken; the writer ran to 2999 and left 4 ms later.
  EXPECT_EQ(input_end(2999, 3000, kPeriodS, 0.004, true), InputEnd::kTailLost);
  // Even when the leaving is seen at once (the last sample came late, in a burst).
  EXPECT_EQ(input_end(2999, 3000, kPeriodS, 0.0, true), InputEnd::kTailLost);
}

TEST(InputEnd, AWriterLeavingLongBeforeItsTicksWereDueLeftEarly) {
  // Tick 1499 taken, the writer gone 5 ms later: 1500 ticks (1.5 s) were never written.
  EXPECT_EQ(input_end(1500, 3000, kPeriodS, 0.005, true), InputEnd::kLeftEarly);
  // 100 ticks missing, seen 20 ms after the last: 100 ms of them could not have been written.
  EXPECT_EQ(input_end(2900, 3000, kPeriodS, 0.020, true), InputEnd::kLeftEarly);
  // The same 100 ticks after 60 ms of silence: a link that lost them while the writer ran on.
  EXPECT_EQ(input_end(2900, 3000, kPeriodS, 0.060, true), InputEnd::kTailLost);
}

TEST(InputEnd, InLockstepAMissingTickIsAlwaysAnEarlyEnd) {
  EXPECT_EQ(input_end(2999, 3000, kPeriodS, 10.0, false), InputEnd::kLeftEarly);
  EXPECT_EQ(input_end(3000, 3000, kPeriodS, 0.0, false), InputEnd::kRunComplete);
}

TEST(InputEndWatch, NoWriterBeforeTheFirstSampleIsNotAnEnd) {
  InputEndWatch watch(3000, kPeriodS, true);
  EXPECT_FALSE(watch.tail_lost(0, 0, ns(1.0)));
  EXPECT_FALSE(watch.tail_lost(0, 0, ns(100.0)));
}

TEST(InputEndWatch, TheLeavingIsJudgedWhenFirstSeenNotWhenPolledLater) {
  InputEndWatch watch(3000, kPeriodS, true);
  watch.taken(ns(10.0));                               // tick 2899 taken at 10 s
  EXPECT_FALSE(watch.tail_lost(1, 2900, ns(10.001)));  // the writer still matched
  // Gone 5 ms after the last sample with 100 ticks missing: an early end, however long the
  // node then waits (the plant-lost timeout decides).
  EXPECT_FALSE(watch.tail_lost(0, 2900, ns(10.005)));
  EXPECT_FALSE(watch.tail_lost(0, 2900, ns(12.0)));
  EXPECT_EQ(watch.missing(2900), 100u);
}

TEST(InputEndWatch, AWriterThatMatchesAgainOrASampleStartsAfresh) {
  InputEndWatch watch(3000, kPeriodS, true);
  watch.taken(ns(10.0));
  EXPECT_FALSE(watch.tail_lost(0, 1000, ns(10.002)));  // left early
  EXPECT_FALSE(watch.tail_lost(1, 1000, ns(10.5)));    // a restarted writer matched
  watch.taken(ns(11.0));                               // and its run goes on to tick 2998
  EXPECT_TRUE(watch.tail_lost(0, 2999, ns(11.003)));   // then it left at the run's end
  EXPECT_EQ(watch.missing(2999), 1u);
}

}  // namespace
}  // namespace pmlsm::node
