#include "pmlsm/sim/velocity_controller.hpp"

#include <algorithm>
#include <cmath>

namespace pmlsm {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

VelocityController::VelocityController(const SystemParams& params, const Scenario& scenario)
    : scenario_(scenario),
      period_s_(params.timing.control_period_s),
      reference_(params.reference_model_params()),
      position_(params.position_loop),
      velocity_(params.velocity_pi_params()),
      compensation_filters_(params.compensation_filter_params()),
      force_filters_(params.force_command_filter_params()) {
  scenario_.validate(period_s_);
  if (params.compensator.guard_enabled) guard_.emplace(params.vibration_guard_params());
  const bool load_loop = params.position_loop.closes_on == PositionFeedback::kLoad;
  if (params.load_sensor.kind != LoadSensorKind::kNone && (params.compensator.standstill_enabled || load_loop)) {
    load_monitor_.emplace(LoadSensorMonitorParams::of(params.load_sensor, period_s_));
  }
  if (params.compensator.standstill_enabled) {
    standstill_.emplace(params.standstill_gate_params());
    if (params.load_sensor.kind == LoadSensorKind::kAccelerometer) {
      // A load that swings on a motor its bearings hold is a mass on a spring: m_L a_L = k (x_M - x_L),
      // so the stretch is (m_L / k) a_L, ringing at the load's own w_L = sqrt(k / m_L) (the filter's
      // model). The reading's noise over its band (0.03 m/s^2 rms for 100 ug/sqrt(Hz) over 1 kHz) is
      // micrometres of stretch; a low-pass at w_L with damping 0.5 (unit gain at w_L, its noise
      // band 1.6 f_L) leaves 1-3 um of it on the family's loads and passes the swing whole: the
      // gate judges it against its own thresholds (quiet_accel_swing_m, wake_accel_swing_m).
      const double m_l = params.kalman.model.load_mass_kg;
      const double k = params.kalman.model.spring_n_per_m;
      BiquadParams witness;
      witness.kind = FilterKind::kLowPass;
      witness.frequency_hz = std::sqrt(k / m_l) / (2.0 * kPi);
      witness.damping = 0.5;
      witness.period_s = period_s_;
      accel_witness_.emplace(witness);
      // The gate's push reads the stretch at the mode without the low-pass's quarter-period lag:
      // the reading less a full notch at w_L, 2 zeta w_L s / (s^2 + 2 zeta w_L s + w_L^2), unit gain
      // and no phase at w_L, nothing at 0 Hz (the bias).
      BiquadParams notch;
      notch.kind = FilterKind::kNotch;
      notch.frequency_hz = witness.frequency_hz;
      notch.damping = 0.0;
      notch.second_damping = params.compensator.standstill.accel_stretch_damping;
      notch.period_s = period_s_;
      accel_mode_notch_.emplace(notch);
      stretch_per_accel_s2_ = m_l / k;
    }
  }
  if (scenario_.input_shaper != ShaperKind::kNone) shaper_.emplace(params.input_shaper_params(scenario_.input_shaper));
}

void VelocityController::retune(const SystemParams& params) {
  velocity_.set_params(params.velocity_pi_params());
  position_.set_params(params.position_loop);
  const auto rebuild = [](FilterChain& chain, const FilterChainParams& wanted) {
    if (chain.params().slots != wanted.slots) chain = FilterChain(wanted);
  };
  rebuild(compensation_filters_, params.compensation_filter_params());
  rebuild(force_filters_, params.force_command_filter_params());
  if (shaper_) shaper_->retune(params.input_shaper_params(scenario_.input_shaper));
}

ExternalReferenceParams external_reference_params(const Scenario& scenario, double control_period_s) {
  ExternalReferenceParams p;
  p.timeout_s = scenario.timeout_s;
  p.max_speed_mps = scenario.max_speed_mps;
  p.max_accel_mps2 = scenario.accel_mps2;
  p.period_s = control_period_s;
  return p;
}

VelocityControllerOutput VelocityController::step(std::uint64_t tick, double motor_velocity_mps,
                                                  const Compensation& compensation, const LoadWitness& load) {
  return step_command(scenario_.command_mps(static_cast<double>(tick) * period_s_), motor_velocity_mps, compensation,
                      load);
}

VelocityControllerOutput VelocityController::step_command(double command_mps, double motor_velocity_mps,
                                                          const Compensation& compensation, const LoadWitness& load) {
  VelocityControllerOutput out;
  const std::uint64_t tick = steps_++;
  out.command_mps = shaper_ ? shaper_->step(command_mps) : command_mps;
  ReferenceSample ref;
  if (scenario_.use_reference_model) {
    ref = reference_.step(out.command_mps);
  } else {
    // A profiled reference is smooth already: V_ref = c(t_k), its slope by the backward difference.
    ref.velocity_mps = out.command_mps;
    ref.accel_mps2 = !have_last_command_ ? 0.0 : (out.command_mps - last_command_mps_) / period_s_;
    last_command_mps_ = out.command_mps;
    have_last_command_ = true;
  }
  out.v_ref_mps = ref.velocity_mps;
  out.a_ref_mps2 = ref.accel_mps2;
  out.x_ref_m = x_ref_m_;
  x_ref_m_ += ref.velocity_mps * period_s_;
  // The load sensor's reading, once the monitor believes it: the position loop's and the gate's.
  double load_position_m = std::numeric_limits<double>::quiet_NaN();
  double load_stretch_m = std::numeric_limits<double>::quiet_NaN();
  double load_stretch_at_mode_m = std::numeric_limits<double>::quiet_NaN();
  if (load_monitor_) {
    const LoadSensorVerdict verdict = load_monitor_->judge(
        tick, load.reading.position_m, load.reading.acceleration_mps2, load.reading.saturated, load.motor_position_m);
    if (verdict.use) {
      load_position_m = load.reading.position_m;
      if (standstill_) {
        if (accel_witness_) {
          const double a = load.reading.acceleration_mps2;
          load_stretch_m = stretch_per_accel_s2_ * accel_witness_->step(a);
          load_stretch_at_mode_m = stretch_per_accel_s2_ * (a - accel_mode_notch_->step(a));
        } else {
          load_stretch_m = load.motor_position_m - load.reading.position_m;
        }
      }
    }
  }
  out.position = position_.step({out.x_ref_m, load.motor_position_m, load_position_m});
  // The guard's scale of the previous period (it judges what was applied), then its new look;
  // the standstill gate's of this period (a move opens it on its first tick).
  if (standstill_) {
    out.standstill = standstill_->step({out.command_mps, ref.velocity_mps, motor_velocity_mps, compensation.force_n,
                                        load_stretch_m, accel_witness_.has_value(), load_stretch_at_mode_m});
  }
  const double scale = (guard_ ? guard_->output().scale : 1.0) * out.standstill.scale;
  // The gate's push after the load's stretch joins the request (added only when it acts, so a
  // run without it is the same to the last bit, a -0 included).
  const double request_n = out.standstill.stretch_force_n != 0.0 ? compensation.force_n + out.standstill.stretch_force_n
                                                                 : compensation.force_n;
  out.compensation_applied_n = compensation_filters_.step(scale * request_n);
  if (guard_) {
    out.guard =
        guard_->step({motor_velocity_mps, ref.velocity_mps, out.compensation_applied_n, compensation.output_share});
  }
  const double followed_mps = ref.velocity_mps + out.position.correction_mps;
  const VelocityPiOutput f = velocity_.step({followed_mps, motor_velocity_mps, out.compensation_applied_n});
  // The force command's filters, then the limit again (a filter may overshoot it).
  const double limit_n = velocity_.params().force_limit_n;
  const double filtered_n = force_filters_.step(f.force_n);
  out.force_n = std::clamp(filtered_n, -limit_n, limit_n);
  out.saturated = f.saturated || filtered_n != out.force_n;
  out.velocity_error_mps = followed_mps - motor_velocity_mps;
  return out;
}

}  // namespace pmlsm
