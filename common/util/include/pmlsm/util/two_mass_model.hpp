// The two-mass model a controller-side component assumes of the mechanics (motor mass, load
// mass, the spring between them): the Kalman filter's (eqs. 30-33) and state feedback's. Each
// holds its own copy, so a study of a plant the model does not match (a heavier load, a stiffer
// coupling) changes the plant alone.
#pragma once

#include <string>

#include "pmlsm/util/validate.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

/// The two-mass entries under `at` (the plant's mechanics, the Kalman filter's and state
/// feedback's models), with one set of ranges (pmlsm/util/parameter_table.hpp).
template <typename Real, typename Visitor>
void declare_two_mass(const std::string& at, Real& motor_mass_kg, Real& load_mass_kg, Real& spring_n_per_m,
                      Visitor& v) {
  v.real(at + ".motor_mass_kg", motor_mass_kg, {0.01, 1e4, "from a 10 g slider to a 10 t gantry"});
  v.real(at + ".load_mass_kg", load_mass_kg, {0.01, 1e4, "from a 10 g load to a 10 t one"});
  v.real(at + ".spring_n_per_m", spring_n_per_m,
         {1.0, 1e9,
          "from a rubber band to a short steel coupling (for the plant, its integrator step bounds it further)"});
}

struct TwoMassModel {
  double motor_mass_kg = 0;   ///< m_M, > 0
  double load_mass_kg = 0;    ///< m_L, > 0
  double spring_n_per_m = 0;  ///< k, > 0
  /// @throws std::invalid_argument naming the first value out of its range (key "model.<field>").
  void validate() const {
    RangeCheck check;
    declare("model", *this, check);
  }
  /// Its entries under `at` (declare_two_mass). Self: TwoMassModel, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& m, Visitor& v) {
    declare_two_mass(at, m.motor_mass_kg, m.load_mass_kg, m.spring_n_per_m, v);
  }
};

}  // namespace pmlsm
