#include "pmlsm/sim/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pmlsm {

double settling_time(const std::vector<double>& values, std::size_t begin, std::size_t end, double band,
                     double period_s) {
  std::size_t last_outside = begin;  // index after the last sample outside the band
  bool any_outside = false;
  for (std::size_t i = begin; i < end; ++i) {
    if (!(std::abs(values[i]) <= band)) {
      last_outside = i + 1;
      any_outside = true;
    }
  }
  if (!any_outside) return 0.0;
  if (last_outside == end) return std::numeric_limits<double>::infinity();
  return static_cast<double>(last_outside - begin) * period_s;
}

ScenarioMetrics compute_metrics(const std::vector<TickRecord>& trace, const Scenario& scenario,
                                double control_period_s) {
  ScenarioMetrics m;
  const std::size_t n = trace.size();
  if (n == 0) return m;

  const auto window = static_cast<std::size_t>(std::llround(scenario.cost_window_s / control_period_s));
  for (std::size_t k = 1; k <= window && k < n; ++k) {
    m.cost_true += std::abs(trace[k].v_ref_mps - trace[k].load_velocity_mps);
    m.cost_estimated += std::abs(trace[k].v_ref_mps - trace[k].est_load_velocity_mps);
  }

  double vib = 0, track = 0, ev = 0, ef = 0, applied = 0;
  for (const TickRecord& r : trace) {
    const double rel = r.load_velocity_mps - r.motor_velocity_mps;
    const double err = r.v_ref_mps - r.load_velocity_mps;
    vib += rel * rel;
    track += err * err;
    ev += std::pow(r.est_load_velocity_mps - r.load_velocity_mps, 2);
    ef += std::pow(r.est_spring_force_n - r.spring_force_n, 2);
    m.peak_force_command_n = std::max(m.peak_force_command_n, std::abs(r.force_command_n));
    m.peak_thrust_n = std::max(m.peak_thrust_n, std::abs(r.thrust_n));
    applied += r.applied_force_n * r.applied_force_n;
    if (r.force_off) ++m.force_off_ticks;
  }
  const double dn = static_cast<double>(n);
  m.load_vibration_rms_mps = std::sqrt(vib / dn);
  m.load_tracking_rms_mps = std::sqrt(track / dn);
  m.est_load_velocity_rms_error_mps = std::sqrt(ev / dn);
  m.est_spring_force_rms_error_n = std::sqrt(ef / dn);
  m.applied_force_rms_n = std::sqrt(applied / dn);

  std::vector<double> signal(n);
  if (scenario.initial_load_displacement_m != 0.0) {
    for (std::size_t i = 0; i < n; ++i) {
      signal[i] = trace[i].load_position_m - trace[i].motor_position_m;
    }
    m.load_settling_time_s = settling_time(
        signal, 0, n, scenario.settling_band * std::abs(scenario.initial_load_displacement_m), control_period_s);
  } else if (scenario.has_constant_segments() && scenario.command_scale_mps() != 0.0) {
    for (std::size_t i = 0; i < n; ++i) signal[i] = trace[i].v_ref_mps - trace[i].load_velocity_mps;
    const double band = scenario.settling_band * scenario.command_scale_mps();
    // Split the run where the scenario's raw command changes and take the worst constant segment
    // (two ticks or more): the flat parts of a step, pulse, ramp, trapezoid, S-curve or profile.
    // The ticks of a rise or fall change every tick and are tracking, not settling. The raw
    // command, not the trace's (which is input-shaped when the scenario shapes it): settling
    // counts from the step asked for, so a shaper's delay is part of it.
    std::size_t begin = 0;
    double worst = 0;
    double previous = n > 0 ? scenario.command_mps(trace[0].time_s) : 0.0;
    for (std::size_t i = 1; i <= n; ++i) {
      const double command = i < n ? scenario.command_mps(trace[i].time_s) : previous;
      if (i == n || command != previous) {
        if (i - begin >= 2) worst = std::max(worst, settling_time(signal, begin, i, band, control_period_s));
        begin = i;
      }
      previous = command;
    }
    m.load_settling_time_s = worst;
  } else {
    m.load_settling_time_s = 0.0;
  }
  return m;
}

}  // namespace pmlsm
