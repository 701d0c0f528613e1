// The pure helpers of the pmlsm tool: loss accounting and statistics.
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>

#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

TEST(SequenceTracker, CountsGapsPerWriterAndJoinLateApart) {
  SequenceTracker t;
  EXPECT_EQ(t.observe("a", 1), 0u);
  EXPECT_EQ(t.observe("a", 2), 0u);
  EXPECT_EQ(t.observe("a", 5), 2u);   // 3 and 4 lost
  EXPECT_EQ(t.observe("b", 40), 0u);  // b was publishing before we joined
  EXPECT_EQ(t.observe("b", 41), 0u);
  EXPECT_EQ(t.observe("a", 4), 0u);  // late repeat: not a loss, and no new gap after it
  EXPECT_EQ(t.observe("a", 6), 0u);
  EXPECT_EQ(t.lost(), 2u);
  EXPECT_EQ(t.missed_before_join(), 39u);
  EXPECT_EQ(t.out_of_order(), 1u);
  EXPECT_EQ(t.writers(), 2u);
}

TEST(Summarize, NearestRankPercentilesAndMoments) {
  std::vector<double> v;
  for (int i = 100; i >= 1; --i) v.push_back(i);  // unsorted on purpose
  const Summary s = summarize(v);
  EXPECT_EQ(s.count, 100u);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 100.0);
  EXPECT_DOUBLE_EQ(s.mean, 50.5);
  EXPECT_DOUBLE_EQ(s.p50, 50.0);
  EXPECT_DOUBLE_EQ(s.p99, 99.0);
  EXPECT_NEAR(s.stddev, 28.866, 1e-3);
  EXPECT_EQ(summarize({}).count, 0u);
  EXPECT_DOUBLE_EQ(summarize({7.0}).p99, 7.0);
}

TEST(RollingWindow, KeepsTheLastCapacityValues) {
  RollingWindow w(3);
  for (double v : {1.0, 2.0, 3.0, 4.0, 5.0}) w.add(v);
  std::vector<double> kept = w.values();
  std::sort(kept.begin(), kept.end());
  EXPECT_EQ(kept, (std::vector<double>{3.0, 4.0, 5.0}));
  EXPECT_THROW(RollingWindow(0), std::invalid_argument);
}

TEST(HumanBytes, ThousandsWithUnits) {
  EXPECT_EQ(human_bytes(999), "999 B");
  EXPECT_EQ(human_bytes(1234), "1.23 kB");
  EXPECT_EQ(human_bytes(5.5e9), "5.50 GB");
}

TEST(StampRunId, ReadsTheRunIdInEitherByteOrder) {
  std::vector<std::uint8_t> le{0x00, 0x01, 0x00, 0x00};
  for (int i = 0; i < 24; ++i) le.push_back(static_cast<std::uint8_t>(0xA0 + i));
  for (std::uint8_t b : {0x10, 0x32, 0x54, 0x76, 0x98, 0xBA, 0xDC, 0xFE}) le.push_back(b);
  le.push_back(0x99);  // the rest of the message
  EXPECT_EQ(stamp_run_id(le), 0xFEDCBA9876543210ULL);
  std::vector<std::uint8_t> be = le;
  be[1] = 0x00;
  std::reverse(be.begin() + 28, be.begin() + 36);
  EXPECT_EQ(stamp_run_id(be), 0xFEDCBA9876543210ULL);
  le.resize(35);
  EXPECT_EQ(stamp_run_id(le), std::nullopt);  // too short
  be[1] = 0x02;                               // PL_CDR_BE: not a plain stamp
  EXPECT_EQ(stamp_run_id(be), std::nullopt);
}

}  // namespace
}  // namespace pmlsm::tools
