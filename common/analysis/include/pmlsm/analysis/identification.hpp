// Commissioning identification of the load: the two-mass model's load mass and spring and the
// bearing friction, from what a drive measures while the velocity PI alone moves the motor
// (encoder velocity and position, the force applied), as a rig is commissioned before its
// compensators are switched on.
//
// Prediction error: the estimator's own Kalman filter, built with a candidate
//   theta = (m_L, k, F_c, F_v)   (load mass, spring, Coulomb and viscous friction)
// and the configured motor mass, ripple model and noise tuning, runs over the recorded samples;
//   J(theta) = sum_k (y_k - C x_k^-)^2,   k >= skip_samples,
// the squared one-step innovations of the motor velocity. The filter that predicts the motor
// best has the load's mode where the plant has it (the load acts on the motor through the
// spring force, which the filter predicts from k, m_L and the motor motion) and the friction the
// motor feels. The motor mass is the motor's (nameplate), not identified.
//
// Search: every coordinate in log space inside a box [configured / range_ratio, configured *
// range_ratio] (each clamped to the parameter's plausible range); Nelder-Mead (reflection 1,
// expansion 2, contraction 1/2, shrink 1/2) on the friction alone with the configured load (a
// tenth of the budget), a 5 x 5 grid over (m_L, k) with that friction, then Nelder-Mead on all
// from the three best grid points, sharing the rest. Deterministic: no random numbers.
//
// What the data cannot pin (a mode the excitation never reaches, a friction never crossed) shows
// as a value at the box's edge: at_bound names it, and `pmlsm identify` refuses to write such a
// model.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

/// What a drive measures at tick k (MotorFeedback and the force it applied).
struct IdentificationSample {
  double motor_velocity_measured_mps = 0;  ///< y_k = (x_k - x_{k-1}) / T
  double encoder_position_m = 0;           ///< x_k
  double applied_force_n = 0;              ///< the force applied over [t_{k-1}, t_k]
};

struct IdentificationParams {
  double range_ratio = 4.0;              ///< the search box around the configured model, > 1
  std::uint32_t max_evaluations = 1500;  ///< filter runs in all, >= 100
  std::uint32_t skip_samples = 50;       ///< the filter's start, not judged
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

struct IdentifiedLoad {
  double load_mass_kg = 0;
  double spring_n_per_m = 0;
  double coulomb_n = 0;
  double viscous_n_s_per_m = 0;
  double innovation_rms_mps = 0;             ///< of the identified model
  double configured_innovation_rms_mps = 0;  ///< of the configured one, on the same samples
  std::uint32_t evaluations = 0;
  /// The parameters that ended within 1 % (in log) of the search box's edge, comma-separated: "" when none.
  std::string at_bound;
  /// sqrt(k / m_L) / (2 pi): the load's mode against a motor held still.
  double load_mode_hz() const;
};

/// @throws std::invalid_argument: the parameters, fewer than skip_samples + 500 samples, or a
/// non-finite sample ("samples[17].applied_force_n: must be finite, got nan").
IdentifiedLoad identify_load(const SystemParams& configured, const std::vector<IdentificationSample>& samples,
                             const IdentificationParams& params = {});

/// The configuration keys an identified load sets, with their values: the Kalman filter's model
/// and friction input, state feedback's model. One list: with_identified_load and `pmlsm identify`
/// (which writes them into a system file) both use it.
std::vector<std::pair<std::string, double>> identified_parameters(const IdentifiedLoad& load);

/// configured with identified_parameters(load) set (the plant untouched).
/// @throws std::invalid_argument when a value is outside its plausible range.
SystemParams with_identified_load(const SystemParams& configured, const IdentifiedLoad& load);

/// Commissioning in process, as `pmlsm identify --simulate` and a rig do it: PI alone runs
/// `identification` on the plant of `on_plant` (run_scenario), and identify_load fits the load to
/// what the drive measured, from the models configured there. The sweep's `models: identified` and
/// the trainer's commissioned plants both use it.
/// @throws std::invalid_argument as identify_load.
IdentifiedLoad commission_load(const SystemParams& on_plant, const Scenario& identification,
                               const IdentificationParams& params = {});

/// The samples of an in-process trace: what the drive measured and applied, never the truth.
std::vector<IdentificationSample> identification_samples(const std::vector<TickRecord>& trace);

}  // namespace pmlsm
