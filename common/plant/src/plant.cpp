#include "pmlsm/plant/plant.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/util/validate.hpp"

#if defined(__GNUC__)
#define PMLSM_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define PMLSM_ALWAYS_INLINE inline
#endif

namespace pmlsm {

const char* to_string(Integrator integrator) {
  switch (integrator) {
    case Integrator::kRk4: return "rk4";
    case Integrator::kHeun: return "heun";
    case Integrator::kAdamsBashforth2: return "ab2";
  }
  return "?";
}

Integrator integrator_from_string(const std::string& name) {
  for (Integrator i : {Integrator::kRk4, Integrator::kHeun, Integrator::kAdamsBashforth2}) {
    if (name == to_string(i)) return i;
  }
  throw std::invalid_argument("must be one of rk4, heun, ab2, got '" + name + "'");
}

namespace {
constexpr double kPi = 3.14159265358979323846;
enum Index { kPsiD = 0, kPsiQ, kPsiDD, kPsiQQ, kXm, kVm, kXl, kVl };

void invert_2x2(double a, double b, double c, double d, double out[2][2]) {
  const double det = a * d - b * c;
  out[0][0] = d / det;
  out[0][1] = -b / det;
  out[1][0] = -c / det;
  out[1][1] = a / det;
}

// sin(theta0 + a) from s = sin(theta0), c = cos(theta0), to third order in a.
// Within one RK4 step the mover travels micrometres, so a stays below 0.01 rad
// at 2 m/s and the error below a^4 / 24 ~ 1e-10: four sin() calls per stage
// become a few multiplications.
double sin_near(double s, double c, double a) {
  const double a2 = a * a;
  return s * (1.0 - 0.5 * a2) + c * a * (1.0 - a2 / 6.0);
}

double cos_near(double s, double c, double a) {
  const double a2 = a * a;
  return c * (1.0 - 0.5 * a2) - s * a * (1.0 - a2 / 6.0);
}

// Beyond this phase step the expansions above lose accuracy: recompute exactly.
constexpr double kMaxExpansionRad = 0.05;

}  // namespace

void MotorElectricalParams::validate() const {
  check_declared_ranges(*this);
  // The flux-current maps (5)-(8) must be invertible and passive (positive definite).
  if (!(mutual_d_inductance_h * mutual_d_inductance_h < armature_d_inductance_h * damper_d_inductance_h)) {
    throw std::invalid_argument("mutual_d_inductance_h: must satisfy L_md^2 < L_ad L_D, got " +
                                format_value(mutual_d_inductance_h));
  }
  if (!(mutual_q_inductance_h * mutual_q_inductance_h < armature_q_inductance_h * damper_q_inductance_h)) {
    throw std::invalid_argument("mutual_q_inductance_h: must satisfy L_mq^2 < L_aq L_Q, got " +
                                format_value(mutual_q_inductance_h));
  }
}

double MotorElectricalParams::thrust_factor_per_m() const { return 1.5 * pole_pairs * kPi / pole_pitch_m; }

double MotorElectricalParams::permanent_magnet_flux_wb() const {
  return motor_constant_n_per_a / thrust_factor_per_m();
}

void RippleParams::validate() const { check_declared_ranges(*this); }

void FrictionParams::validate() const { check_declared_ranges(*this); }

double ripple_force_n(const RippleParams& r, double motor_position_m) {
  return r.scale_n * r.amplitude_1 * std::sin(r.spatial_freq_1_rad_per_m * motor_position_m) *
         (r.amplitude_1 + r.amplitude_2 * std::sin(r.spatial_freq_2_rad_per_m * motor_position_m));
}

double friction_force_n(const FrictionParams& f, double motor_velocity_mps) {
  const double w = std::min(1.0, std::max(-1.0, motor_velocity_mps / f.regularisation_velocity_mps));
  return -(f.coulomb_n * w * (1.5 - 0.5 * w * w) + f.viscous_n_s_per_m * motor_velocity_mps);
}

void MechanicsParams::validate() const { check_declared_ranges(*this); }

void InverterParams::validate() const { check_declared_ranges(*this); }

double InverterParams::voltage_limit_v() const { return dc_bus_v / std::sqrt(3.0); }

void EncoderParams::validate() const {
  check_declared_ranges(*this);
  if (mount_frequency_hz > 0.0) require_in_range("mount_damping", mount_damping, 1e-4, 2.0);
}

void PlantParams::validate() const {
  validate_section("electrical", [&] { electrical.validate(); });
  validate_section("ripple", [&] { ripple.validate(); });
  validate_section("friction", [&] { friction.validate(); });
  validate_section("mechanics", [&] { mechanics.validate(); });
  validate_section("inverter", [&] { inverter.validate(); });
  validate_section("encoder", [&] { encoder.validate(); });
  check_declared_ranges(*this);  // max_step_s, its one entry besides the sections (checked above, by name)
}

namespace {

// Largest eigenvalue of L^-1 R for one axis, L = [[L_a, L_m], [L_m, L_D]], R = diag(R_a, R_D):
// the fastest decay rate of its flux linkages (5)-(8). Real and positive for a passive axis.
double fastest_pole_per_s(double l_a, double l_m, double l_d, double r_a, double r_d) {
  const double det_l = l_a * l_d - l_m * l_m;
  const double trace = (l_d * r_a + l_a * r_d) / det_l;
  const double det = r_a * r_d / det_l;
  return 0.5 * trace + std::sqrt(std::max(0.0, 0.25 * trace * trace - det));
}

void require_rate(const char* name, double value, const char* what, double rate_per_s, double step_s, double limit) {
  if (!(rate_per_s * step_s <= limit)) {
    throw std::invalid_argument(std::string(name) + ": " + what + " = " + format_value(rate_per_s) +
                                " 1/s times max_step_s " + format_value(step_s) + " must be <= " + format_value(limit) +
                                " for the explicit integrator, got " + format_value(value));
  }
}

}  // namespace

void PlantParams::check_step() const {
  // Rates in 1/s; an explicit step h resolves a rate r only while r h is small:
  // 0.1 for an oscillation (60 steps a period), 0.5 for a decay.
  const auto& m = mechanics;
  const double inverse_masses = 1.0 / m.motor_mass_kg + 1.0 / m.load_mass_kg;
  require_rate("mechanics.spring_n_per_m", m.spring_n_per_m, "the load mode sqrt(k (1/m_M + 1/m_L))",
               std::sqrt(m.spring_n_per_m * inverse_masses), max_step_s, 0.1);
  require_rate("mechanics.damping_n_s_per_m", m.damping_n_s_per_m, "the damping rate b (1/m_M + 1/m_L)",
               m.damping_n_s_per_m * inverse_masses, max_step_s, 0.5);
  require_rate("encoder.mount_frequency_hz", encoder.mount_frequency_hz, "the read head's mode 2 pi f_e",
               2.0 * kPi * encoder.mount_frequency_hz, max_step_s, 0.1);
  // Friction (11): its slope at v = 0 is 1.5 F_c / v_eps + F_v, acting on m_M.
  require_rate(
      "friction.regularisation_velocity_mps", friction.regularisation_velocity_mps,
      "the friction slope (1.5 F_c / v_eps + F_v) / m_M",
      (1.5 * friction.coulomb_n / friction.regularisation_velocity_mps + friction.viscous_n_s_per_m) / m.motor_mass_kg,
      max_step_s, 0.5);
  const auto& e = electrical;
  require_rate("electrical.resistance_ohm", e.resistance_ohm, "the fastest d-axis pole of L^-1 R",
               fastest_pole_per_s(e.armature_d_inductance_h, e.mutual_d_inductance_h, e.damper_d_inductance_h,
                                  e.resistance_ohm, e.damper_d_resistance_ohm),
               max_step_s, 0.5);
  require_rate("electrical.resistance_ohm", e.resistance_ohm, "the fastest q-axis pole of L^-1 R",
               fastest_pole_per_s(e.armature_q_inductance_h, e.mutual_q_inductance_h, e.damper_q_inductance_h,
                                  e.resistance_ohm, e.damper_q_resistance_ohm),
               max_step_s, 0.5);
}

Plant::Plant(const PlantParams& params) : params_(params), noise_rng_(params.encoder.noise_seed), noise_(0.0, 1.0) {
  params_.validate();
  params_.check_step();
  const auto& e = params_.electrical;
  Coefficients& c = coeff_;
  c.psi_pm = e.permanent_magnet_flux_wb();
  c.thrust_factor = e.thrust_factor_per_m();
  c.electrical_rad_per_m = kPi / e.pole_pitch_m;
  invert_2x2(e.armature_d_inductance_h, e.mutual_d_inductance_h, e.mutual_d_inductance_h, e.damper_d_inductance_h,
             c.inv_ld);
  invert_2x2(e.armature_q_inductance_h, e.mutual_q_inductance_h, e.mutual_q_inductance_h, e.damper_q_inductance_h,
             c.inv_lq);
  c.r = e.resistance_ohm;
  c.r_dd = e.damper_d_resistance_ohm;
  c.r_qq = e.damper_q_resistance_ohm;
  c.phi1 = params_.ripple.spatial_freq_1_rad_per_m;
  c.phi2 = params_.ripple.spatial_freq_2_rad_per_m;
  c.ripple_gain = params_.ripple.scale_n * params_.ripple.amplitude_1;
  c.a_r1 = params_.ripple.amplitude_1;
  c.a_r2 = params_.ripple.amplitude_2;
  c.coulomb = params_.friction.coulomb_n;
  c.viscous = params_.friction.viscous_n_s_per_m;
  c.inv_friction_band = 1.0 / params_.friction.regularisation_velocity_mps;
  c.k = params_.mechanics.spring_n_per_m;
  c.b = params_.mechanics.damping_n_s_per_m;
  c.inv_motor_mass = 1.0 / params_.mechanics.motor_mass_kg;
  c.inv_load_mass = 1.0 / params_.mechanics.load_mass_kg;
  voltage_limit_v_ = params_.inverter.voltage_limit_v();
  inv_encoder_resolution_ = 1.0 / params_.encoder.resolution_m;
  compliant_mount_ = params_.encoder.mount_frequency_hz > 0.0;
  const double mount_rad_s = 2.0 * kPi * params_.encoder.mount_frequency_hz;
  mount_stiffness_per_s2_ = mount_rad_s * mount_rad_s;
  mount_damping_per_s_ = 2.0 * params_.encoder.mount_damping * mount_rad_s;
  inv_max_step_ = 1.0 / params_.max_step_s;
  reset(PlantInitialCondition{});
}

namespace {

// The first entry of the state that is not finite or beyond any physical motor, or nullptr.
const char* diverged_entry(const PlantState& s, double& value) {
  constexpr double kMaxFluxWb = 1e6, kMaxPositionM = 1e6, kMaxVelocityMps = 1e4;
  const struct {
    const char* name;
    double value;
    double bound;
  } entries[] = {
      {"psi_d_wb", s.psi_d_wb, kMaxFluxWb},
      {"psi_q_wb", s.psi_q_wb, kMaxFluxWb},
      {"psi_dd_wb", s.psi_dd_wb, kMaxFluxWb},
      {"psi_qq_wb", s.psi_qq_wb, kMaxFluxWb},
      {"motor_position_m", s.motor_position_m, kMaxPositionM},
      {"motor_velocity_mps", s.motor_velocity_mps, kMaxVelocityMps},
      {"load_position_m", s.load_position_m, kMaxPositionM},
      {"load_velocity_mps", s.load_velocity_mps, kMaxVelocityMps},
  };
  for (const auto& e : entries) {
    if (!(std::fabs(e.value) <= e.bound)) {  // also true for NaN
      value = e.value;
      return e.name;
    }
  }
  return nullptr;
}

}  // namespace

void Plant::reset(const PlantInitialCondition& initial) {
  state_ = PlantState{};
  // No current: psi_d = psi_D = psi_pm by (5), (7); q-axis fluxes zero.
  state_.psi_d_wb = coeff_.psi_pm;
  state_.psi_dd_wb = coeff_.psi_pm;
  state_.motor_position_m = initial.motor_position_m;
  state_.motor_velocity_mps = initial.motor_velocity_mps;
  state_.load_position_m = initial.load_position_m;
  state_.load_velocity_mps = initial.load_velocity_mps;
  head_offset_m_ = 0.0;
  head_offset_rate_mps_ = 0.0;
  ripple_phase_ = anchor_at(state_.motor_position_m);
  steps_since_resync_ = 0;
  history_valid_ = false;
  last_input_ = PlantInput{};
  divergence_ = PlantDivergence{};
  steps_since_reset_ = 0;
  double bad_value = 0;
  if (const char* bad = diverged_entry(state_, bad_value)) {
    throw std::invalid_argument(std::string("initial condition: ") + bad +
                                ": must be finite and within any motor's range, got " + format_value(bad_value));
  }
}

PMLSM_ALWAYS_INLINE Plant::StateVector Plant::to_vector(const PlantState& s) {
  return {s.psi_d_wb,         s.psi_q_wb,           s.psi_dd_wb,       s.psi_qq_wb,
          s.motor_position_m, s.motor_velocity_mps, s.load_position_m, s.load_velocity_mps};
}

PMLSM_ALWAYS_INLINE PlantState Plant::from_vector(const StateVector& v) {
  PlantState s;
  s.psi_d_wb = v[kPsiD];
  s.psi_q_wb = v[kPsiQ];
  s.psi_dd_wb = v[kPsiDD];
  s.psi_qq_wb = v[kPsiQQ];
  s.motor_position_m = v[kXm];
  s.motor_velocity_mps = v[kVm];
  s.load_position_m = v[kXl];
  s.load_velocity_mps = v[kVl];
  return s;
}

Plant::RippleAnchor Plant::anchor_at(double x) const {
  const auto& r = params_.ripple;
  RippleAnchor a;
  a.x0 = x;
  a.s1 = std::sin(r.spatial_freq_1_rad_per_m * x);
  a.c1 = std::cos(r.spatial_freq_1_rad_per_m * x);
  a.s2 = std::sin(r.spatial_freq_2_rad_per_m * x);
  a.c2 = std::cos(r.spatial_freq_2_rad_per_m * x);
  return a;
}

PMLSM_ALWAYS_INLINE void Plant::advance_ripple_phase() {
  const double x = state_.motor_position_m;
  const double a1 = coeff_.phi1 * (x - ripple_phase_.x0);
  const double a2 = coeff_.phi2 * (x - ripple_phase_.x0);
  if (++steps_since_resync_ >= kResyncSteps || std::abs(a1) > kMaxExpansionRad || std::abs(a2) > kMaxExpansionRad) {
    ripple_phase_ = anchor_at(x);
    steps_since_resync_ = 0;
    return;
  }
  RippleAnchor next;
  next.x0 = x;
  next.s1 = sin_near(ripple_phase_.s1, ripple_phase_.c1, a1);
  next.c1 = cos_near(ripple_phase_.s1, ripple_phase_.c1, a1);
  next.s2 = sin_near(ripple_phase_.s2, ripple_phase_.c2, a2);
  next.c2 = cos_near(ripple_phase_.s2, ripple_phase_.c2, a2);
  ripple_phase_ = next;
}

PMLSM_ALWAYS_INLINE void Plant::rhs(const Coefficients& c, const StateVector& s, double u_d, double u_q,
                                    double load_force, const RippleAnchor& anchor, Rhs& out) {
  // Currents from fluxes, inverting (5)-(8).
  const double fd = s[kPsiD] - c.psi_pm;
  const double fdd = s[kPsiDD] - c.psi_pm;
  out.i_d = c.inv_ld[0][0] * fd + c.inv_ld[0][1] * fdd;
  out.i_dd = c.inv_ld[1][0] * fd + c.inv_ld[1][1] * fdd;
  out.i_q = c.inv_lq[0][0] * s[kPsiQ] + c.inv_lq[0][1] * s[kPsiQQ];
  out.i_qq = c.inv_lq[1][0] * s[kPsiQ] + c.inv_lq[1][1] * s[kPsiQQ];

  const double v_m = s[kVm];
  const double w_s = c.electrical_rad_per_m * v_m;               // (2)
  out.derivative[kPsiD] = u_d - c.r * out.i_d + w_s * s[kPsiQ];  // (1)
  out.derivative[kPsiQ] = u_q - c.r * out.i_q - w_s * s[kPsiD];  // (2)
  out.derivative[kPsiDD] = -c.r_dd * out.i_dd;                   // (3)
  out.derivative[kPsiQQ] = -c.r_qq * out.i_qq;                   // (4)

  out.thrust = c.thrust_factor * (s[kPsiD] * out.i_q - s[kPsiQ] * out.i_d);  // (9)

  const double dx = s[kXm] - anchor.x0;
  const double sin1 = sin_near(anchor.s1, anchor.c1, c.phi1 * dx);
  const double sin2 = sin_near(anchor.s2, anchor.c2, c.phi2 * dx);
  out.ripple = c.ripple_gain * sin1 * (c.a_r1 + c.a_r2 * sin2);  // (10), ripple_gain = K_s A_r1

  // (11) with sign(v) smoothed inside |v| < v_eps only: s(u) = u (3 - u^2) / 2 on the
  // clamped u = v / v_eps, which is exactly sign(v) for |v| >= v_eps and C1 at
  // the joins. Friction opposes the motion.
  const double u = std::min(1.0, std::max(-1.0, v_m * c.inv_friction_band));
  out.friction = -(c.coulomb * u * (1.5 - 0.5 * u * u) + c.viscous * v_m);

  // (13) with dx = x_l - x_m; spring is the Kalman filter's F_s = -(k dx + b dv).
  const double stretch = s[kXl] - s[kXm];
  const double stretch_rate = s[kVl] - v_m;
  out.spring = -(c.k * stretch + c.b * stretch_rate);
  out.derivative[kXm] = v_m;
  out.derivative[kVm] = (-out.spring + out.thrust + out.ripple + out.friction) * c.inv_motor_mass;
  out.derivative[kXl] = s[kVl];
  out.derivative[kVl] = (out.spring + load_force) * c.inv_load_mass;
}

// The state lives in a local array across all sub-steps of one step() call;
// rhs() is forced inline so the stages stay in registers. Both methods use
// the ripple phase anchored at the start of each sub-step.
void Plant::integrate(double u_d, double u_q, double load_force, double h, int substeps) {
  // A local copy of the constants: the compiler then knows the stage stores
  // cannot alias them and keeps them in registers.
  const Coefficients c = coeff_;
  const Integrator method = params_.integrator;
  StateVector y = to_vector(state_);
  Rhs k1, k2, k3, k4;
  StateVector stage;

  if (method == Integrator::kAdamsBashforth2 && history_valid_ && h == history_step_s_) {
    // The inputs enter the right-hand side additively (f = g(y) + B u), so the
    // stored f_{n-1} is moved to the new input exactly: the history then
    // belongs to the ODE being integrated now.
    previous_derivative_[kPsiD] += u_d - history_input_.u_d_v;
    previous_derivative_[kPsiQ] += u_q - history_input_.u_q_v;
    previous_derivative_[kVl] += (load_force - history_input_.load_force_n) * c.inv_load_mass;
  } else {
    history_valid_ = false;
  }

  for (int n = 0; n < substeps; ++n) {
    const RippleAnchor& anchor = ripple_phase_;
    rhs(c, y, u_d, u_q, load_force, anchor, k1);
    if (method == Integrator::kAdamsBashforth2 && history_valid_) {
      // Two-step Adams-Bashforth, second order, one evaluation per step:
      // y_{n+1} = y_n + h (3 f_n - f_{n-1}) / 2.
      for (int i = 0; i < 8; ++i) y[i] += 0.5 * h * (3.0 * k1.derivative[i] - previous_derivative_[i]);
      previous_derivative_ = k1.derivative;
    } else if (method != Integrator::kRk4) {
      // Heun (explicit trapezoid), second order; also AB2's first step.
      for (int i = 0; i < 8; ++i) stage[i] = y[i] + h * k1.derivative[i];
      rhs(c, stage, u_d, u_q, load_force, anchor, k2);
      for (int i = 0; i < 8; ++i) y[i] += 0.5 * h * (k1.derivative[i] + k2.derivative[i]);
      previous_derivative_ = k1.derivative;
      history_valid_ = true;
    } else {
      // Classical Runge-Kutta, fourth order.
      for (int i = 0; i < 8; ++i) stage[i] = y[i] + 0.5 * h * k1.derivative[i];
      rhs(c, stage, u_d, u_q, load_force, anchor, k2);
      for (int i = 0; i < 8; ++i) stage[i] = y[i] + 0.5 * h * k2.derivative[i];
      rhs(c, stage, u_d, u_q, load_force, anchor, k3);
      for (int i = 0; i < 8; ++i) stage[i] = y[i] + h * k3.derivative[i];
      rhs(c, stage, u_d, u_q, load_force, anchor, k4);
      for (int i = 0; i < 8; ++i) {
        y[i] += h / 6.0 * (k1.derivative[i] + 2.0 * k2.derivative[i] + 2.0 * k3.derivative[i] + k4.derivative[i]);
      }
    }
    state_.motor_position_m = y[kXm];
    advance_ripple_phase();
    if (compliant_mount_) advance_encoder_head(k1.derivative[kVm], h);
  }
  history_step_s_ = h;
  history_input_ = PlantInput{u_d, u_q, load_force};
  state_ = from_vector(y);
}

void Plant::advance_encoder_head(double motor_accel_mps2, double h) {
  head_offset_rate_mps_ -=
      h * (mount_stiffness_per_s2_ * head_offset_m_ + mount_damping_per_s_ * head_offset_rate_mps_ + motor_accel_mps2);
  head_offset_m_ += h * head_offset_rate_mps_;
}

PlantMeasurement Plant::step(const PlantInput& input, double dt_s) {
  if (divergence_.diverged) return measure();
  if (!(std::isfinite(dt_s) && dt_s > 0.0)) {
    ++counters_.rejected_inputs;
    return measure();
  }
  PlantInput applied = input;
  if (!all_finite(input.u_d_v, input.u_q_v, input.load_force_n)) {
    ++counters_.rejected_inputs;
    applied = last_input_;
  }
  const double magnitude_sq = applied.u_d_v * applied.u_d_v + applied.u_q_v * applied.u_q_v;
  if (magnitude_sq > voltage_limit_v_ * voltage_limit_v_) {
    const double scale = voltage_limit_v_ / std::sqrt(magnitude_sq);
    applied.u_d_v *= scale;
    applied.u_q_v *= scale;
    ++counters_.voltage_limited;
  }
  last_input_ = applied;
  ++counters_.steps;

  // Fewest equal sub-steps no longer than max_step_s (ceil without a libm call).
  const double ratio = dt_s * inv_max_step_;
  int substeps = static_cast<int>(ratio);
  if (substeps < 1 || static_cast<double>(substeps) < ratio - 1e-9) ++substeps;
  const double h = dt_s / substeps;
  const PlantState before = state_;
  const RippleAnchor ripple_before = ripple_phase_;
  const double head_offset_before = head_offset_m_, head_offset_rate_before = head_offset_rate_mps_;
  integrate(applied.u_d_v, applied.u_q_v, applied.load_force_n, h, substeps);
  ++steps_since_reset_;
  double bad_value = 0;
  if (const char* bad = diverged_entry(state_, bad_value)) {
    divergence_ = PlantDivergence{true, bad, bad_value, steps_since_reset_};
    state_ = before;
    ripple_phase_ = ripple_before;
    head_offset_m_ = head_offset_before;
    head_offset_rate_mps_ = head_offset_rate_before;
    history_valid_ = false;
  }
  return measure();
}

PlantMeasurement Plant::measure() {
  const auto& enc = params_.encoder;
  double x = state_.motor_position_m + head_offset_m_;
  if (enc.position_noise_std_m > 0.0) x += enc.position_noise_std_m * noise_(noise_rng_);
  PlantMeasurement out;
  // Counts = floor(x / resolution), by truncation corrected for negative x:
  // std::floor is a libm call without SSE4.1 and this runs every current-loop period.
  const double counts = x * inv_encoder_resolution_;
  auto whole = static_cast<std::int64_t>(counts);
  if (static_cast<double>(whole) > counts) --whole;
  out.encoder_position_m = static_cast<double>(whole) * enc.resolution_m;
  // Armature currents by (5), (6) inverted; the drive measures them exactly.
  out.i_d_a = coeff_.inv_ld[0][0] * (state_.psi_d_wb - coeff_.psi_pm) +
              coeff_.inv_ld[0][1] * (state_.psi_dd_wb - coeff_.psi_pm);
  out.i_q_a = coeff_.inv_lq[0][0] * state_.psi_q_wb + coeff_.inv_lq[0][1] * state_.psi_qq_wb;
  return out;
}

PlantTruth Plant::truth() const {
  Rhs r;
  rhs(coeff_, to_vector(state_), last_input_.u_d_v, last_input_.u_q_v, last_input_.load_force_n, ripple_phase_, r);
  PlantTruth t;
  t.state = state_;
  t.i_d_a = r.i_d;
  t.i_q_a = r.i_q;
  t.i_dd_a = r.i_dd;
  t.i_qq_a = r.i_qq;
  t.thrust_n = r.thrust;
  t.ripple_n = r.ripple;
  t.friction_n = r.friction;
  t.spring_force_n = r.spring;
  t.encoder_head_position_m = state_.motor_position_m + head_offset_m_;
  t.motor_accel_mps2 = r.derivative[kVm];
  t.load_accel_mps2 = r.derivative[kVl];
  return t;
}

}  // namespace pmlsm
