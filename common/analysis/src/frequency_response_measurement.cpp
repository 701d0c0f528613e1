#include "pmlsm/analysis/frequency_response_measurement.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

MultisineParams multisine_params(const FrequencyResponseMeasurementParams& p) {
  MultisineParams m;
  m.amplitude_n = p.amplitude_n;
  m.min_frequency_hz = p.min_frequency_hz;
  m.max_frequency_hz = p.max_frequency_hz;
  m.resolution_hz = p.resolution_hz;
  m.period_s = p.period_s;
  m.dense_max_frequency_hz = p.dense_max_frequency_hz;
  m.lines_per_decade = p.lines_per_decade;
  return m;
}

VelocityPi checked_pi(const VelocityPiParams& pi, const FrequencyResponseMeasurementParams& p) {
  if (std::fabs(pi.period_s - p.period_s) > 1e-12) {
    throw std::invalid_argument("velocity loop period " + format_value(pi.period_s) +
                                " s differs from the measurement's " + format_value(p.period_s) + " s");
  }
  if (p.amplitude_n >= pi.force_limit_n) {
    throw std::invalid_argument("amplitude_n: the excitation's peak " + format_value(p.amplitude_n) +
                                " N would exceed the force limit (velocity_loop.force_limit_n " +
                                format_value(pi.force_limit_n) + " N) with the loop's own force on top");
  }
  return VelocityPi(pi);
}

/// v0 moved so that the ripple's f_r = v0 / tau lies at (m + 1/4) df, m >= 0 (see the header).
double ripple_quarter_line_velocity(double velocity_mps, double pole_pitch_m, double resolution_hz) {
  const double lines = std::fabs(velocity_mps) / pole_pitch_m / resolution_hz;
  const double m = std::max(0.0, std::round(lines - 0.25));
  return std::copysign((m + 0.25) * resolution_hz * pole_pitch_m, velocity_mps);
}

}  // namespace

void FrequencyResponseMeasurementParams::validate_entries() const {
  check_declared_ranges(*this);
  if (!(max_frequency_hz > min_frequency_hz)) {
    throw std::invalid_argument("max_frequency_hz: must lie above min_frequency_hz (" + format_value(min_frequency_hz) +
                                "), got " + format_value(max_frequency_hz));
  }
  if (offset_velocity_mps == 0.0) {
    throw std::invalid_argument("offset_velocity_mps: must not be 0 (at rest the bearings stick), got 0");
  }
  if (measure_periods % 4 != 0) {
    throw std::invalid_argument("measure_periods: must be a multiple of 4 (the ripple cancels over 4), got " +
                                std::to_string(measure_periods));
  }
}

void FrequencyResponseMeasurementParams::validate() const {
  validate_entries();
  multisine_params(*this).validate();
  require_in_range("ramp_s", ramp_s, period_s, 60.0);  // at least a tick
  require_positive("pole_pitch_m", pole_pitch_m);      // the plant's
}

const char* measurement_phase_name(MeasurementPhase phase) {
  switch (phase) {
    case MeasurementPhase::kRamp: return "ramp";
    case MeasurementPhase::kExcite: return "excite";
    case MeasurementPhase::kStop: return "stop";
    case MeasurementPhase::kDone: return "done";
    case MeasurementPhase::kAborted: return "aborted";
  }
  return "?";
}

FrequencyResponseMeasurement::FrequencyResponseMeasurement(const FrequencyResponseMeasurementParams& params,
                                                           const VelocityPiParams& velocity_pi)
    : params_((params.validate(), params)),
      excitation_(multisine_params(params_)),
      velocity_pi_(checked_pi(velocity_pi, params_)) {
  offset_velocity_mps_ =
      ripple_quarter_line_velocity(params_.offset_velocity_mps, params_.pole_pitch_m, excitation_.resolution_hz());
  if (std::fabs(offset_velocity_mps_) >= params_.max_velocity_mps) {
    throw std::invalid_argument("offset_velocity_mps: " + format_value(offset_velocity_mps_) +
                                " m/s is not below the measurement's velocity limit max_velocity_mps " +
                                format_value(params_.max_velocity_mps) + " m/s");
  }
  ramp_ticks_ = static_cast<std::uint64_t>(std::llround(params_.ramp_s / params_.period_s));
  const std::size_t excite_ticks = (params_.settle_periods + params_.measure_periods) * excitation_.ticks_per_period();
  excite_end_tick_ = ramp_ticks_ + excite_ticks;
  measure_start_tick_ = ramp_ticks_ + params_.settle_periods * excitation_.ticks_per_period();
  trim_gain_per_s_ = 4.0 / (static_cast<double>(params_.settle_periods) / excitation_.resolution_hz());
  stop_end_tick_ = excite_end_tick_ + ramp_ticks_;
  // Travel: half a ramp each end and the excitation at v0.
  const double travel_m =
      std::fabs(offset_velocity_mps_) * (static_cast<double>(ramp_ticks_ + excite_ticks) * params_.period_s);
  if (travel_m > params_.max_travel_m) {
    throw std::invalid_argument("the measurement would leave the stroke: it travels " + format_value(travel_m) +
                                " m at " + format_value(offset_velocity_mps_) + " m/s, the limit max_travel_m is " +
                                format_value(params_.max_travel_m) + " m");
  }
  excitation_n_.reserve(excite_ticks);
  force_n_.reserve(excite_ticks);
  velocity_mps_.reserve(excite_ticks);
  load_velocity_mps_.reserve(excite_ticks);
  abort_reason_.reserve(200);
}

double FrequencyResponseMeasurement::velocity_command_mps() const {
  if (tick_ < ramp_ticks_) {
    return offset_velocity_mps_ * static_cast<double>(tick_) / static_cast<double>(ramp_ticks_);
  }
  if (tick_ < excite_end_tick_) return offset_velocity_mps_ + velocity_trim_mps_;
  if (tick_ < stop_end_tick_) {  // from where the trim left the command, so it does not step
    return (offset_velocity_mps_ + velocity_trim_mps_) * static_cast<double>(stop_end_tick_ - tick_) /
           static_cast<double>(ramp_ticks_);
  }
  return 0.0;
}

void FrequencyResponseMeasurement::abort(const char* what, double value, double limit) {
  phase_ = MeasurementPhase::kAborted;
  char text[200];
  if (std::isnan(limit)) {
    std::snprintf(text, sizeof text, "%s at tick %llu", what, static_cast<unsigned long long>(tick_));
  } else {
    std::snprintf(text, sizeof text, "%s at tick %llu: %.6g, the limit is %.6g", what,
                  static_cast<unsigned long long>(tick_), value, limit);
  }
  abort_reason_ = text;  // fits the reserved capacity: no allocation
  last_force_n_ = 0.0;
}

double FrequencyResponseMeasurement::step(const drive::Measurement& m, bool operation_enabled) {
  if (finished()) return 0.0;
  if (!operation_enabled) {
    abort("the drive left operation enabled", 0.0, std::nan(""));
    return 0.0;
  }
  if (!std::isfinite(m.position_m) || !std::isfinite(m.velocity_mps)) {
    abort("a non-finite reading of the position or velocity", 0.0, std::nan(""));
    return 0.0;
  }
  if (!have_start_) {
    start_position_m_ = m.position_m;
    have_start_ = true;
  }
  const double travel_m = std::fabs(m.position_m - start_position_m_);
  if (travel_m > params_.max_travel_m) {
    abort("travel from the start [m]", travel_m, params_.max_travel_m);
    return 0.0;
  }
  if (std::fabs(m.velocity_mps) > params_.max_velocity_mps) {
    abort("velocity [m/s]", m.velocity_mps, params_.max_velocity_mps);
    return 0.0;
  }
  // The velocity measured now is the mean over the tick the last force was held: one sample,
  // with the force the drive says it held when it says (a command that reached it late left the
  // one before in force), else the one sent.
  if (last_recorded_) {
    const bool reported = std::isfinite(m.applied_force_n);
    excitation_n_.push_back(last_excitation_n_);
    force_n_.push_back(reported ? m.applied_force_n : last_force_n_);
    if (reported && m.applied_force_n != last_force_n_) ++late_ticks_;
    velocity_mps_.push_back(m.velocity_mps);
    // The load's velocity over the same tick, from its encoder's two readings.
    if (std::isfinite(m.load_position_m) && std::isfinite(last_load_position_m_)) {
      if (load_velocity_mps_.size() + 1 == velocity_mps_.size()) {
        load_velocity_mps_.push_back((m.load_position_m - last_load_position_m_) / params_.period_s);
      }
    } else if (!load_velocity_mps_.empty()) {
      load_lost_ = true;
    }
  }
  last_load_position_m_ = m.load_position_m;
  const bool exciting = tick_ >= ramp_ticks_ && tick_ < excite_end_tick_;
  // The PI's integral is weak (Table 3: K_i = 0.01 N/m): the motor runs slower than commanded by
  // the friction over K_p. A slow trim of the command, frozen before the averaged periods, brings
  // the mean velocity to v0 so the ripple falls where it cancels.
  if (exciting && tick_ < measure_start_tick_) {
    velocity_trim_mps_ += trim_gain_per_s_ * params_.period_s * (offset_velocity_mps_ - m.velocity_mps);
  }
  const double excitation_n = exciting ? excitation_.value(tick_ - ramp_ticks_) : 0.0;
  const VelocityPiOutput out = velocity_pi_.step({velocity_command_mps(), m.velocity_mps, excitation_n});
  if (out.saturated) {
    abort("force [N]", out.force_n, velocity_pi_.params().force_limit_n);
    return 0.0;
  }
  last_force_n_ = out.force_n;
  last_excitation_n_ = excitation_n;
  last_recorded_ = exciting;
  ++tick_;
  phase_ = tick_ < ramp_ticks_        ? MeasurementPhase::kRamp
           : tick_ < excite_end_tick_ ? MeasurementPhase::kExcite
           : tick_ < stop_end_tick_   ? MeasurementPhase::kStop
                                      : MeasurementPhase::kDone;
  return out.force_n;
}

std::vector<FrequencyPoint> FrequencyResponseMeasurement::response() const {
  if (phase_ != MeasurementPhase::kDone) {
    throw std::invalid_argument("the measurement did not complete (" + std::string(measurement_phase_name(phase_)) +
                                (abort_reason_.empty() ? "" : ": " + abort_reason_) + ")");
  }
  return estimate_frequency_response(excitation_, excitation_n_, force_n_, velocity_mps_, params_.settle_periods);
}

FrequencyResponseResult evaluate_measurement(const FrequencyResponseMeasurement& measurement) {
  FrequencyResponseResult result;
  result.points = measurement.response();
  const FrequencyResponseMeasurementParams& p = measurement.params();
  const FrequencyPoint* worst = nullptr;
  for (const FrequencyPoint& point : result.points) {
    if (point.coherence >= p.min_coherence) continue;
    ++result.low_coherence_lines;
    if (worst == nullptr || point.coherence < worst->coherence) worst = &point;
  }
  const double share = static_cast<double>(result.low_coherence_lines) / static_cast<double>(result.points.size());
  if (worst != nullptr && share > p.max_low_coherence_share) {
    throw std::invalid_argument("poor coherence: " + std::to_string(result.low_coherence_lines) + " of " +
                                std::to_string(result.points.size()) + " lines below min_coherence " +
                                format_value(p.min_coherence) + " (the worst " + format_value(worst->coherence) +
                                " at " + format_value(worst->frequency_hz) +
                                " Hz), more than max_low_coherence_share " + format_value(p.max_low_coherence_share));
  }
  const double band_hz = p.dense_max_frequency_hz != 0.0 ? p.dense_max_frequency_hz : p.max_frequency_hz;
  result.fit = fit_two_mass(result.points, p.min_coherence, band_hz);
  if (measurement.load_lost()) {
    throw std::invalid_argument("the load's sensor stopped reading during the excitation: its side not measured");
  }
  if (measurement.has_load_sensor()) {
    result.load_points = estimate_load_ratio(measurement.excitation(), measurement.velocity_mps(),
                                             measurement.load_velocity_mps(), p.settle_periods);
    result.load_fit = fit_load_side(result.load_points, result.points, p.min_coherence, band_hz);
    const std::string disagreement = load_sensor_disagreement(*result.load_fit, kLoadSensorGainTolerance);
    if (!disagreement.empty()) throw std::invalid_argument(disagreement);
  }
  return result;
}

}  // namespace pmlsm
