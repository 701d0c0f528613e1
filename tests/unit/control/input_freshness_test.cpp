// InputFreshness: the controller's judgement of a compensation computed in another process.
#include <gtest/gtest.h>

#include <optional>
#include <stdexcept>

#include "pmlsm/control/input_freshness.hpp"

namespace {

using pmlsm::InputFreshness;
using Change = InputFreshness::Change;

TEST(InputFreshness, RefusesAMaximumAgeOfZero) { EXPECT_THROW(InputFreshness(0), std::invalid_argument); }

TEST(InputFreshness, UsesAnInputUpToItsMaximumAgeAndNotBeyond) {
  InputFreshness f(3);
  EXPECT_TRUE(f.step(10, 9).on_time);   // output k-1 for tick k
  EXPECT_TRUE(f.step(12, 9).on_time);   // three ticks old
  EXPECT_FALSE(f.step(13, 9).on_time);  // four
  EXPECT_FALSE(f.step(5, std::nullopt).on_time);
}

TEST(InputFreshness, TickZeroIsNotJudged) {
  InputFreshness f(3);
  const InputFreshness::Step s = f.step(0, std::nullopt);
  EXPECT_FALSE(s.on_time);
  EXPECT_EQ(s.change, Change::kNone);
  EXPECT_EQ(f.counters().ticks, 0U);
}

TEST(InputFreshness, TheStartIsCountedApartFromTheEpisodesAfterIt) {
  InputFreshness f(3);
  for (std::uint64_t k = 1; k <= 5; ++k) EXPECT_EQ(f.step(k, std::nullopt).change, Change::kNone);
  const InputFreshness::Step first = f.step(6, 5);
  EXPECT_EQ(first.change, Change::kFirst);
  EXPECT_EQ(first.gap_ticks, 5U);
  EXPECT_TRUE(first.on_time);
  EXPECT_EQ(f.counters().ticks_before_first, 5U);
  EXPECT_EQ(f.counters().late_ticks, 0U);
  EXPECT_EQ(f.counters().episodes, 0U);
}

TEST(InputFreshness, AGapIsOneEpisodeToldAtItsStartAndEndWithItsLength) {
  InputFreshness f(3);
  std::uint64_t newest = 0;
  for (std::uint64_t k = 1; k <= 400; ++k) {
    // The link is down for ticks 40..339 (300 ms): nothing new arrives.
    if (k < 40 || k >= 340) newest = k - 1;
    const InputFreshness::Step s = f.step(k, newest);
    if (k == 1) {
      EXPECT_EQ(s.change, Change::kFirst);
    } else if (k == 42) {
      EXPECT_EQ(s.change, Change::kLate);  // the input of tick 38 is four ticks old
    } else if (k == 340) {
      EXPECT_EQ(s.change, Change::kBack);
      EXPECT_EQ(s.gap_ticks, 298U);  // ticks 42..339
      EXPECT_TRUE(s.on_time);
    } else {
      EXPECT_EQ(s.change, Change::kNone) << k;
    }
  }
  EXPECT_EQ(f.counters().ticks, 400U);
  EXPECT_EQ(f.counters().ticks_before_first, 0U);
  EXPECT_EQ(f.counters().late_ticks, 298U);
  EXPECT_EQ(f.counters().episodes, 1U);
  EXPECT_EQ(f.counters().longest_gap_ticks, 298U);
}

TEST(InputFreshness, ANewRunStartsAnew) {
  InputFreshness f(2);
  EXPECT_EQ(f.step(1, 0).change, Change::kFirst);
  EXPECT_EQ(f.step(5, 0).change, Change::kLate);
  f.reset();
  // A restarted drive: its first ticks are a start again, not the old episode going on.
  EXPECT_EQ(f.step(1, std::nullopt).change, Change::kNone);
  EXPECT_EQ(f.step(2, 1).change, Change::kFirst);
  EXPECT_EQ(f.counters().ticks_before_first, 1U);
  EXPECT_EQ(f.counters().episodes, 1U);
}

}  // namespace
