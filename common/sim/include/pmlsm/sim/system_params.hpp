// Every parameter of the simulated system in one place: what configs/system.yaml
// holds. Components take the parts they need; the controller-side models (the
// drive's motor model, the Kalman filter's masses and stiffness) are taken from
// the nominal plant, as a drive tuned on the datasheet would be.
#pragma once

#include <string>
#include <type_traits>
#include <vector>

#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/compensation/standstill_gate.hpp"
#include "pmlsm/compensation/vibration_guard.hpp"
#include "pmlsm/control/biquad.hpp"
#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/control/input_shaper.hpp"
#include "pmlsm/control/position_loop.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/compensation/state_feedback.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/plant/load_sensor.hpp"
#include "pmlsm/plant/plant.hpp"
#include "pmlsm/util/parameter_section.hpp"
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
  /// K_a's factor when a load encoder is declared (sensors.load.kind: encoder): the fused a_L is
  /// quiet enough for a stiffer law, which breaks a stuck motor free for a swing of micrometres.
  double accel_load_encoder_gain_scale = 0;
  /// K_a's factor with an accelerometer on the load (sensors.load.kind: accelerometer): a_L read,
  /// not inferred from the motor's count, so the same stiffer law.
  double accel_accelerometer_gain_scale = 0;
  /// The RNN's s_o factor when a load encoder is declared: on the fused states its force damps the
  /// last micrometres of a swing the motor's side alone leaves to decay.
  double rnn_load_encoder_gain_scale = 0;
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

/// A lightly damped mode of a linear loop: s = -zeta w_n +- j w_n sqrt(1 - zeta^2).
struct VibrationMode {
  double frequency_hz = 0;  ///< w_n / (2 pi)
  double damping_ratio = 0;
};

struct SystemParams;

/// Every parameter of SystemParams, each declared once by its component (pmlsm/util/parameter_table.hpp):
/// its key path in configs/system.yaml, its kind, its plausible range with the reason and who
/// takes it live. The config
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
  /// Over the velocity loop, off by default; closes_on load needs a load encoder.
  PositionLoopParams position_loop;
  ReferenceModelParams reference_model;  ///< period_s: timing.control_period_s
  KalmanParams kalman;                   ///< period_s: timing.control_period_s
  CompensatorTuning compensator;
  InputShapingTuning input_shaping;
  /// Filter slots: on the velocity loop's force command, and on the compensator's force before it
  /// is added to the PI (period_s: timing.control_period_s).
  FilterChainParams force_command_filters;
  FilterChainParams compensation_filters;
  /// A sensor on the load beside the motor's encoder (none by default), read each control tick.
  LoadSensorParams load_sensor;
  /// The sections declared outside this library (the commissioning's, in analysis; the compensators
  /// added in their own folders, compensators/<name>/), as the system file was read with them
  /// (pmlsm/util/parameter_section.hpp), and their values.
  std::vector<ParameterSection> sections;
  SectionValues section_values;

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
  FilterChainParams force_command_filter_params() const;
  FilterChainParams compensation_filter_params() const;
  /// A shaper of `kind` timed to loop_vibration_mode(), at the control period.
  InputShaperParams input_shaper_params(ShaperKind kind) const;
  /// The Params of the section at `at` (its defaults with the file's values over them).
  template <typename Params>
  Params section(const std::string& at) const {
    return section_params<Params>(section_values, at);
  }
};

template <typename Params, typename Visitor>
void visit_parameters(Params& p, Visitor& v) {
  // Each component declares its own entries next to its code (its Params::declare); this is the
  // system file's layout of them, and which node takes which live (Plausible::live_at).
  constexpr const char* kController = "controller";
  constexpr const char* kAccelFeedback = "accel_feedback";
  constexpr const char* kStateFeedback = "state_feedback";
  constexpr const char* kRnnCompensator = "rnn_compensator";
  v.real("timing.control_period_s", p.timing.control_period_s, {1e-5, 1.0, "a velocity loop between 100 kHz and 1 Hz"});
  v.real("timing.current_loop_period_s", p.timing.current_loop_period_s,
         {1e-7, 1e-3, "a current loop between 10 MHz and 1 kHz"});
  PlantParams::declare("plant", p.plant, v);
  CurrentControllerParams::declare("current_loop", p.current_loop, v);
  VelocityPiParams::declare("velocity_loop", p.velocity_loop, v, kController);
  PositionLoopParams::declare("position_loop", p.position_loop, v, kController);
  ReferenceModelParams::declare("reference_model", p.reference_model, v);
  v.real("input_shaping.vibration_tolerance", p.input_shaping.vibration_tolerance,
         {1e-6, 0.25, "EI's residual vibration on its mode: above 0, at most a quarter of unshaped"});
  FilterChainParams::declare("filters.force_command", p.force_command_filters, v, kController);
  FilterChainParams::declare("filters.compensation", p.compensation_filters, v, kController);
  KalmanParams::declare("kalman", p.kalman, v);
  auto& c = p.compensator;
  RnnCompensatorParams::declare("compensator.rnn", c.rnn, v, kRnnCompensator);
  v.real("compensator.rnn.load_encoder_gain_scale", c.rnn_load_encoder_gain_scale,
         {1.0, 10.0, "s_o x1 (as without) to x10 with a load encoder"});
  AccelFeedbackParams::declare("compensator.acceleration_feedback", c.acceleration_feedback, v, kAccelFeedback);
  v.real("compensator.acceleration_feedback.load_encoder_gain_scale", c.accel_load_encoder_gain_scale,
         {1.0, 10.0, "K_a x1 (as without) to x10 with a load encoder"});
  v.real("compensator.acceleration_feedback.accelerometer_gain_scale", c.accel_accelerometer_gain_scale,
         {1.0, 10.0, "K_a x1 (as without) to x10 with an accelerometer on the load"});
  v.real("compensator.design_load_mass_kg", c.design_load_mass_kg, {0.01, 1e4, "from a 10 g load to a 10 t one"});
  v.real("compensator.max_gain_scale", c.max_gain_scale, {1.0, 100.0, "1 (never above the tuned gains) to 100"});
  StateFeedbackParams::declare("compensator.state_feedback", c.state_feedback, v, kStateFeedback);
  v.flag("compensator.guard.enabled", c.guard_enabled);
  VibrationGuardParams::declare("compensator.guard", c.guard, v);
  v.flag("compensator.standstill.enabled", c.standstill_enabled);
  StandstillGateParams::declare("compensator.standstill", c.standstill, v);
  LoadSensorParams::declare("sensors.load", p.load_sensor, v);
  // The sections' entries go through a visitor behind virtual calls; a const walk sees a copy.
  SectionVisitorOf<Visitor> section_visitor(v);
  for (const ParameterSection& section : p.sections) {
    if constexpr (std::is_const_v<Params>) {
      SectionValues values = p.section_values;
      section.visit(section, values, section_visitor);
    } else {
      section.visit(section, p.section_values, section_visitor);
    }
  }
}

}  // namespace pmlsm
