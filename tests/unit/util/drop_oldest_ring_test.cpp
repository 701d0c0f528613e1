// DropOldestRing: the chain's hand-over to a publisher thread. One thread: the queue's order and
// what a full queue drops. Two threads: whatever the interleaving, every sample is popped,
// overwritten, dropped busy or still queued, exactly once, and what is popped is in order and
// never torn.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <thread>
#include <vector>

#include "pmlsm/util/drop_oldest_ring.hpp"

namespace {

using pmlsm::DropOldestRing;
using Push = DropOldestRing<int>::Push;

TEST(DropOldestRing, RefusesACapacityUnderTwo) {
  EXPECT_THROW(DropOldestRing<int>(1), std::invalid_argument);
  EXPECT_THROW(DropOldestRing<int>(0), std::invalid_argument);
}

TEST(DropOldestRing, GivesBackWhatWasPushedInOrder) {
  DropOldestRing<int> ring(4);
  int out = -1;
  EXPECT_FALSE(ring.pop(out));
  for (int i = 0; i < 3; ++i) EXPECT_EQ(ring.push(i), Push::kQueued);
  EXPECT_EQ(ring.pending(), 3U);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(ring.pop(out));
    EXPECT_EQ(out, i);
  }
  EXPECT_FALSE(ring.pop(out));
  EXPECT_EQ(ring.pending(), 0U);
  // Round the ring several times: the slots are reused.
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(ring.push(100 + i), Push::kQueued);
    ASSERT_TRUE(ring.pop(out));
    EXPECT_EQ(out, 100 + i);
  }
}

TEST(DropOldestRing, AFullRingDropsTheOldestAndCountsIt) {
  DropOldestRing<int> ring(4);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(ring.push(i), Push::kQueued);
  EXPECT_EQ(ring.push(4), Push::kOverwrote);  // 0 goes
  EXPECT_EQ(ring.push(5), Push::kOverwrote);  // 1 goes
  EXPECT_EQ(ring.overwritten(), 2U);
  EXPECT_EQ(ring.pending(), 4U);
  int out = -1;
  for (int want = 2; want <= 5; ++want) {
    ASSERT_TRUE(ring.pop(out));
    EXPECT_EQ(out, want);
  }
  EXPECT_FALSE(ring.pop(out));
  // Far past the capacity without a pop: the newest `capacity` remain.
  for (int i = 0; i < 23; ++i) ring.push(1000 + i);
  for (int want = 1019; want <= 1022; ++want) {
    ASSERT_TRUE(ring.pop(out));
    EXPECT_EQ(out, want);
  }
  EXPECT_EQ(ring.pushed(), ring.popped() + ring.overwritten());
}

// A sample whose words all carry its index: a torn copy would show two different values.
struct Wide {
  std::array<std::uint64_t, 16> words{};
};

TEST(DropOldestRing, TwoThreadsLoseNothingUncountedAndNeverTearASample) {
  constexpr std::uint64_t kSamples = 200000;
  DropOldestRing<Wide> ring(8);
  std::atomic<bool> done{false};
  std::vector<std::uint64_t> seen;
  seen.reserve(kSamples);
  bool torn = false;
  std::thread consumer([&] {
    Wide w;
    for (;;) {
      const bool finished = done.load(std::memory_order_acquire);
      while (ring.pop(w)) {
        for (std::uint64_t word : w.words) torn = torn || word != w.words[0];
        seen.push_back(w.words[0]);
      }
      if (finished) break;
    }
  });
  std::uint64_t busy = 0;
  bool last_queued = false;
  Wide w;
  for (std::uint64_t i = 0; i < kSamples; ++i) {
    w.words.fill(i);
    const auto pushed = ring.push(w);
    if (pushed == DropOldestRing<Wide>::Push::kDroppedBusy) ++busy;
    last_queued = pushed != DropOldestRing<Wide>::Push::kDroppedBusy;
  }
  done.store(true, std::memory_order_release);
  consumer.join();
  EXPECT_FALSE(torn);
  for (std::size_t i = 1; i < seen.size(); ++i) ASSERT_LT(seen[i - 1], seen[i]) << "out of order at " << i;
  EXPECT_EQ(busy, ring.dropped_busy());
  EXPECT_EQ(ring.pending(), 0U);
  EXPECT_EQ(seen.size(), ring.popped());
  EXPECT_EQ(kSamples, ring.popped() + ring.overwritten() + ring.dropped_busy());
  ASSERT_FALSE(seen.empty());
  // A queued sample is never lost to a later pop: the newest, once queued, is the last one seen.
  if (last_queued) {
    EXPECT_EQ(seen.back(), kSamples - 1);
  }
}

}  // namespace
