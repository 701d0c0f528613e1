// The two-mass model a controller-side component assumes of the mechanics (motor mass, load
// mass, the spring between them): the Kalman filter's (eqs. 30-33) and state feedback's. Each
// holds its own copy, so a study of a plant the model does not match (a heavier load, a stiffer
// coupling) changes the plant alone.
#pragma once

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

struct TwoMassModel {
  double motor_mass_kg = 0;   ///< m_M, > 0
  double load_mass_kg = 0;    ///< m_L, > 0
  double spring_n_per_m = 0;  ///< k, > 0
  /// @throws std::invalid_argument naming the first value that is not positive (key "model.<field>").
  void validate() const {
    require_positive("model.motor_mass_kg", motor_mass_kg);
    require_positive("model.load_mass_kg", load_mass_kg);
    require_positive("model.spring_n_per_m", spring_n_per_m);
  }
};

}  // namespace pmlsm
