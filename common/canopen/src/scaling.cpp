// Unit scaling between SI values and CiA 402 object units; see scaling.hpp.
#include "pmlsm/canopen/scaling.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm::canopen {
namespace {

template <typename T>
Scaled<T> round_saturate(double value) noexcept {
  constexpr double kLo = static_cast<double>(std::numeric_limits<T>::min());
  constexpr double kHi = static_cast<double>(std::numeric_limits<T>::max());
  if (std::isnan(value)) return {T{0}, true};
  const double rounded = std::round(value);
  if (rounded < kLo) return {std::numeric_limits<T>::min(), true};
  if (rounded > kHi) return {std::numeric_limits<T>::max(), true};
  return {static_cast<T>(rounded), false};
}

}  // namespace

UnitScaling::UnitScaling(ScalingConfig config) : config_(config) {
  require_positive("rated_force_n", config.rated_force_n);
  require_positive("increments_per_metre", config.increments_per_metre);
  const double mn = std::round(config.rated_force_n * 1000.0);
  if (!(mn >= 1.0 && mn <= 4294967295.0)) {
    throw std::invalid_argument("rated_force_n: must round to 1..4294967295 mN (0x6076), got " +
                                format_value(config.rated_force_n));
  }
  rated_torque_mn_ = static_cast<std::uint32_t>(mn);
}

UnitScaling UnitScaling::from_rated_torque_object(std::uint32_t rated_torque_mn, double increments_per_metre) {
  if (rated_torque_mn == 0) throw std::invalid_argument("rated torque (0x6076): must be >= 1 mN, got 0");
  return UnitScaling(ScalingConfig{static_cast<double>(rated_torque_mn) / 1000.0, increments_per_metre});
}

Scaled<std::int16_t> UnitScaling::force_to_per_mille(double force_n) const noexcept {
  // Per mille of 0x6076 as the drive holds it (mN): force [N] * 1000 / (mN / 1000).
  return round_saturate<std::int16_t>(force_n * 1.0e6 / static_cast<double>(rated_torque_mn_));
}

double UnitScaling::per_mille_to_force(std::int16_t per_mille) const noexcept {
  return static_cast<double>(per_mille) * static_cast<double>(rated_torque_mn_) / 1.0e6;
}

Scaled<std::int32_t> UnitScaling::metres_to_increments(double position_m) const noexcept {
  return round_saturate<std::int32_t>(position_m * config_.increments_per_metre);
}

double UnitScaling::increments_to_metres(std::int32_t increments) const noexcept {
  return static_cast<double>(increments) / config_.increments_per_metre;
}

Scaled<std::int32_t> UnitScaling::velocity_to_increments(double velocity_m_per_s) const noexcept {
  return round_saturate<std::int32_t>(velocity_m_per_s * config_.increments_per_metre);
}

double UnitScaling::increments_to_velocity(std::int32_t increments_per_s) const noexcept {
  return static_cast<double>(increments_per_s) / config_.increments_per_metre;
}

}  // namespace pmlsm::canopen
