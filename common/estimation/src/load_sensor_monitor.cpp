// The load sensor's health: see load_sensor_monitor.hpp.
#include "pmlsm/estimation/load_sensor_monitor.hpp"

#include <algorithm>
#include <cmath>

namespace pmlsm {

const char* to_string(LoadSensorFault fault) {
  switch (fault) {
    case LoadSensorFault::kNone: return "none";
    case LoadSensorFault::kSilent: return "silent (no reading)";
    case LoadSensorFault::kSaturated: return "saturated (at its rail)";
    case LoadSensorFault::kJumping: return "jumping (faster than the load moves)";
    case LoadSensorFault::kStuck: return "stuck (the reading does not change while the load moves)";
  }
  return "none";
}

LoadSensorMonitorParams LoadSensorMonitorParams::of(const LoadSensorParams& sensor, double period_s) {
  LoadSensorMonitorParams p;
  p.kind = sensor.kind;
  p.period_s = period_s;
  p.window_ticks = static_cast<std::uint32_t>(std::max(1.0, std::ceil(sensor.fault_after_s / period_s - 1e-9)));
  p.saturated_window_ticks =
      static_cast<std::uint32_t>(std::max(1.0, std::ceil(sensor.saturated_fail_after_s / period_s - 1e-9)));
  p.resolution_m = sensor.resolution_m;
  p.max_speed_mps = sensor.max_speed_mps;
  p.stuck_travel_m = sensor.stuck_travel_m;
  p.noisy = sensor.kind == LoadSensorKind::kAccelerometer && sensor.noise_density_mps2_per_sqrt_hz > 0.0;
  return p;
}

LoadSensorVerdict LoadSensorMonitor::fail(std::uint64_t tick, LoadSensorFault fault) {
  fault_ = fault;
  failed_at_tick_ = tick;
  return {false, fault};
}

LoadSensorVerdict LoadSensorMonitor::judge(std::uint64_t tick, double position_m, double accel_mps2, bool saturated,
                                           double motor_position_m) {
  if (params_.kind == LoadSensorKind::kNone) return {false, LoadSensorFault::kNone};
  if (failed()) return {false, fault_};
  const bool encoder = params_.kind == LoadSensorKind::kEncoder;
  const double value = encoder ? position_m : accel_mps2;
  LoadSensorFault problem = LoadSensorFault::kNone;
  if (!std::isfinite(value)) {
    problem = LoadSensorFault::kSilent;
  } else if (!encoder && saturated) {
    problem = LoadSensorFault::kSaturated;
  } else if (encoder && have_last_ &&
             std::abs(value - last_value_) > params_.max_speed_mps * params_.period_s + params_.resolution_m) {
    problem = LoadSensorFault::kJumping;
  }
  if (problem == LoadSensorFault::kSaturated) {
    // At the rail: refused, failed only after saturated_window_ticks of it; the next reading off
    // the rail starts the stuck test afresh (the rail's value repeats by nature).
    ++rejected_;
    have_last_ = false;
    unchanged_ = 0;
    if (++saturated_in_row_ >= params_.saturated_window_ticks) return fail(tick, problem);
    return {false, problem};
  }
  saturated_in_row_ = 0;
  if (std::isfinite(value)) {
    // Stuck: the same reading tick after tick, while the motor travelled (encoder) or a noisy
    // part's reading should have changed (accelerometer).
    if (have_last_ && value == last_value_) {
      ++unchanged_;
    } else {
      unchanged_ = 0;
      motor_at_change_m_ = motor_position_m;
    }
    last_value_ = value;  // after a jump the new count is the reference: one tick rejected, not all
    have_last_ = true;
    const bool stuck =
        unchanged_ >= params_.window_ticks &&
        (encoder ? std::abs(motor_position_m - motor_at_change_m_) > params_.stuck_travel_m : params_.noisy);
    if (stuck) {
      ++rejected_;
      return fail(tick, LoadSensorFault::kStuck);
    }
  }
  if (problem == LoadSensorFault::kNone) {
    bad_in_row_ = 0;
    return {true, problem};
  }
  ++rejected_;
  if (++bad_in_row_ >= params_.window_ticks) return fail(tick, problem);
  return {false, problem};
}

}  // namespace pmlsm
