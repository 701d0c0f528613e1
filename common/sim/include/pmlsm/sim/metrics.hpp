// Figures of merit of a closed-loop run, computed from its trace.
#pragma once

#include <cstdint>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/scenario.hpp"

namespace pmlsm {

struct ScenarioMetrics {
  /// Cost (23)-(24): sum over k = 1..K of |V_ref(k) - V_load(k)|, K = cost window / T,
  /// with the true load velocity and with the Kalman estimate (the paper's V_load).
  double cost_true = 0;
  double cost_estimated = 0;
  /// RMS of v_L - v_M over the run: zero when the load moves rigidly with the motor.
  double load_vibration_rms_mps = 0;
  /// RMS of V_ref - v_L over the run.
  double load_tracking_rms_mps = 0;
  /// Settling time to the band (2 %):
  ///  - with an initial load displacement: time after which |x_L - x_M| stays
  ///    within band * |initial displacement|;
  ///  - with a command made of constant segments (step, pulse, the hold and rest of a
  ///    ramp, trapezoid or S-curve, flat stretches of a CSV profile): the longest time,
  ///    over the command's constant segments of two ticks or more, after which
  ///    |V_ref - v_L| stays within band * command_scale_mps() until the segment ends;
  ///    the rises and falls between them are tracking (load_tracking_rms_mps), not settling.
  ///    Infinity when it never settles;
  ///  - sines, chirps, multi-sines: 0 (no segment to settle in; see the tracking RMS).
  double load_settling_time_s = 0;
  double peak_force_command_n = 0;
  double peak_thrust_n = 0;
  /// RMS of the Kalman filter's load-velocity and spring-force errors over the run.
  double est_load_velocity_rms_error_mps = 0;
  double est_spring_force_rms_error_n = 0;
  /// RMS of the force the drive applied (MotorFeedback's applied_force_n): near zero for a
  /// run spent with the force off, whatever the controller commanded.
  double applied_force_rms_n = 0;
  /// Ticks at which the drive had its force off (fault, safe state, not enabled): 0 in a valid run.
  std::uint64_t force_off_ticks = 0;
};

/// Time from the start of samples[begin, end) after which |value| <= band holds
/// to the end; +infinity when the last sample is outside the band.
double settling_time(const std::vector<double>& values, std::size_t begin, std::size_t end, double band,
                     double period_s);

ScenarioMetrics compute_metrics(const std::vector<TickRecord>& trace, const Scenario& scenario,
                                double control_period_s);

}  // namespace pmlsm
