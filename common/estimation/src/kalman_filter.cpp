#include "pmlsm/estimation/kalman_filter.hpp"

#include <algorithm>
#include <cmath>

#include "pmlsm/util/discretize.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {
constexpr double kNoReading = std::numeric_limits<double>::quiet_NaN();
}  // namespace

void KalmanParams::validate() const {
  // The model, the noises, the lag, the friction and ripple inputs and the standstill hold.
  check_declared_ranges(*this);
  require_in_range("period_s", period_s, 1e-6, 1.0);
  if (load_measurement.kind != LoadSensorKind::kNone) {
    require_in_range("load_measurement.variance", load_measurement.variance, 1e-15, 1e12);
  }
}

Eigen::Matrix3d KalmanFilter::continuous_a(const KalmanParams& p) {
  Eigen::Matrix3d a;
  a << 0.0, 0.0, -1.0 / p.model.motor_mass_kg,  //
      0.0, 0.0, 1.0 / p.model.load_mass_kg,     //
      p.model.spring_n_per_m, -p.model.spring_n_per_m, 0.0;
  return a;
}

Eigen::Vector3d KalmanFilter::continuous_b(const KalmanParams& p) {
  return Eigen::Vector3d(1.0 / p.model.motor_mass_kg, 0.0, 0.0);
}

KalmanFilter::KalmanFilter(const KalmanParams& params)
    : params_(params), load_monitor_(params.load_measurement.monitor) {
  params_.validate();
  const DiscreteModel d = discretize_zoh(continuous_a(params_), continuous_b(params_), params_.period_s);
  phi_ = d.phi;
  gamma_ = d.gamma;
  q_ = params_.process_noise_diag.asDiagonal();
  load_impedance_n_s_per_m_ = std::sqrt(params_.model.spring_n_per_m * params_.model.load_mass_kg);
  if (params_.thrust_lag_s > 0) {
    lag_decay_ = std::exp(-params_.period_s / params_.thrust_lag_s);
    lag_over_period_ = params_.thrust_lag_s / params_.period_s;
    lag_rise_ = 1.0 - lag_decay_;
  }
  reset();
}

void KalmanFilter::reset(const Eigen::Vector3d& initial_state) {
  x_ = initial_state;
  p_ = params_.initial_covariance_diag.asDiagonal();
  last_input_n_ = 0;
  thrust_n_ = 0;
  last_position_m_ = 0;
  have_last_position_ = false;
  have_load_position_ = false;
  stretch_ = StretchOffset{};
}

double KalmanFilter::modelled_disturbance_n(double y_mps, double position_m) {
  double disturbance_n = 0;
  if (params_.friction_input.enabled) {
    // v_k = y_k, the mean velocity over the period; without a finite y_k the
    // prior estimate of v_M (the posterior of k-1) stands in for it.
    const double v_mps = std::isfinite(y_mps) ? y_mps : x_(0);
    disturbance_n += params_.friction_input.force_n(v_mps);
  }
  if (params_.ripple_input.enabled) {
    if (std::isfinite(position_m)) {
      const double previous_m = have_last_position_ ? last_position_m_ : position_m;
      disturbance_n += params_.ripple_input.force_n(0.5 * (previous_m + position_m));
      last_position_m_ = position_m;
      have_last_position_ = true;
    } else {
      ++counters_.rejected_inputs;
      if (have_last_position_) disturbance_n += params_.ripple_input.force_n(last_position_m_);
    }
  }
  return disturbance_n;
}

KalmanEstimate KalmanFilter::step(const KalmanInput& in) {
  ++counters_.steps;
  if (std::isfinite(in.thrust_previous_n)) {
    last_input_n_ = in.thrust_previous_n;
  } else {
    ++counters_.rejected_inputs;
  }
  // u_{k-1} = F_{k-1}, or with the thrust lag the period's mean thrust Fbar_k (+ F_friction(v_k) +
  // F_ripple(xbar_k) when modelled; see the header).
  double force_n = last_input_n_;
  if (params_.thrust_lag_s > 0) {
    const double lag_n = thrust_n_ - last_input_n_;  // Fhat_{k-1} - F_{k-1}
    // Evaluated in this order, (lag_n tau_i / T)(1 - e^{-T / tau_i}): the shipped weights were
    // searched on these bits, and the loop's stick-slip carries a last-digit change to the cost.
    force_n = last_input_n_ + lag_n * lag_over_period_ * lag_rise_;
    thrust_n_ = last_input_n_ + lag_n * lag_decay_;
  }
  const bool disturbance_modelled = params_.friction_input.enabled || params_.ripple_input.enabled;
  const double input_n = disturbance_modelled
                             ? force_n + modelled_disturbance_n(in.motor_velocity_measured_mps, in.motor_position_m)
                             : force_n;
  // The standstill hold's test, on the estimate before this step (see the header).
  const double y = in.motor_velocity_measured_mps;
  bool hold = false;
  if (params_.standstill_hold.enabled && params_.friction_input.enabled && std::isfinite(y) &&
      std::abs(y) <= params_.standstill_hold.max_velocity_mps) {
    const double swing_n = std::hypot(x_(2), load_impedance_n_s_per_m_ * (x_(1) - x_(0)));
    hold = swing_n >= params_.standstill_hold.min_ring_share * params_.friction_input.model.coulomb_n;
  }
  // Time update (28), (29).
  x_ = phi_ * x_ + gamma_ * input_n;
  p_ = phi_ * p_ * phi_.transpose() + q_;

  KalmanEstimate out;
  out.input_force_n = input_n;
  if (hold) {
    // v_M = y_k; v_L and F_s keep their prediction, and v_M no longer correlates with them.
    out.innovation_mps = y - x_(0);
    x_(0) = y;
    p_.row(0).setZero();
    p_.col(0).setZero();
    p_(0, 0) = params_.measurement_noise;
    out.measurement_used = true;
    out.standstill_held = true;
    ++counters_.standstill_holds;
  } else if (std::isfinite(y)) {
    // Measurement update (30)-(32) with C = [1 0 0]: C P C^T = P(0,0).
    const double s = p_(0, 0) + params_.measurement_noise;
    const Eigen::Vector3d gain = p_.col(0) / s;
    out.innovation_mps = y - x_(0);
    x_ += gain * out.innovation_mps;
    // Joseph form of (32): same value in exact arithmetic, stays symmetric and
    // positive semi-definite in floating point.
    Eigen::Matrix3d i_kc = Eigen::Matrix3d::Identity();
    i_kc.col(0) -= gain;
    p_ = i_kc * p_ * i_kc.transpose() + gain * params_.measurement_noise * gain.transpose();
    out.measurement_used = true;
  } else {
    ++counters_.rejected_measurements;
  }
  load_update(in, out);
  out.motor_velocity_mps = x_(0);
  out.load_velocity_mps = x_(1);
  out.spring_force_n = x_(2);
  out.load_accel_mps2 = x_(2) / params_.model.load_mass_kg;
  out.covariance_diag = p_.diagonal();
  return out;
}

double KalmanFilter::scalar_update(const Eigen::RowVector3d& h, double y, double r) {
  const Eigen::Vector3d ph = p_ * h.transpose();
  const double s = h.dot(ph) + r;
  const Eigen::Vector3d gain = ph / s;
  const double innovation = y - h.dot(x_);
  x_ += gain * innovation;
  const Eigen::Matrix3d i_kh = Eigen::Matrix3d::Identity() - gain * h;
  p_ = i_kh * p_ * i_kh.transpose() + gain * r * gain.transpose();
  return innovation;
}

void KalmanFilter::load_update(const KalmanInput& in, KalmanEstimate& out) {
  const KalmanLoadMeasurement& m = params_.load_measurement;
  if (m.kind == LoadSensorKind::kNone) return;
  const LoadSensorVerdict verdict = load_monitor_.judge(counters_.steps - 1, in.load_position_m, in.load_accel_mps2,
                                                        in.load_sensor_saturated, in.motor_position_m);
  out.load_sensor_problem = verdict.problem;
  out.load_sensor_failed = load_monitor_.failed();
  if (m.kind == LoadSensorKind::kEncoder) {
    // The load's mean velocity over the period, from this reading and the last tick's (none at the
    // first, or after a silent tick); a reading refused as a jump is still the next one's start.
    const bool finite = std::isfinite(in.load_position_m);
    if (verdict.use && have_load_position_) {
      const double y = (in.load_position_m - last_load_position_m_) / params_.period_s;
      out.load_innovation = scalar_update(Eigen::RowVector3d(0.0, 1.0, 0.0), y, m.variance);
      out.load_measurement_used = true;
    }
    stretch_update(verdict.use && std::isfinite(in.motor_position_m) ? in.load_position_m : kNoReading,
                   in.motor_position_m, out);
    have_load_position_ = finite;
    if (finite) last_load_position_m_ = in.load_position_m;
  } else {
    AccelerometerBias& b = accel_bias_;
    if (!b.started && verdict.use) {
      b.started = true;
      b.first_load_velocity_mps = x_(1);
    }
    if (b.started) {
      const double t_s = static_cast<double>(b.periods) * params_.period_s;
      b.bias_mps2 = (b.sum_mps - (x_(1) - b.first_load_velocity_mps)) / (params_.accelerometer_bias_prior_s + t_s);
      // A reading not believed counts as the filter's own a_L plus the bias so far, so the sum
      // still integrates to the change of v_L over the gap.
      const double reading_mps2 = verdict.use ? in.load_accel_mps2 : x_(2) / params_.model.load_mass_kg + b.bias_mps2;
      b.sum_mps += reading_mps2 * params_.period_s;
      ++b.periods;
    }
    out.accelerometer_bias_mps2 = b.bias_mps2;
    if (verdict.use) {
      const Eigen::RowVector3d h(0.0, 0.0, 1.0 / params_.model.load_mass_kg);
      out.load_innovation = scalar_update(h, in.load_accel_mps2 - b.bias_mps2, m.variance);
      out.load_measurement_used = true;
    }
  }
  if (out.load_measurement_used) ++counters_.load_updates;
}

void KalmanFilter::stretch_update(double load_position_m, double motor_position_m, KalmanEstimate& out) {
  StretchOffset& b = stretch_;
  const double k = params_.model.spring_n_per_m;
  const double m_l = params_.model.load_mass_kg;
  if (!b.started) {
    if (!std::isfinite(load_position_m)) return;
    b.started = true;
    b.first_n = b.last_n = b.sum_n = k * (motor_position_m - load_position_m);
    b.first_load_velocity_mps = x_(1);
    b.first_variance = p_(1, 1);
    return;
  }
  // b_k from the readings' trapezoid so far and the filter's v_L now (see the header).
  const auto offset_n = [&] {
    if (b.periods == 0) return 0.0;
    const double integral_n_s = params_.period_s * (b.sum_n - 0.5 * (b.first_n + b.last_n));
    return (integral_n_s - m_l * (x_(1) - b.first_load_velocity_mps)) /
           (static_cast<double>(b.periods) * params_.period_s);
  };
  // A tick without a reading carries the prediction F_s^- + b into the integral.
  const bool reading = std::isfinite(load_position_m);
  const double y_n = reading ? k * (motor_position_m - load_position_m) : x_(2) + offset_n();
  ++b.periods;
  b.sum_n += y_n;
  b.last_n = y_n;
  const double span_s = static_cast<double>(b.periods) * params_.period_s;
  const double offset_now_n = offset_n();
  out.stretch_offset_n = offset_now_n;
  if (!reading) return;
  const double offset_variance = m_l * m_l * (p_(1, 1) + b.first_variance) / (span_s * span_s);
  const double r = k * k * params_.load_measurement.stretch_variance_m2 + offset_variance;
  out.stretch_innovation_n = scalar_update(Eigen::RowVector3d(0.0, 0.0, 1.0), y_n - offset_now_n, r);
}

LoadSensorUse load_sensor_use(const KalmanEstimate& e) {
  if (e.load_sensor_failed) return LoadSensorUse::kFailed;
  if (e.load_measurement_used) return LoadSensorUse::kUsed;
  return e.load_sensor_problem != LoadSensorFault::kNone ? LoadSensorUse::kRefused : LoadSensorUse::kNotUsed;
}

KalmanLoadMeasurement KalmanLoadMeasurement::of(const LoadSensorParams& sensor, double period_s,
                                                double motor_resolution_m) {
  KalmanLoadMeasurement m;
  m.kind = sensor.kind;
  if (sensor.kind == LoadSensorKind::kEncoder) {
    const double per_reading =
        sensor.resolution_m * sensor.resolution_m / 12.0 + sensor.position_noise_std_m * sensor.position_noise_std_m;
    m.variance = 2.0 * per_reading / (period_s * period_s);
    m.stretch_variance_m2 = per_reading + motor_resolution_m * motor_resolution_m / 12.0;
  } else if (sensor.kind == LoadSensorKind::kAccelerometer) {
    const double gain = LoadSensor::low_pass_gain(sensor.bandwidth_hz, period_s);
    const double white = sensor.noise_density_mps2_per_sqrt_hz * sensor.noise_density_mps2_per_sqrt_hz * 0.5 / period_s;
    // A noiseless part is still read to the unit of its object (1 um/s^2): never a zero variance.
    m.variance = std::max(white * gain / (2.0 - gain), 1e-12);
  }
  m.monitor = LoadSensorMonitorParams::of(sensor, period_s);
  return m;
}

}  // namespace pmlsm
