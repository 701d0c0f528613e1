// TickFilter: which MotorFeedback ticks the controller and the estimator take.
#include <gtest/gtest.h>

#include "tick_filter.hpp"

namespace {

using pmlsm::node::TickFilter;

TEST(TickFilter, TakesTicksInOrderAndRejectsOldOnes) {
  TickFilter f;
  EXPECT_TRUE(f.accept(0));
  EXPECT_TRUE(f.accept(1));
  EXPECT_FALSE(f.accept(1));  // duplicate
  EXPECT_FALSE(f.accept(0));  // out of order
  EXPECT_TRUE(f.accept(5));   // a gap within the bound
  EXPECT_EQ(f.expected(), 6u);
}

TEST(TickFilter, TheFirstTickIsTakenWhateverItIs) {
  TickFilter f(10);
  EXPECT_TRUE(f.accept(123456));  // joining a running system
  EXPECT_EQ(f.expected(), 123457u);
}

TEST(TickFilter, ASingleFarFutureTickIsRejectedAndTheStreamGoesOn) {
  TickFilter f(10);
  EXPECT_TRUE(f.accept(0));
  EXPECT_FALSE(f.accept(1000));  // malformed
  EXPECT_TRUE(f.accept(1));      // the genuine stream is not taken for stale
  EXPECT_TRUE(f.accept(2));
  EXPECT_FALSE(f.accept(1001));  // not a successor of an accepted far tick: 1000 was forgotten
  EXPECT_EQ(f.expected(), 3u);
}

TEST(TickFilter, AFarJumpFollowedByItsSuccessorIsTaken) {
  TickFilter f(10);
  EXPECT_TRUE(f.accept(0));
  EXPECT_FALSE(f.accept(500));  // the writer's history overflowed: ticks really skipped
  EXPECT_TRUE(f.accept(501));   // its successor confirms it
  EXPECT_EQ(f.expected(), 502u);
  EXPECT_TRUE(f.accept(502));
}

TEST(TickFilter, TheBoundItselfIsNear) {
  TickFilter f(10);
  EXPECT_TRUE(f.accept(0));
  EXPECT_TRUE(f.accept(11));   // expected 1, 1 + 10
  EXPECT_FALSE(f.accept(23));  // expected 12, 12 + 11
}

}  // namespace
