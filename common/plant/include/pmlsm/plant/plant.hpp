// Nonlinear plant: permanent-magnet linear synchronous motor (PMLSM) in the
// d-q frame with damper windings, driving a load through a spring (two-mass
// system), as modelled by Yousefi et al. (2008), eqs. (1)-(13).
//
// States (fluxes are integrated, currents follow from them):
//   psi_d, psi_q   armature flux linkages [Wb]
//   psi_D, psi_Q   damper-winding flux linkages [Wb]
//   x_m, v_m       motor (mover) position [m] and velocity [m/s]
//   x_l, v_l       load position [m] and velocity [m/s]
//
// Electrical, with w_s = pi v_m / tau (2):
//   dpsi_d/dt = u_d - R i_d + w_s psi_q          (1)
//   dpsi_q/dt = u_q - R i_q - w_s psi_d          (2)
//   dpsi_D/dt = -R_D i_D,  dpsi_Q/dt = -R_Q i_Q  (3), (4)
//   [psi_d - psi_pm; psi_D - psi_pm] = [L_ad L_md; L_md L_D] [i_d; i_D]   (5), (7)
//   [psi_q; psi_Q]                   = [L_aq L_mq; L_mq L_Q] [i_q; i_Q]   (6), (8)
//   F_dx = (3p/2)(pi/tau)(psi_d i_q - psi_q i_d)                        (9)
// psi_pm is not a free parameter: it follows from the motor constant,
// K_m = (3p/2)(pi/tau) psi_pm, so that with i_d = 0 and no damper current the
// steady thrust is exactly K_m i_q (i_q in amplitude-invariant, peak amperes).
//
// Disturbances (12): F_dist = F_ripple + F_friction with
//   F_ripple = K_s A_r1 sin(phi_1 x_m) [A_r1 + A_r2 sin(phi_2 x_m)]        (10)
//   F_friction = -(F_c s(v_m) + F_v v_m)                                     (11)
// where s(v) replaces sign(v) inside a narrow band |v| < v_eps only:
//   s(v) = u (3 - u^2) / 2,  u = clamp(v / v_eps, -1, 1),
// a cubic that equals sign(v) exactly for |v| >= v_eps and joins it with a
// continuous slope. (11) is thus exact away from zero velocity, and a
// fixed-step integrator does not chatter at v = 0: the slope through zero,
// 1.5 F_c / v_eps, is a stiff but integrable viscous friction. A mover held
// by a force |F| < F_c creeps at below v_eps instead of sticking. The sign
// is chosen so friction opposes the motion (the paper writes F_T = F + F_dist
// without fixing the sign).
//
// Mechanics (13), dx = x_l - x_m, dv = v_l - v_m:
//   m_M a_m =  k dx + b dv + F_dx + F_dist
//   m_L a_l = -k dx - b dv + F_load_ext
//
// Inverter: an ideal voltage source whose voltage vector is limited to
// |u_dq| <= V_dc / sqrt(3) (the largest phase amplitude of space-vector PWM).
//
// Integration (a config choice, `integrator`): classical fourth-order
// Runge-Kutta, Heun's second-order method, or the two-step Adams-Bashforth
// method (second order, one evaluation of the right-hand side per step; its
// first step after a reset is a Heun step, and as the inputs enter the
// equations additively its history carries over exactly across input
// changes). Every step is far inside each method's stability region: the
// stiffest eigenvalue, the friction band's 1.5 F_c / (v_eps m_M), gives
// h lambda = 0.075 at 10 us. step(input, dt) splits dt
// into the fewest equal sub-steps no longer than max_step_s (10 us in the
// paper); the input voltage is held over dt (zero-order hold, as a PWM
// inverter holds its duty cycle). tests/unit/plant/plant_test.cpp measures the
// order and the error against a fine-step reference.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <string>

#include "pmlsm/util/parameter_table.hpp"
#include "pmlsm/util/two_mass_model.hpp"

namespace pmlsm {

struct MotorElectricalParams {
  double resistance_ohm = 0;           ///< R, armature resistance per phase
  double armature_d_inductance_h = 0;  ///< L_ad
  double armature_q_inductance_h = 0;  ///< L_aq
  double mutual_d_inductance_h = 0;    ///< L_md, armature-damper magnetising inductance
  double mutual_q_inductance_h = 0;    ///< L_mq
  double damper_d_inductance_h = 0;    ///< L_D
  double damper_q_inductance_h = 0;    ///< L_Q
  double damper_d_resistance_ohm = 0;  ///< R_D
  double damper_q_resistance_ohm = 0;  ///< R_Q
  double motor_constant_n_per_a = 0;   ///< K_m, thrust per q-axis (peak) ampere
  double pole_pitch_m = 0;             ///< tau
  double pole_pairs = 0;               ///< p in (9)
  /// The declared ranges, then what they cannot say: the flux-current maps invertible.
  void validate() const;
  /// Its entries under `at` ("plant.electrical"). Self: MotorElectricalParams, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& e, Visitor& v) {
    const std::string el = at + ".";
    const Plausible resistance{1e-3, 1e3, "winding resistances of real motors: 1 mOhm to 1 kOhm"};
    const Plausible inductance{1e-6, 10.0, "winding inductances of real motors: 1 uH to 10 H"};
    v.real(el + "resistance_ohm", e.resistance_ohm, resistance);
    v.real(el + "armature_d_inductance_h", e.armature_d_inductance_h, inductance);
    v.real(el + "armature_q_inductance_h", e.armature_q_inductance_h, inductance);
    v.real(el + "mutual_d_inductance_h", e.mutual_d_inductance_h, {0.0, 10.0, "0 (no damper coupling) to 10 H"});
    v.real(el + "mutual_q_inductance_h", e.mutual_q_inductance_h, {0.0, 10.0, "0 (no damper coupling) to 10 H"});
    v.real(el + "damper_d_inductance_h", e.damper_d_inductance_h, inductance);
    v.real(el + "damper_q_inductance_h", e.damper_q_inductance_h, inductance);
    v.real(el + "damper_d_resistance_ohm", e.damper_d_resistance_ohm, resistance);
    v.real(el + "damper_q_resistance_ohm", e.damper_q_resistance_ohm, resistance);
    v.real(el + "motor_constant_n_per_a", e.motor_constant_n_per_a,
           {0.1, 1e4, "thrust constants of linear motors: 0.1 N/A to 10 kN/A"});
    v.real(el + "pole_pitch_m", e.pole_pitch_m, {1e-3, 1.0, "pole pitches of 1 mm to 1 m"});
    v.integer(el + "pole_pairs", e.pole_pairs, {1.0, 1000.0, "a count of pole pairs: a whole number, 1 to 1000"});
  }
  /// psi_pm = K_m / ((3p/2)(pi/tau)).
  double permanent_magnet_flux_wb() const;
  /// (3p/2)(pi/tau): thrust per (flux * current).
  double thrust_factor_per_m() const;
};

struct RippleParams {
  double scale_n = 0;                   ///< K_s
  double amplitude_1 = 0;               ///< A_r1
  double amplitude_2 = 0;               ///< A_r2
  double spatial_freq_1_rad_per_m = 0;  ///< phi_1
  double spatial_freq_2_rad_per_m = 0;  ///< phi_2
  void validate() const;
  /// Its entries under `at` (the plant's, and the Kalman filter's model of it). Self: RippleParams,
  /// const or not (pmlsm/util/parameter_table.hpp).
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& r, Visitor& v) {
    v.real(at + ".scale_n", r.scale_n, {0.0, 1e4, "K_s up to 10 kN, the thrust of the largest linear motors"});
    v.real(at + ".amplitude_1", r.amplitude_1, {-10.0, 10.0, "normalised harmonic amplitude: K_s carries the newtons"});
    v.real(at + ".amplitude_2", r.amplitude_2, {-10.0, 10.0, "normalised harmonic amplitude: K_s carries the newtons"});
    v.real(at + ".spatial_freq_1_rad_per_m", r.spatial_freq_1_rad_per_m,
           {0.0, 1e5, "wavelengths down to 63 um, finer than any pole pitch or detent"});
    v.real(at + ".spatial_freq_2_rad_per_m", r.spatial_freq_2_rad_per_m,
           {0.0, 1e5, "wavelengths down to 63 um, finer than any pole pitch or detent"});
  }
};

struct FrictionParams {
  double coulomb_n = 0;                    ///< F_coulomb
  double viscous_n_s_per_m = 0;            ///< F_viscous
  double regularisation_velocity_mps = 0;  ///< v_eps: half-width of the smoothed band of s(v)
  void validate() const;
  /// Its entries under `at` (the plant's, and the Kalman filter's model of it).
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& f, Visitor& v) {
    v.real(at + ".coulomb_n", f.coulomb_n, {0.0, 1e4, "up to 10 kN, the thrust of the largest linear motors"});
    v.real(at + ".viscous_n_s_per_m", f.viscous_n_s_per_m,
           {0.0, 1e5, "up to 10 kN at 0.1 m/s, the largest thrust at a crawl"});
    v.real(at + ".regularisation_velocity_mps", f.regularisation_velocity_mps,
           {1e-7, 1.0, "the smoothed band of sign(v): from 0.1 um/s to 1 m/s"});
  }
};

/// Ripple force (10): F_ripple(x) = K_s A_r1 sin(phi_1 x) [A_r1 + A_r2 sin(phi_2 x)] [N].
/// The plant evaluates the same expression incrementally in its hot loop; this is the
/// reference form, for the filter's model and the tests.
double ripple_force_n(const RippleParams& ripple, double motor_position_m);

/// Friction force (11), opposing the motion: -(F_coulomb s(v) + F_viscous v) [N], with
/// s(v) = sign(v) outside +-v_eps and the cubic w (3 - w^2) / 2, w = v / v_eps, inside.
double friction_force_n(const FrictionParams& friction, double motor_velocity_mps);

struct MechanicsParams {
  double motor_mass_kg = 0;      ///< m_M
  double load_mass_kg = 0;       ///< m_L
  double spring_n_per_m = 0;     ///< k
  double damping_n_s_per_m = 0;  ///< b
  void validate() const;
  /// Its entries under `at` ("plant.mechanics").
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& m, Visitor& v) {
    declare_two_mass(at, m.motor_mass_kg, m.load_mass_kg, m.spring_n_per_m, v);
    v.real(at + ".damping_n_s_per_m", m.damping_n_s_per_m, {0.0, 1e6, "0 (undamped) to a stiff hydraulic damper"});
  }
};

struct InverterParams {
  double dc_bus_v = 0;
  void validate() const;
  /// Its entries under `at` ("plant.inverter").
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& i, Visitor& v) {
    v.real(at + ".dc_bus_v", i.dc_bus_v,
           {1.0, 2000.0, "from 1 V to the 1500 V DC of the largest industrial inverters"});
  }
  double voltage_limit_v() const;  ///< V_dc / sqrt(3)
};

struct EncoderParams {
  double resolution_m = 0;          ///< quantisation step of the position reading
  double position_noise_std_m = 0;  ///< optional white noise added before quantisation
  std::uint64_t noise_seed = 0;
  /// The read head on a compliant mount (a bracket, the motor's frame): a mode of its own the
  /// two-mass model does not hold, x_e'' = w_e^2 (x_m - x_e) + 2 zeta_e w_e (v_m - v_e), read
  /// instead of x_m; the head is light, so nothing acts back on the motor. 0: a rigid mount.
  double mount_frequency_hz = 0;  ///< w_e / (2 pi)
  double mount_damping = 0;       ///< zeta_e, used when mount_frequency_hz > 0
  /// The declared ranges, then a compliant mount's least damping.
  void validate() const;
  /// Its entries under `at` ("plant.encoder").
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& e, Visitor& v) {
    const std::string en = at + ".";
    v.real(en + "resolution_m", e.resolution_m,
           {1e-10, 1e-2, "from an interferometer's 0.1 nm to a 10 mm coarse scale"});
    v.real(en + "position_noise_std_m", e.position_noise_std_m, {0.0, 1e-2, "0 to 10 mm of noise"});
    v.integer(en + "noise_seed", e.noise_seed, {0.0, 18446744073709551615.0, "a seed: any whole number of 64 bits"});
    v.real(en + "mount_frequency_hz", e.mount_frequency_hz, {0.0, 1e5, "0 (a rigid mount) to 100 kHz"});
    v.real(en + "mount_damping", e.mount_damping, {0.0, 2.0, "0 to 2 (at least 1e-4 with a compliant mount)"});
  }
};

/// Fixed-step explicit integrators; tests/unit/plant/plant_test.cpp measures their order and error.
enum class Integrator { kRk4, kHeun, kAdamsBashforth2 };
const char* to_string(Integrator integrator);
/// @throws std::invalid_argument on an unknown name.
Integrator integrator_from_string(const std::string& name);

struct PlantParams {
  MotorElectricalParams electrical;
  RippleParams ripple;
  FrictionParams friction;
  MechanicsParams mechanics;
  InverterParams inverter;
  EncoderParams encoder;
  double max_step_s = 0;  ///< longest integrator step
  Integrator integrator = Integrator::kRk4;
  void validate() const;
  /// The explicit integrators are stable and accurate only while every rate of the
  /// model times max_step_s stays small: the load mode, the damper, the friction
  /// slope and the fastest electrical pole (see plant.cpp). Separate from validate()
  /// so that a config's plausible ranges are checked before these combinations.
  /// @throws std::invalid_argument naming the parameter and the rate.
  void check_step() const;
  /// Its entries under `at` ("plant"): the integrator, the motor's windings, ripple, friction, the
  /// two-mass mechanics, the inverter and the encoder. Self: PlantParams, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    v.real(at + ".max_step_s", p.max_step_s,
           {1e-9, 1e-3, "the integrator step: at least one per millisecond, at most a billion per second"});
    v.choice(at + ".integrator", p.integrator, &integrator_from_string);
    MotorElectricalParams::declare(at + ".electrical", p.electrical, v);
    RippleParams::declare(at + ".ripple", p.ripple, v);
    FrictionParams::declare(at + ".friction", p.friction, v);
    MechanicsParams::declare(at + ".mechanics", p.mechanics, v);
    InverterParams::declare(at + ".inverter", p.inverter, v);
    EncoderParams::declare(at + ".encoder", p.encoder, v);
  }
};

/// The integrated state; see the class comment for the meaning of each entry.
struct PlantState {
  double psi_d_wb = 0, psi_q_wb = 0, psi_dd_wb = 0, psi_qq_wb = 0;
  double motor_position_m = 0, motor_velocity_mps = 0;
  double load_position_m = 0, load_velocity_mps = 0;
};

/// Initial mechanical condition; the electrical state starts at rest (no current).
struct PlantInitialCondition {
  double motor_position_m = 0, motor_velocity_mps = 0;
  double load_position_m = 0, load_velocity_mps = 0;
};

/// Inputs held over one step() call.
struct PlantInput {
  double u_d_v = 0;         ///< requested d-axis voltage (limited by the inverter)
  double u_q_v = 0;         ///< requested q-axis voltage
  double load_force_n = 0;  ///< external force on the load (a disturbance test input)
};

/// What a drive measures after a step: phase currents (as d-q) and the encoder.
struct PlantMeasurement {
  double i_d_a = 0;
  double i_q_a = 0;
  double encoder_position_m = 0;  ///< quantised (and noisy if configured)
};

/// Everything about the plant that no controller may read: for evaluation and tests.
struct PlantTruth {
  PlantState state;
  double i_d_a = 0, i_q_a = 0, i_dd_a = 0, i_qq_a = 0;  ///< armature and damper currents
  double thrust_n = 0;                                  ///< F_dx (9)
  double ripple_n = 0;                                  ///< F_ripple (10)
  double friction_n = 0;                                ///< F_friction (11), opposing motion
  double spring_force_n = 0;                            ///< F_s = k (x_m - x_l) + b (v_m - v_l), the Kalman state
  double encoder_head_position_m = 0;                   ///< x_e: x_m on a rigid mount
  double motor_accel_mps2 = 0;
  double load_accel_mps2 = 0;
};

/// The plant's state left the numbers: an entry became non-finite or beyond any
/// physical motor (|position| > 1e6 m, |velocity| > 1e4 m/s, |flux| > 1e6 Wb), which
/// only a parameter set outside what the integrator resolves can cause. The plant then
/// keeps the last good state and integrates no more (reset() clears it).
struct PlantDivergence {
  bool diverged = false;
  const char* state = "";  ///< name of the first bad PlantState entry, e.g. "load_position_m"
  double value = 0;        ///< its value after the step that diverged
  std::uint64_t step = 0;  ///< the step() call (counted from 1 since reset) that diverged
};

struct PlantCounters {
  std::uint64_t steps = 0;            ///< step() calls accepted
  std::uint64_t rejected_inputs = 0;  ///< step() calls with a non-finite input or dt
  std::uint64_t voltage_limited = 0;  ///< step() calls whose voltage the inverter limited
};

class Plant {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter.
  explicit Plant(const PlantParams& params);

  /// @throws std::invalid_argument for an initial condition that is not finite or beyond
  /// any motor (see PlantDivergence).
  void reset(const PlantInitialCondition& initial);

  /// Integrates over dt_s with the input held. A non-finite input or a dt_s
  /// that is not finite and positive is rejected: the last accepted input is
  /// applied instead (for a bad dt nothing moves) and the rejection counted.
  /// A step that diverges (see PlantDivergence) is undone and nothing moves after it.
  PlantMeasurement step(const PlantInput& input, double dt_s);

  const PlantDivergence& divergence() const { return divergence_; }

  /// Encoder and current reading of the present state (draws noise if configured).
  PlantMeasurement measure();

  PlantTruth truth() const;
  const PlantState& state() const { return state_; }
  const PlantParams& params() const { return params_; }
  const PlantCounters& counters() const { return counters_; }

 private:
  using StateVector = std::array<double, 8>;
  /// Right-hand side of the state equation plus the forces it computed on the
  /// way. Left uninitialised on purpose: rhs() writes every member, and zeroing
  /// four of them per RK4 step was a measurable share of the step's cost.
  struct Rhs {
    StateVector derivative;
    double i_d, i_q, i_dd, i_qq;
    double thrust, ripple, friction, spring;
  };
  /// Constants of the right-hand side, derived once from the parameters.
  struct Coefficients {
    double psi_pm, thrust_factor, electrical_rad_per_m;
    double inv_ld[2][2];  // inverse of [L_ad L_md; L_md L_D]
    double inv_lq[2][2];  // inverse of [L_aq L_mq; L_mq L_Q]
    double r, r_dd, r_qq;
    double phi1, phi2, ripple_gain, a_r1, a_r2;
    double coulomb, viscous, inv_friction_band;
    double k, b, inv_motor_mass, inv_load_mass;
  };
  /// sin/cos of the ripple's two spatial phases at the start of an RK4 step.
  struct RippleAnchor {
    double x0 = 0, s1 = 0, c1 = 0, s2 = 0, c2 = 0;
  };
  static StateVector to_vector(const PlantState& s);
  static PlantState from_vector(const StateVector& v);
  RippleAnchor anchor_at(double x) const;
  /// Moves ripple_phase_ to the present motor position: a rotation by the
  /// (small) distance travelled, recomputed exactly every kResyncSteps steps
  /// so the rounding of the recurrence cannot accumulate.
  void advance_ripple_phase();
  static constexpr int kResyncSteps = 256;
  static void rhs(const Coefficients& c, const StateVector& s, double u_d, double u_q, double load_force,
                  const RippleAnchor& anchor, Rhs& out);
  void integrate(double u_d, double u_q, double load_force, double h, int substeps);
  /// The read head on its mount one sub-step h on, driven by the motor's acceleration over it:
  /// its offset e = x_e - x_m obeys e'' = -w_e^2 e - 2 zeta_e w_e e' - x_m'' (semi-implicit Euler
  /// on e, so its error scales with the offset, not with the motor's travel; stable while
  /// w_e h < 2, within 1e-5 of the mode's frequency at w_e h < 0.1).
  void advance_encoder_head(double motor_accel_mps2, double h);

  PlantParams params_;
  Coefficients coeff_{};
  double voltage_limit_v_ = 0;
  double inv_encoder_resolution_ = 0;
  double inv_max_step_ = 0;
  PlantState state_;
  bool compliant_mount_ = false;
  double mount_stiffness_per_s2_ = 0, mount_damping_per_s_ = 0;  ///< w_e^2, 2 zeta_e w_e
  double head_offset_m_ = 0, head_offset_rate_mps_ = 0;          ///< e, e
  RippleAnchor ripple_phase_;
  int steps_since_resync_ = 0;
  // Adams-Bashforth history: f_{n-1}, and the input and step it was taken with.
  StateVector previous_derivative_{};
  bool history_valid_ = false;
  double history_step_s_ = 0;
  PlantInput history_input_;
  PlantInput last_input_;
  PlantCounters counters_;
  PlantDivergence divergence_;
  std::uint64_t steps_since_reset_ = 0;
  std::mt19937_64 noise_rng_;
  std::normal_distribution<double> noise_;
};

}  // namespace pmlsm
