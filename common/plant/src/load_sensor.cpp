// The load's sensor: see load_sensor.hpp for the equations.
#include "pmlsm/plant/load_sensor.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace pmlsm {

namespace {
constexpr double kTwoPi = 6.283185307179586476925;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

const char* to_string(LoadSensorKind kind) {
  switch (kind) {
    case LoadSensorKind::kNone: return "none";
    case LoadSensorKind::kEncoder: return "encoder";
    case LoadSensorKind::kAccelerometer: return "accelerometer";
  }
  return "none";
}

LoadSensorKind load_sensor_kind_from_string(const std::string& name) {
  if (name == "none") return LoadSensorKind::kNone;
  if (name == "encoder") return LoadSensorKind::kEncoder;
  if (name == "accelerometer") return LoadSensorKind::kAccelerometer;
  throw std::invalid_argument("must be one of none, encoder, accelerometer, got '" + name + "'");
}

void LoadSensorParams::validate() const { check_declared_ranges(*this); }

LoadSensor::LoadSensor(const LoadSensorParams& params, double period_s)
    : params_(params), period_s_(period_s), rng_(params.noise_seed) {
  params_.validate();
  if (!std::isfinite(period_s) || period_s <= 0.0 || period_s > 1.0) {
    throw std::invalid_argument("period_s: must be in (0, 1], got " + std::to_string(period_s));
  }
  low_pass_gain_ = low_pass_gain(params_.bandwidth_hz, period_s_);
  noise_std_mps2_ = params_.noise_density_mps2_per_sqrt_hz * std::sqrt(0.5 / period_s_);
  drift_std_mps2_ = params_.bias_drift_mps2_per_sqrt_s * std::sqrt(period_s_);
  silent_from_ = static_cast<std::uint64_t>(std::llround(params_.silent_after_s / period_s_));
  inv_resolution_ = 1.0 / params_.resolution_m;
  reset(0.0);
}

double LoadSensor::low_pass_gain(double bandwidth_hz, double period_s) {
  return 1.0 - std::exp(-kTwoPi * bandwidth_hz * period_s);
}

void LoadSensor::reset(double load_position_m) {
  line_.fill(Truth{load_position_m, 0.0});
  next_ = 0;
  steps_ = 0;
  filtered_mps2_ = params_.bias_mps2;
  bias_mps2_ = params_.bias_mps2;
  last_ = LoadSensorReading{};
}

LoadSensorReading LoadSensor::step(double load_position_m, double load_accel_mps2) {
  if (params_.kind == LoadSensorKind::kNone) return LoadSensorReading{};
  const std::uint64_t step = steps_++;
  if (silent_from_ > 0 && step >= silent_from_) {
    ++counters_.silent;
    return LoadSensorReading{};
  }
  if (!std::isfinite(load_position_m) || !std::isfinite(load_accel_mps2)) {
    ++counters_.rejected_inputs;
    return last_;
  }
  ++counters_.readings;
  // The latency line: the truth of tick k goes in, that of tick k - L comes out.
  const std::size_t slots = params_.latency_ticks + 1U;
  line_[next_ % slots] = {load_position_m, load_accel_mps2};
  ++next_;
  const Truth& seen = line_[next_ % slots];
  if (params_.kind == LoadSensorKind::kEncoder) {
    double x = seen.position_m;
    if (params_.position_noise_std_m > 0.0) x += params_.position_noise_std_m * normal_(rng_);
    last_ = {std::floor(x * inv_resolution_) * params_.resolution_m, kNaN, false};
    return last_;
  }
  double u = seen.accel_mps2 + bias_mps2_;
  if (noise_std_mps2_ > 0.0) u += noise_std_mps2_ * normal_(rng_);
  if (drift_std_mps2_ > 0.0) bias_mps2_ += drift_std_mps2_ * normal_(rng_);
  filtered_mps2_ += low_pass_gain_ * (u - filtered_mps2_);
  const double railed = std::clamp(filtered_mps2_, -params_.range_mps2, params_.range_mps2);
  const bool saturated = railed != filtered_mps2_;
  if (saturated) ++counters_.saturated;
  last_ = {kNaN, railed, saturated};
  return last_;
}

}  // namespace pmlsm
