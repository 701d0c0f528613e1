// Every parameter of the simulated system in one place: what configs/system.yaml
// holds. Components take the parts they need; the controller-side models (the
// drive's motor model, the Kalman filter's masses and stiffness) are taken from
// the nominal plant, as a drive tuned on the datasheet would be.
#pragma once

#include <string>
#include <vector>

#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/compensation/standstill_gate.hpp"
#include "pmlsm/compensation/vibration_guard.hpp"
#include "pmlsm/control/biquad.hpp"
#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/control/input_shaper.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/compensation/state_feedback.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/plant/plant.hpp"
#include "pmlsm/sim/filter_design.hpp"
#include "pmlsm/sim/frequency_response_measurement.hpp"
#include "pmlsm/sim/loop_tuning.hpp"
#include "pmlsm/util/parameter_table.hpp"
#include "pmlsm/control/reference_model.hpp"
#include "pmlsm/control/velocity_pi.hpp"

namespace pmlsm {

struct TimingParams {
  double control_period_s = 0;       ///< velocity loop, estimator, reference (1 ms)
  double current_loop_period_s = 0;  ///< drive current loop (31.25 us); divides the control period
  void validate() const;
  /// control_period_s / current_loop_period_s, checked to be a whole number by validate().
  int current_steps_per_tick() const;
};

/// The compensators added to the PI output: the Jordan RNN (section 3.2), the linear
/// load-acceleration feedback it is compared with, state feedback with inverse-model feedforward,
/// and the vibration guard and the standstill gate in the compensation path. Each is its
/// component's own Params; the fields the system derives (periods, the velocity loop's gain and
/// limit, the gain schedule) are left unset here and filled by SystemParams' accessors.
struct CompensatorTuning {
  RnnCompensatorParams rnn;
  AccelFeedbackParams acceleration_feedback;
  StateFeedbackParams state_feedback;
  /// The load mass K_a and the RNN's weights were tuned for: both scale with the Kalman model's
  /// load mass over this one (compensator_gain_scale).
  double design_load_mass_kg = 0;
  double max_gain_scale = 0;  ///< the schedule's upper limit (the stiff PI's, not the load's)
  bool guard_enabled = false;
  VibrationGuardParams guard;
  bool standstill_enabled = false;
  StandstillGateParams standstill;
};

/// Input shaping of the command (a scenario's `input_shaper`): the mode it is timed to is the
/// velocity loop's own (loop_vibration_mode), so only EI's tolerance is set here.
struct InputShapingTuning {
  double vibration_tolerance = 0;  ///< EI's residual vibration on the mode
};

/// Commissioning (`pmlsm commission`): the frequency-response measurement; its control period and
/// the ripple's pole pitch come from the system (SystemParams::frequency_response_params).
struct CommissioningTuning {
  FrequencyResponseMeasurementParams frequency_response;
  TuningTargets tuning;              ///< the velocity PI's margins `pmlsm commission --tune` sets the gains to
  FilterDesignParams filter_design;  ///< `pmlsm commission --design-filters`: notches on resonances
};

/// A lightly damped mode of a linear loop: s = -zeta w_n +- j w_n sqrt(1 - zeta^2).
struct VibrationMode {
  double frequency_hz = 0;  ///< w_n / (2 pi)
  double damping_ratio = 0;
};

struct SystemParams;

/// Every parameter of SystemParams in one declaration (pmlsm/util/parameter_table.hpp): its key
/// path in configs/system.yaml, its kind and its plausible range with the reason. The config
/// loader reads the file by this table (so every key is known and present),
/// SystemParams::validate() checks the ranges, tests mutate every entry, `pmlsm config
/// reference` writes it out. Params is SystemParams or const SystemParams.
template <typename Params, typename Visitor>
void visit_parameters(Params& p, Visitor& v);

/// A real (not integer, flag or choice) entry of the table by its key path, for tools that
/// move one parameter (the robustness sweep). range: its plausible range.
/// @throws std::invalid_argument when no real entry has that key path.
double& real_parameter(SystemParams& params, const std::string& key_path, Plausible* range = nullptr);

/// The key paths of the filter slot at `at` ("filters.force_command.slot_1"): its kind and its
/// four values, as the system file names them.
std::vector<std::string> filter_slot_keys(const std::string& at);

/// The parameters of configs/system.yaml, nested as the file is. A component's Params appears
/// whole where the file has its section; the values it takes from elsewhere in the system (its
/// period from timing, a motor model from the plant) are filled by the accessors below, which are
/// what components are built from.
struct SystemParams {
  TimingParams timing;
  PlantParams plant;
  CurrentControllerParams current_loop;  ///< period_s: timing; voltage limit and motor model: the plant
  VelocityPiParams velocity_loop;        ///< period_s: timing.control_period_s
  ReferenceModelParams reference_model;  ///< period_s: timing.control_period_s
  KalmanParams kalman;                   ///< period_s: timing.control_period_s
  CompensatorTuning compensator;
  InputShapingTuning input_shaping;
  CommissioningTuning commissioning;
  /// Filter slots: on the velocity loop's force command, and on the compensator's force before it
  /// is added to the PI (period_s: timing.control_period_s).
  FilterChainParams force_command_filters;
  FilterChainParams compensation_filters;

  /// @throws std::invalid_argument with the section path of the first invalid value.
  void validate() const;
  CurrentControllerParams current_controller_params() const;
  VelocityPiParams velocity_pi_params() const;
  ReferenceModelParams reference_model_params() const;
  KalmanParams kalman_params() const;
  RnnCompensatorParams rnn_compensator_params(bool online_learning) const;
  /// min(max_gain_scale, m_L,model / m_L,design): acceleration feedback's K_a and the RNN's output
  /// scale with it, so the force per newton of estimated spring force (F = -K_a F_s / m_L) stays
  /// what was tuned when the model's load is identified lighter or heavier (1 with the nominal
  /// model); never more than max_gain_scale, where the compensation starts to fight the stiff PI.
  double compensator_gain_scale() const;
  AccelFeedbackParams accel_feedback_params() const;
  StateFeedbackParams state_feedback_params() const;
  VibrationGuardParams vibration_guard_params() const;
  StandstillGateParams standstill_gate_params() const;
  /// The load's vibration under the velocity loop, from the Kalman filter's model of the mechanics
  /// (the identified one after commissioning) and the PI's gains: the least damped oscillatory
  /// pole pair of the linear loop (m_M dv_M/dt = F - k (x_M - x_L), m_L dv_L/dt = k (x_M - x_L),
  /// F = -K_p v_M + K_i integral(-v_M)). It lies between the load's mode on a held motor,
  /// sqrt(k / m_L), and the free two-mass resonance, sqrt(k (1/m_M + 1/m_L)).
  VibrationMode loop_vibration_mode() const;
  /// The frequency-response measurement at the control period, with the plant's pole pitch (the
  /// motor's datasheet value: the force ripple's period in space).
  FrequencyResponseMeasurementParams frequency_response_params() const;
  FilterChainParams force_command_filter_params() const;
  FilterChainParams compensation_filter_params() const;
  /// A shaper of `kind` timed to loop_vibration_mode(), at the control period.
  InputShaperParams input_shaper_params(ShaperKind kind) const;
};

namespace detail {

// The plant's and the Kalman filter's ripple (10) and friction (11) models share their keys.
template <typename Ripple, typename Visitor>
void visit_ripple(const std::string& at, Ripple& r, Visitor& v) {
  v.real(at + ".scale_n", r.scale_n, {0.0, 1e4, "K_s up to 10 kN, the thrust of the largest linear motors"});
  v.real(at + ".amplitude_1", r.amplitude_1, {-10.0, 10.0, "normalised harmonic amplitude: K_s carries the newtons"});
  v.real(at + ".amplitude_2", r.amplitude_2, {-10.0, 10.0, "normalised harmonic amplitude: K_s carries the newtons"});
  v.real(at + ".spatial_freq_1_rad_per_m", r.spatial_freq_1_rad_per_m,
         {0.0, 1e5, "wavelengths down to 63 um, finer than any pole pitch or detent"});
  v.real(at + ".spatial_freq_2_rad_per_m", r.spatial_freq_2_rad_per_m,
         {0.0, 1e5, "wavelengths down to 63 um, finer than any pole pitch or detent"});
}

template <typename Friction, typename Visitor>
void visit_friction(const std::string& at, Friction& f, Visitor& v) {
  v.real(at + ".coulomb_n", f.coulomb_n, {0.0, 1e4, "up to 10 kN, the thrust of the largest linear motors"});
  v.real(at + ".viscous_n_s_per_m", f.viscous_n_s_per_m,
         {0.0, 1e5, "up to 10 kN at 0.1 m/s, the largest thrust at a crawl"});
  v.real(at + ".regularisation_velocity_mps", f.regularisation_velocity_mps,
         {1e-7, 1.0, "the smoothed band of sign(v): from 0.1 um/s to 1 m/s"});
}

// A filter slot (pmlsm/control/biquad.hpp): the kind and the four values each kind may use;
// which it uses is checked by the slot's validate(). A chain holds four.
// live_at: the node that takes the slot live (the velocity loop's chains: the controller), or nullptr.
template <typename Slot, typename Visitor>
void visit_filter_slot(const std::string& at, Slot& slot, Visitor& v, const char* live_at = nullptr) {
  v.choice(at + ".kind", slot.kind, &filter_kind_from_string, live_at);
  v.real(at + ".frequency_hz", slot.frequency_hz, {0.0, 1e4, "0 (unused) to 10 kHz", live_at});
  v.real(at + ".damping", slot.damping, {0.0, 10.0, "0 to overdamped tenfold", live_at});
  v.real(at + ".second_frequency_hz", slot.second_frequency_hz, {0.0, 1e4, "0 (unused) to 10 kHz", live_at});
  v.real(at + ".second_damping", slot.second_damping, {0.0, 10.0, "0 to overdamped tenfold", live_at});
}

template <typename Chain, typename Visitor>
void visit_filter_chain(const std::string& at, Chain& chain, Visitor& v, const char* live_at) {
  for (std::size_t i = 0; i < chain.slots.size(); ++i) {
    visit_filter_slot(at + ".slot_" + std::to_string(i + 1), chain.slots[i], v, live_at);
  }
}

// The two-mass mechanics: the plant's, and the models of it in the Kalman filter and in state
// feedback, with one set of ranges.
template <typename Real, typename Visitor>
void visit_two_mass(const std::string& at, Real& motor_mass_kg, Real& load_mass_kg, Real& spring_n_per_m, Visitor& v) {
  v.real(at + ".motor_mass_kg", motor_mass_kg, {0.01, 1e4, "from a 10 g slider to a 10 t gantry"});
  v.real(at + ".load_mass_kg", load_mass_kg, {0.01, 1e4, "from a 10 g load to a 10 t one"});
  v.real(at + ".spring_n_per_m", spring_n_per_m,
         {1.0, 1e9,
          "from a rubber band to a short steel coupling (for the plant, its integrator step bounds it further)"});
}

template <typename Model, typename Visitor>
void visit_two_mass(const std::string& at, Model& m, Visitor& v) {
  visit_two_mass(at, m.motor_mass_kg, m.load_mass_kg, m.spring_n_per_m, v);
}

}  // namespace detail

template <typename Params, typename Visitor>
void visit_parameters(Params& p, Visitor& v) {
  // The nodes that take entries live (Plausible::live_at): each names its own node.
  constexpr const char* kController = "controller";
  constexpr const char* kAccelFeedback = "accel_feedback";
  constexpr const char* kStateFeedback = "state_feedback";
  constexpr const char* kRnnCompensator = "rnn_compensator";
  v.real("timing.control_period_s", p.timing.control_period_s, {1e-5, 1.0, "a velocity loop between 100 kHz and 1 Hz"});
  v.real("timing.current_loop_period_s", p.timing.current_loop_period_s,
         {1e-7, 1e-3, "a current loop between 10 MHz and 1 kHz"});

  v.real("plant.max_step_s", p.plant.max_step_s,
         {1e-9, 1e-3, "the integrator step: at least one per millisecond, at most a billion per second"});
  v.choice("plant.integrator", p.plant.integrator, &integrator_from_string);
  auto& e = p.plant.electrical;
  const Plausible resistance{1e-3, 1e3, "winding resistances of real motors: 1 mOhm to 1 kOhm"};
  const Plausible inductance{1e-6, 10.0, "winding inductances of real motors: 1 uH to 10 H"};
  v.real("plant.electrical.resistance_ohm", e.resistance_ohm, resistance);
  v.real("plant.electrical.armature_d_inductance_h", e.armature_d_inductance_h, inductance);
  v.real("plant.electrical.armature_q_inductance_h", e.armature_q_inductance_h, inductance);
  v.real("plant.electrical.mutual_d_inductance_h", e.mutual_d_inductance_h,
         {0.0, 10.0, "0 (no damper coupling) to 10 H"});
  v.real("plant.electrical.mutual_q_inductance_h", e.mutual_q_inductance_h,
         {0.0, 10.0, "0 (no damper coupling) to 10 H"});
  v.real("plant.electrical.damper_d_inductance_h", e.damper_d_inductance_h, inductance);
  v.real("plant.electrical.damper_q_inductance_h", e.damper_q_inductance_h, inductance);
  v.real("plant.electrical.damper_d_resistance_ohm", e.damper_d_resistance_ohm, resistance);
  v.real("plant.electrical.damper_q_resistance_ohm", e.damper_q_resistance_ohm, resistance);
  v.real("plant.electrical.motor_constant_n_per_a", e.motor_constant_n_per_a,
         {0.1, 1e4, "thrust constants of linear motors: 0.1 N/A to 10 kN/A"});
  v.real("plant.electrical.pole_pitch_m", e.pole_pitch_m, {1e-3, 1.0, "pole pitches of 1 mm to 1 m"});
  v.integer("plant.electrical.pole_pairs", e.pole_pairs,
            {1.0, 1000.0, "a count of pole pairs: a whole number, 1 to 1000"});
  detail::visit_ripple("plant.ripple", p.plant.ripple, v);
  detail::visit_friction("plant.friction", p.plant.friction, v);
  auto& m = p.plant.mechanics;
  detail::visit_two_mass("plant.mechanics", m.motor_mass_kg, m.load_mass_kg, m.spring_n_per_m, v);
  v.real("plant.mechanics.damping_n_s_per_m", m.damping_n_s_per_m,
         {0.0, 1e6, "0 (undamped) to a stiff hydraulic damper"});
  v.real("plant.inverter.dc_bus_v", p.plant.inverter.dc_bus_v,
         {1.0, 2000.0, "from 1 V to the 1500 V DC of the largest industrial inverters"});
  v.real("plant.encoder.resolution_m", p.plant.encoder.resolution_m,
         {1e-10, 1e-2, "from an interferometer's 0.1 nm to a 10 mm coarse scale"});
  v.real("plant.encoder.position_noise_std_m", p.plant.encoder.position_noise_std_m,
         {0.0, 1e-2, "0 to 10 mm of noise"});
  v.integer("plant.encoder.noise_seed", p.plant.encoder.noise_seed,
            {0.0, 18446744073709551615.0, "a seed: any whole number of 64 bits"});
  v.real("plant.encoder.mount_frequency_hz", p.plant.encoder.mount_frequency_hz,
         {0.0, 1e5, "0 (a rigid mount) to 100 kHz"});
  v.real("plant.encoder.mount_damping", p.plant.encoder.mount_damping,
         {0.0, 2.0, "0 to 2 (at least 1e-4 with a compliant mount)"});

  v.real("current_loop.kp_v_per_a", p.current_loop.kp_v_per_a,
         {1e-3, 1e5, "1 mV/A to 100 kV/A: L w_c for any motor and a bandwidth up to the sampling"});
  v.real("current_loop.ki_v_per_a_s", p.current_loop.ki_v_per_a_s, {0.0, 1e9, "0 to R w_c of the stiffest loop"});
  v.real("current_loop.current_limit_a", p.current_loop.current_limit_a, {1e-3, 1e4, "1 mA to 10 kA"});

  v.real("velocity_loop.kp_n_s_per_m", p.velocity_loop.kp_n_s_per_m,
         {0.0, 1e6, "above 1e6 N s/m one encoder count per tick (1 mm/s at 1 um, 1 ms) alone would command 1 kN",
          kController});
  v.real("velocity_loop.ki_n_per_m", p.velocity_loop.ki_n_per_m,
         {0.0, 1e9, "0 to 1 kN per um of accumulated error", kController});
  v.real("velocity_loop.force_limit_n", p.velocity_loop.force_limit_n,
         {1e-3, 1e5, "1 mN to 100 kN, beyond the largest linear motors"});

  v.real("reference_model.natural_frequency_rad_s", p.reference_model.natural_frequency_rad_s,
         {0.1, 1e4, "0.1 rad/s to 10 krad/s (the loop's 1 ms sampling resolves far less)"});
  v.real("reference_model.damping_ratio", p.reference_model.damping_ratio,
         {0.01, 100.0, "from barely damped to overdamped a hundred times"});
  v.real("input_shaping.vibration_tolerance", p.input_shaping.vibration_tolerance,
         {1e-6, 0.25, "EI's residual vibration on its mode: above 0, at most a quarter of unshaped"});
  auto& fr = p.commissioning.frequency_response;
  const std::string at = "commissioning.frequency_response.";
  v.real(at + "amplitude_n", fr.amplitude_n, {1e-3, 1e5, "1 mN to 100 kN, the range of the force limit"});
  v.real(at + "min_frequency_hz", fr.min_frequency_hz, {0.01, 1e4, "0.01 Hz to 10 kHz"});
  v.real(at + "max_frequency_hz", fr.max_frequency_hz, {0.01, 1e4, "0.01 Hz to 10 kHz, below the Nyquist frequency"});
  v.real(at + "resolution_hz", fr.resolution_hz, {0.01, 100.0, "a period of 10 ms to 100 s"});
  v.real(at + "dense_max_frequency_hz", fr.dense_max_frequency_hz, {0.0, 1e4, "0 (every line) to 10 kHz"});
  v.real(at + "lines_per_decade", fr.lines_per_decade, {0.0, 1000.0, "0 (unused) to 1000"});
  v.real(at + "offset_velocity_mps", fr.offset_velocity_mps, {-10.0, 10.0, "either direction, up to 10 m/s"});
  v.integer(at + "settle_periods", fr.settle_periods, {1.0, 100.0, "1 to 100 periods"});
  v.integer(at + "measure_periods", fr.measure_periods, {4.0, 400.0, "4 to 400 periods, a multiple of 4"});
  v.real(at + "ramp_s", fr.ramp_s, {1e-3, 60.0, "a tick to a minute"});
  v.real(at + "max_travel_m", fr.max_travel_m, {1e-6, 100.0, "1 um to 100 m of stroke"});
  v.real(at + "max_velocity_mps", fr.max_velocity_mps, {1e-6, 100.0, "1 um/s to 100 m/s"});
  v.real(at + "min_coherence", fr.min_coherence, {0.0, 1.0, "a coherence: 0 to 1"});
  v.real(at + "max_low_coherence_share", fr.max_low_coherence_share, {0.0, 1.0, "a share of the lines: 0 to 1"});
  detail::visit_filter_chain("filters.force_command", p.force_command_filters, v, kController);
  detail::visit_filter_chain("filters.compensation", p.compensation_filters, v, kController);
  auto& tuning = p.commissioning.tuning;
  v.real("commissioning.tuning.min_phase_margin_deg", tuning.min_phase_margin_deg, {1.0, 89.0, "1 to 89 deg"});
  v.real("commissioning.tuning.min_gain_margin_db", tuning.min_gain_margin_db, {0.1, 40.0, "0.1 to 40 dB"});
  v.real("commissioning.tuning.max_gain_scale", tuning.max_gain_scale,
         {1.01, 100.0, "the gains may move by 1 % to a hundredfold either way"});
  v.real("commissioning.tuning.phase_allowance_deg", tuning.phase_allowance_deg, {0.0, 30.0, "0 to 30 deg"});
  v.real("commissioning.tuning.gain_allowance_db", tuning.gain_allowance_db, {0.0, 10.0, "0 to 10 dB"});
  auto& design = p.commissioning.filter_design;
  v.real("commissioning.filter_design.min_frequency_hz", design.min_frequency_hz,
         {1e-3, 1e5, "1 mHz to 100 kHz (above it: resonances; below it: the two-mass model)"});
  v.real("commissioning.filter_design.min_peak_db", design.min_peak_db, {0.1, 60.0, "0.1 to 60 dB"});
  v.real("commissioning.filter_design.min_gain_increase", design.min_gain_increase,
         {1.000001, 100.0, "a factor above 1, up to 100"});

  // The filter's model of the mechanics: the ranges of the plant's (the model is of such a plant).
  detail::visit_two_mass("kalman.model", p.kalman.model, v);
  const Plausible noise{0.0, 1e12, "a variance: 0 to 1e12 (a 1 MN or 1 Mm/s standard deviation)"};
  v.vector3("kalman.process_noise_diag", p.kalman.process_noise_diag, noise);
  v.real("kalman.measurement_noise", p.kalman.measurement_noise,
         {1e-15, 1e6, "a variance: positive (the filter divides by it), up to 1e6"});
  v.real("kalman.thrust_lag_s", p.kalman.thrust_lag_s, {0.0, 1.0, "0 (thrust = command) to 1 s"});
  v.vector3("kalman.initial_covariance_diag", p.kalman.initial_covariance_diag, noise);
  v.flag("kalman.friction_input.enabled", p.kalman.friction_input.enabled);
  detail::visit_friction("kalman.friction_input", p.kalman.friction_input.model, v);
  v.flag("kalman.ripple_input.enabled", p.kalman.ripple_input.enabled);
  detail::visit_ripple("kalman.ripple_input", p.kalman.ripple_input.model, v);
  v.flag("kalman.standstill_hold.enabled", p.kalman.standstill_hold.enabled);
  v.real("kalman.standstill_hold.max_velocity_mps", p.kalman.standstill_hold.max_velocity_mps,
         {1e-6, 1.0, "1 um/s to 1 m/s: a few encoder counts a period"});
  v.real("kalman.standstill_hold.min_ring_share", p.kalman.standstill_hold.min_ring_share,
         {0.0, 100.0, "0 (every swing at rest) to 100 times the bearing friction"});

  auto& c = p.compensator;
  v.integer_list("compensator.rnn.layer_sizes", c.rnn.layer_sizes,
                 {1.0, 1000.0, "neurons of a layer: a whole number, 1 to 1000"});
  v.real("compensator.rnn.input_scale_s2_per_m", c.rnn.input_scale_s2_per_m,
         {1e-6, 1e3, "maps accelerations of 1 mm/s^2 to 1000 km/s^2 into tanh's range"});
  v.real("compensator.rnn.gain_n", c.rnn.gain_n, {1e-3, 1e5, "1 mN to 100 kN, the range of the force limit"});
  v.real("compensator.rnn.output_scale", c.rnn.output_scale,
         {0.05, 20.0, "a twentieth to twenty times the force", kRnnCompensator});
  v.real("compensator.rnn.learning_rate", c.rnn.learning_rate,
         {0.0, 1.0, "eta of (16): a step larger than the gradient itself diverges", kRnnCompensator});
  v.real("compensator.rnn.momentum", c.rnn.momentum,
         {0.0, 0.999, "alpha of (16): below 1 to contract", kRnnCompensator});
  v.real("compensator.rnn.tolerance_mps", c.rnn.tolerance_mps, {0.0, 1.0, "0 to 1 m/s of dead band", kRnnCompensator});
  v.real("compensator.rnn.kc_limit_mps", c.rnn.kc_limit_mps, {1e-6, 1e3, "1 um/s to 1 km/s", kRnnCompensator});
  v.real("compensator.rnn.du_deadband_per_s", c.rnn.du_deadband_per_s, {1e-6, 1e6, "1e-6 to 1e6 1/s", kRnnCompensator});
  v.flag("compensator.rnn.on_reference_error", c.rnn.on_reference_error);
  v.real("compensator.acceleration_feedback.gain_kg", c.acceleration_feedback.gain_kg,
         {0.0, 1e5, "0 to 100 t of virtual mass", kAccelFeedback});
  v.flag("compensator.acceleration_feedback.on_reference_error", c.acceleration_feedback.on_reference_error);
  v.real("compensator.design_load_mass_kg", c.design_load_mass_kg, {0.01, 1e4, "from a 10 g load to a 10 t one"});
  v.real("compensator.max_gain_scale", c.max_gain_scale, {1.0, 100.0, "1 (never above the tuned gains) to 100"});
  detail::visit_two_mass("compensator.state_feedback.model", c.state_feedback.model, v);
  v.real("compensator.state_feedback.model_frequency_ratio", c.state_feedback.model_frequency_ratio,
         {1.0, 100.0, "the model's load mode 1 to 100 times the open one sqrt(k / m_L)", kStateFeedback});
  v.real("compensator.state_feedback.model_damping_ratio", c.state_feedback.model_damping_ratio,
         {0.0, 100.0, "from undamped to overdamped a hundred times", kStateFeedback});
  v.real("compensator.state_feedback.correction_damping_ratio", c.state_feedback.correction_damping_ratio,
         {0.0, 100.0, "from none to overdamped a hundred times", kStateFeedback});
  v.real("compensator.state_feedback.max_correction_gain", c.state_feedback.max_correction_gain,
         {1e-3, 1e4, "newtons of correction per newton of spring-force difference", kStateFeedback});
  auto& sf = c.state_feedback;
  v.real("compensator.state_feedback.friction_feedforward.coulomb_n", sf.friction_coulomb_n,
         {0.0, 1e4, "0 (none) to 10 kN", kStateFeedback});
  v.real("compensator.state_feedback.friction_feedforward.viscous_n_s_per_m", sf.friction_viscous_n_s_per_m,
         {0.0, 1e5, "0 (none) to 100 kN s/m", kStateFeedback});
  v.real("compensator.state_feedback.friction_feedforward.band_mps", sf.friction_band_mps,
         {1e-6, 1.0, "1 um/s to 1 m/s", kStateFeedback});
  v.flag("compensator.state_feedback.output_filter.enabled", sf.output_filter_enabled);
  detail::visit_filter_slot("compensator.state_feedback.output_filter", sf.output_filter, v);
  v.flag("compensator.guard.enabled", c.guard_enabled);
  v.real("compensator.guard.highpass_hz", c.guard.highpass_hz,
         {0.01, 1e4, "the corner between tracking motion and vibration: 10 mHz to 10 kHz"});
  v.real("compensator.guard.window_s", c.guard.window_s, {1e-3, 100.0, "1 ms to 100 s of evaluation window"});
  v.real("compensator.guard.min_oscillation_mps", c.guard.min_oscillation_mps,
         {1e-6, 10.0, "1 um/s to 10 m/s: below it there is no oscillation worth guarding against"});
  v.real("compensator.guard.growth_ratio", c.guard.growth_ratio, {1.0001, 100.0, "more than 1: a growth"});
  v.real("compensator.guard.min_decay", c.guard.min_decay,
         {1e-3, 0.999, "a share of the amplitude lost per window: between none and all"});
  v.integer("compensator.guard.windows_to_trip", c.guard.windows_to_trip,
            {1.0, 1000.0, "a count of windows in a row: a whole number, 1 to 1000"});
  v.real("compensator.guard.fade_s", c.guard.fade_s, {0.0, 10.0, "0 (at once) to 10 s"});
  v.real("compensator.guard.max_reference_share", c.guard.max_reference_share,
         {1e-3, 1e3, "the error oscillation over the reference's own: a thousandth to a thousand times"});
  v.real("compensator.guard.max_saturated_share", c.guard.max_saturated_share,
         {1e-3, 1.0,
          "a share of a window's ticks: above it a window at the compensation's limit is not judged sustained"});
  v.real("compensator.guard.saturated_output_share", c.guard.saturated_output_share,
         {1e-3, 1.0, "a share of the compensator's own output range: at or above it the compensator is at its limit"});
  v.flag("compensator.standstill.enabled", c.standstill_enabled);
  v.real("compensator.standstill.rest_velocity_mps", c.standstill.rest_velocity_mps,
         {0.0, 10.0, "0 (the command exactly zero) to 10 m/s"});
  v.real("compensator.standstill.settle_s", c.standstill.settle_s, {0.0, 3600.0, "0 (at once) to an hour at rest"});
  v.real("compensator.standstill.window_s", c.standstill.window_s, {1e-3, 100.0, "1 ms to 100 s of quiet window"});
  v.real("compensator.standstill.quiet_velocity_mps", c.standstill.quiet_velocity_mps,
         {1e-6, 10.0, "1 um/s to 10 m/s of motor velocity (rms over the window)"});
  v.real("compensator.standstill.wake_velocity_mps", c.standstill.wake_velocity_mps,
         {1e-6, 10.0, "1 um/s to 10 m/s of motor velocity (rms over the window)"});
  v.real("compensator.standstill.fade_s", c.standstill.fade_s, {0.0, 60.0, "0 (at once) to a minute"});
  v.real("compensator.standstill.wake_force_n", c.standstill.wake_force_n,
         {1e-3, 1e5, "1 mN to 100 kN of requested compensation (rms over a window spent closed)"});
}

}  // namespace pmlsm
