// Whether the load's sensor may be believed, tick by tick (a sensor declared in sensors.load):
//   silent     no reading where one was declared (a cable off, a drive that stopped sending it)
//   saturated  the accelerometer at its rail
//   jumping    a load encoder's reading moved further in one tick than the load can,
//              |x_k - x_k-1| > v_max T + q (a burst of lost or spurious counts)
//   stuck      a load encoder's count unchanged over the window while the motor's encoder moved
//              more than stuck_travel_m (the load follows the motor on its spring: 0.5 mm of
//              travel pulls it through many counts well within 10 ms; the filter's own estimate
//              is no witness, since it follows the stuck count); an accelerometer's reading the very
//              same number over the window (a live part's noise moves it every tick)
// A reading judged bad is not used (counted). A sensor bad for the whole window in a row (silent,
// jumping), or stuck, has failed: latched for the run, the filter back on the motor's side alone,
// the reason and the tick kept for the report. The window is fault_after_s (10 ms: ten ticks at
// 1 kHz). An accelerometer at its rail is refused at once too, but a live part reaches it at the
// peaks of a violent swing (a 20 mm release on a light, stiff load: 28 g against a 16 g part, for
// 17 ms), so it fails only after saturated_fail_after_s at the rail in a row, and the rail's
// repeated value is no sign of a stuck part. Pure; no allocation.
#pragma once

#include <cstdint>

#include "pmlsm/plant/load_sensor.hpp"

namespace pmlsm {

enum class LoadSensorFault { kNone, kSilent, kSaturated, kJumping, kStuck };
const char* to_string(LoadSensorFault fault);

struct LoadSensorMonitorParams {
  LoadSensorKind kind = LoadSensorKind::kNone;
  double period_s = 0;
  std::uint32_t window_ticks = 0;            ///< fault_after_s in ticks, >= 1
  std::uint32_t saturated_window_ticks = 0;  ///< saturated_fail_after_s in ticks, >= 1
  double resolution_m = 0;                   ///< an encoder's count
  double max_speed_mps = 0;                  ///< v_max: faster than this the load does not move
  double stuck_travel_m = 0;                 ///< the motor's travel over the window an encoder's count must follow
  bool noisy = false;                        ///< an accelerometer with noise: a reading that repeats is stuck
  /// From the sensor's declaration, read every `period_s`.
  static LoadSensorMonitorParams of(const LoadSensorParams& sensor, double period_s);
};

struct LoadSensorVerdict {
  bool use = false;                                  ///< the reading may correct the estimate
  LoadSensorFault problem = LoadSensorFault::kNone;  ///< why not (this tick)
};

class LoadSensorMonitor {
 public:
  explicit LoadSensorMonitor(const LoadSensorMonitorParams& params) : params_(params) {}
  /// Tick `tick`'s reading (NaN: none) with the motor encoder's position at the same tick.
  LoadSensorVerdict judge(std::uint64_t tick, double position_m, double accel_mps2, bool saturated,
                          double motor_position_m);
  bool failed() const { return fault_ != LoadSensorFault::kNone; }
  LoadSensorFault fault() const { return fault_; }
  std::uint64_t failed_at_tick() const { return failed_at_tick_; }
  std::uint64_t rejected() const { return rejected_; }

 private:
  LoadSensorVerdict fail(std::uint64_t tick, LoadSensorFault fault);

  LoadSensorMonitorParams params_;
  LoadSensorFault fault_ = LoadSensorFault::kNone;
  std::uint64_t failed_at_tick_ = 0;
  std::uint64_t rejected_ = 0;
  std::uint32_t bad_in_row_ = 0;        ///< refused readings in a row, the rail's aside
  std::uint32_t saturated_in_row_ = 0;  ///< readings at the rail in a row
  bool have_last_ = false;
  double last_value_ = 0;         ///< the last reading (position or acceleration)
  std::uint32_t unchanged_ = 0;   ///< ticks the reading has not changed
  double motor_at_change_m_ = 0;  ///< the motor's position when the reading last changed (encoder)
};

}  // namespace pmlsm
