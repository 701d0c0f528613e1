// Unit scaling between the SI values of the control loop and CiA 402's object units:
//   force  [N]  <-> target torque 0x6071 / torque actual 0x6077 [per mille of the rated torque
//                   0x6076; for a linear motor the rated force, 0x6076 in mN]  (INTEGER16)
//   position [m]   <-> position actual 0x6064 [increments]                     (INTEGER32)
//   velocity [m/s] <-> velocity actual 0x606C [increments/s]                   (INTEGER32)
//
// The rated force is used as the drive holds it in 0x6076: round(rated_force_n * 1000) mN, so
// that master and drive scale alike. To the integer objects: the exact product is rounded to the nearest
// integer, halves away from zero (std::round), then saturated to the type's range; saturated says it was (a
// NaN gives 0, saturated). From the objects: the exact quotient (no rounding). noexcept, no allocation.
#pragma once

#include <cstdint>

#include "pmlsm/drive/drive.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm::canopen {

struct ScalingConfig {
  /// The rated force [N] the per-mille values refer to; > 0, and round(rated_force_n * 1000)
  /// (0x6076 in mN) in 1..4294967295.
  double rated_force_n = 100.0;
  /// Encoder increments per metre (e.g. 1e6 for a 1 um encoder); finite, > 0.
  double increments_per_metre = 1e6;
};

/// The scaling's two settings as a rig file writes them (drive.rated_force_n,
/// drive.increments_per_metre), declared once for both buses' rig files.
template <typename Scaling, typename Visitor>
void visit_scaling_parameters(Scaling& s, Visitor& v) {
  v.real("drive.rated_force_n", s.rated_force_n,
         {1e-3, 4294967.295, "0x6076 holds it as 32 bits of millinewtons: 1 mN to 4.29 MN"});
  v.real("drive.increments_per_metre", s.increments_per_metre,
         {1.0, 1e12, "from a 1 m coarse scale to a 1 pm interferometer"});
}

template <typename T>
struct Scaled {
  T value{};
  bool saturated = false;  // the value was clipped to the type's range (or was NaN)
};

class UnitScaling {
 public:
  /// @throws std::invalid_argument naming the field and its value, e.g.
  ///         "rated_force_n: must be > 0, got -1".
  explicit UnitScaling(ScalingConfig config);

  /// The scaling for a drive's 0x6076 (mN). @throws std::invalid_argument for 0 or a bad
  /// increments_per_metre.
  static UnitScaling from_rated_torque_object(std::uint32_t rated_torque_mn, double increments_per_metre);

  /// 1000 * force / rated force, rounded, saturated to [-32768, 32767].
  Scaled<std::int16_t> force_to_per_mille(double force_n) const noexcept;
  double per_mille_to_force(std::int16_t per_mille) const noexcept;

  Scaled<std::int32_t> metres_to_increments(double position_m) const noexcept;
  double increments_to_metres(std::int32_t increments) const noexcept;

  Scaled<std::int32_t> velocity_to_increments(double velocity_m_per_s) const noexcept;
  double increments_to_velocity(std::int32_t increments_per_s) const noexcept;

  /// A drive's actual values (0x6064 position, 0x606C velocity, 0x6077 torque) as the drive loop
  /// reads them: metres, m/s, and the thrust in newtons.
  drive::Measurement measurement(std::int32_t position_increments, std::int32_t velocity_increments_per_s,
                                 std::int16_t torque_per_mille) const noexcept {
    drive::Measurement m;
    m.position_m = increments_to_metres(position_increments);
    m.velocity_mps = increments_to_velocity(velocity_increments_per_s);
    m.thrust_force_n = per_mille_to_force(torque_per_mille);
    return m;
  }

  /// round(rated_force_n * 1000): the value of 0x6076 in mN.
  std::uint32_t rated_torque_object() const noexcept { return rated_torque_mn_; }
  const ScalingConfig& config() const noexcept { return config_; }

 private:
  ScalingConfig config_;
  std::uint32_t rated_torque_mn_ = 0;
};

}  // namespace pmlsm::canopen
