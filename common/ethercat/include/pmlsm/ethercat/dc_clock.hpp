// A slave's distributed clock (ETG.1000.4, the ET1100's DC unit): a local clock that runs at its
// own crystal's rate (a drift in ppm), the system time the master sees (local time + the offset the
// master wrote to 0x0920), and the drift control that keeps it on the times the master writes to
// 0x0910: each write is compared with the clock's own system time (plus the delay of 0x0928), the
// difference filtered into 0x092C, and the clock's rate corrected by it.
//
// The drift control is a proportional-integral loop on the rate, fed by the filtered difference d
// (a running mean over about 16 writes, so a link's jitter moves the rate little): with writes T
// apart, c = kp d + sum ki d, kp T = 0.1 and ki T = 0.005 for T = 1 ms. A 100 ppm crystal is
// followed to under 1 us within 2 s of writes (the DistributedClockDrift test: 40 ns from 2 s on,
// 1.3 us at worst before 1 s). The correction is limited to +-1000 ppm (a crystal's tolerance is
// +-100 ppm); a write whose difference is beyond 1 ms (a master that set no offset, or another
// time base) moves the clock there at once, and the loop starts again. Pure; no allocation.
#pragma once

#include <cstdint>

namespace pmlsm::ethercat {

struct DcClockParams {
  /// The local crystal's rate error: +100 runs 100 ppm fast.
  double drift_ppm = 0.0;
  /// The local time at the first advance_to() [ns].
  std::uint64_t start_local_ns = 0;
  /// The writes' nominal period the loop gains are set for [ns].
  std::int64_t write_period_ns = 1'000'000;
  /// @throws std::invalid_argument naming the value: drift beyond +-1000 ppm, a period <= 0.
  void validate() const;
};

class DcClock {
 public:
  /// @throws std::invalid_argument from the params.
  explicit DcClock(DcClockParams params = {});

  /// The wall time (any monotonic origin, the simulation's or the host's) is now `now_ns`: the
  /// local clock runs on by the time passed at its own rate.
  void advance_to(std::int64_t now_ns) noexcept;
  /// The crystal's rate error from now on. @throws std::invalid_argument beyond +-1000 ppm.
  void set_drift_ppm(double drift_ppm);
  std::uint64_t local_ns() const noexcept { return local_ns_; }
  /// Local time + the offset: what 0x0910 reads.
  std::uint64_t system_time_ns() const noexcept { return local_ns_ + offset_ns_; }
  void set_offset_ns(std::uint64_t offset) noexcept { offset_ns_ = offset; }
  std::uint64_t offset_ns() const noexcept { return offset_ns_; }
  void set_delay_ns(std::uint32_t delay) noexcept { delay_ns_ = delay; }
  /// A system time the master wrote (0x0910): compared, filtered, the rate corrected.
  void on_system_time_written(std::uint64_t received_ns) noexcept;
  /// The filtered difference (received + delay) - own system time [ns] (0x092C's value).
  std::int64_t difference_ns() const noexcept { return difference_ns_; }
  /// The rate correction the drift control applies now [ppm].
  double correction_ppm() const noexcept { return correction_ * 1e6; }
  std::uint64_t writes() const noexcept { return writes_; }

 private:
  DcClockParams params_;
  bool started_ = false;
  std::int64_t last_now_ns_ = 0;
  std::uint64_t local_ns_ = 0;
  double fraction_ns_ = 0.0;  ///< below a nanosecond, carried on
  std::uint64_t offset_ns_ = 0;
  std::uint32_t delay_ns_ = 0;
  double integral_ = 0.0;    ///< the loop's integral term (a rate)
  double correction_ = 0.0;  ///< the rate correction now
  std::int64_t difference_ns_ = 0;
  std::uint64_t writes_ = 0;
};

}  // namespace pmlsm::ethercat
