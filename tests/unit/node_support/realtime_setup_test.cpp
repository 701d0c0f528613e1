// The real-time setup a chain node applies before its DDS participant exists.
#include <gtest/gtest.h>

#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "realtime_setup.hpp"

namespace {

using pmlsm::node::RealtimeOptions;
using pmlsm::node::RealtimeSetup;

std::string message_of(const RealtimeOptions& options) {
  try {
    RealtimeSetup setup(options);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(RealtimeSetup, RejectsAPriorityOutsideTheFifoRange) {
  RealtimeOptions o;
  o.rt_priority = 100;
  EXPECT_THROW(RealtimeSetup{o}, std::invalid_argument);
  EXPECT_NE(message_of(o).find("100"), std::string::npos) << message_of(o);
  o.rt_priority = -3;
  EXPECT_NE(message_of(o).find("-3"), std::string::npos) << message_of(o);
}

TEST(RealtimeSetup, RejectsALatencyBelowMinusOne) {
  RealtimeOptions o;
  o.cpu_dma_latency_us = -2;
  EXPECT_THROW(RealtimeSetup{o}, std::invalid_argument);
  EXPECT_NE(message_of(o).find("-2"), std::string::npos) << message_of(o);
}

TEST(RealtimeSetup, SetsATimerSlackOfOneNanosecond) {
  const int before = prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0);
  {
    RealtimeSetup setup(RealtimeOptions{});
    EXPECT_EQ(prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0), 1);
    EXPECT_EQ(setup.summary(), "timer slack 1 ns");
  }
  prctl(PR_SET_TIMERSLACK, static_cast<unsigned long>(before), 0UL, 0UL, 0UL);
}

TEST(RealtimeSetup, WritesTheLatencyRequestAsA32BitValue) {
  // The PM QoS device takes a binary int32; a plain file stands in for it.
  const auto path = std::filesystem::temp_directory_path() / ("pmlsm_dma_latency_" + std::to_string(getpid()));
  { std::ofstream create(path); }
  RealtimeOptions o;
  o.cpu_dma_latency_us = 7;
  o.cpu_dma_latency_device = path.string();
  {
    RealtimeSetup setup(o);
    EXPECT_NE(setup.summary().find("cpu_dma_latency 7 us"), std::string::npos) << setup.summary();
  }
  std::ifstream in(path, std::ios::binary);
  std::int32_t written = -1;
  in.read(reinterpret_cast<char*>(&written), sizeof written);
  EXPECT_EQ(in.gcount(), static_cast<std::streamsize>(sizeof written));
  EXPECT_EQ(written, 7);
  std::filesystem::remove(path);
}

TEST(RealtimeSetup, AMissingLatencyDeviceIsAnErrorNamingIt) {
  RealtimeOptions o;
  o.cpu_dma_latency_us = 0;
  o.cpu_dma_latency_device = "/nonexistent/pmlsm/cpu_dma_latency";
  EXPECT_THROW(RealtimeSetup{o}, std::runtime_error);
  EXPECT_NE(message_of(o).find("/nonexistent/pmlsm/cpu_dma_latency"), std::string::npos) << message_of(o);
}

TEST(RealtimeSetup, FifoPriorityIsAppliedOrRefusedWithTheReason) {
  RealtimeOptions o;
  o.rt_priority = 10;
  std::string error;
  int policy = -1;
  sched_param param{};
  try {
    RealtimeSetup setup(o);
    policy = sched_getscheduler(0);
    sched_getparam(0, &param);
    EXPECT_NE(setup.summary().find("SCHED_FIFO 10, memory locked"), std::string::npos) << setup.summary();
  } catch (const std::runtime_error& e) {
    error = e.what();
  }
  if (error.empty()) {
    EXPECT_EQ(policy, SCHED_FIFO);
    EXPECT_EQ(param.sched_priority, 10);
    // Back to normal scheduling for the rest of the tests.
    sched_param normal{};
    ASSERT_EQ(sched_setscheduler(0, SCHED_OTHER, &normal), 0);
    munlockall();
  } else {
    // Refused all or nothing: normal scheduling stays.
    EXPECT_EQ(sched_getscheduler(0), SCHED_OTHER);
    // Without CAP_SYS_NICE (or CAP_IPC_LOCK): the message says which call and why.
    EXPECT_TRUE(error.find("SCHED_FIFO priority 10 refused") != std::string::npos ||
                error.find("mlockall refused") != std::string::npos)
        << error;
  }
}

}  // namespace
