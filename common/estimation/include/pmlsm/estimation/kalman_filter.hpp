// Kalman filter of section 3.5 on the two-mass model (34), b neglected:
//   x = [v_M, v_L, F_s],  u = F_T (motor thrust),  y = v_M,
//   A = [[0, 0, -1/m_M], [0, 0, 1/m_L], [k, -k, 0]],  B = [1/m_M, 0, 0]^T,  C = [1, 0, 0].
// F_s = k (x_M - x_L) is the spring force; (36) gives the load acceleration
// a_L = F_s / m_L. The model is discretised exactly (ZOH) at the filter's
// period (Phi, Gamma of (26)); Q (35) and R enter (29)-(30) as the discrete
// covariances. Each step runs the time update (28)-(29) with the input of the
// period just ended, then the measurement update (30)-(32) with y_k.
//
// The model input. The paper (and the default here) uses the force command
// alone, u_{k-1} = F_{k-1}, and lets friction and ripple count as process
// noise. Optionally the filter adds the modelled disturbance (12) of the
// period [t_{k-1}, t_k], as a drive that has identified its bearing friction
// and its force ripple would:
//   u_{k-1} = F_{k-1} + F_friction(v_k) + F_ripple(xbar_k)
//   F_friction(v) = -(F_c s(v) + F_v v)                                   (11)
//   s(v) = w (3 - w^2) / 2,  w = clamp(v / v_s, -1, 1)
//   F_ripple(x) = K_s A_r1 sin(phi_1 x) [A_r1 + A_r2 sin(phi_2 x)]         (10)
// with v_k = y_k = (x_k - x_{k-1}) / T, the encoder velocity: the mean motor
// velocity over exactly the period the input acts on, and xbar_k = (x_{k-1} +
// x_k) / 2, the midpoint of the encoder positions. s(v) is sign(v) outside
// |v| < v_s and a C1 cubic inside, so the 1 mm/s steps of a 1 um encoder at
// 1 ms do not flip the friction between +-F_c when the motor is at rest. The
// filter stays linear in its state: the disturbance is a known input computed
// from measurements, not from the estimate (except that a rejected y_k falls
// back on the prior v_M estimate for the friction).
// Why: with the paper's Q the v_M innovation is charged to v_M's process
// noise, so v_L and F_s are corrected only weakly and an unknown start (the
// free-vibration test, F_s = -274 N) is never found. A Q that trusts v_M's
// model (small Q_00) makes the innovation correct F_s, but then every
// unmodelled force on the motor (20 N of friction, 13 N of ripple at 13 Hz,
// close to the 10.2 Hz load mode) is read as spring force; with the
// disturbance in the input that error is gone.
//
// Thrust lag (optional). The drive's current loop makes the thrust follow the command F_{k-1} as
// a first-order lag of time constant tau_i (1 / w_c of the current loop), not as a step:
//   F(t) = F_{k-1} + (Fhat_{k-1} - F_{k-1}) e^{-(t - t_{k-1}) / tau_i}   over [t_{k-1}, t_k],
// Fhat_{k-1} the thrust at t_{k-1}. The filter then takes the period's mean thrust for F_{k-1},
//   Fbar_k = F_{k-1} + (Fhat_{k-1} - F_{k-1}) (tau_i / T) (1 - e^{-T / tau_i}),
//   Fhat_k = F_{k-1} + (Fhat_{k-1} - F_{k-1}) e^{-T / tau_i}
// (the mean, not F(t) weighted by the model's response within the period: tau_i is a third of T
// and the load mode a hundred times slower). Why: with tau_i = 0.33 ms the thrust of a period falls
// 32 % short of a step of the command (190 N of a 600 N step); the filter (small Q_00) put the
// difference on the spring force, so a compensator's own steps came back to it through the
// estimate: on stiff 5 kg plants the RNN chattered at 165 Hz until the guard tripped.
// tau_i = 0: the paper's filter, thrust = command.
//
// Standstill hold (optional). Near rest the bearing friction is not the model's F_c s(v): a stuck
// or creeping motor carries any friction in [-F_c, F_c], whatever the force on it. A motor at
// rest with the load still swinging then reads, to the filter, as a motor that no force moves:
// the innovation explains it away as F_s = 0, and within a few tens of milliseconds the estimate
// has lost a swing the encoder cannot see (on an 8 kg, 6,850 N/m load with 30 N of friction a
// 2 mm, 13 N swing outlives the move while F_s-hat reads 0; the compensation, acting on the
// estimate, never breaks the motor free to damp it). With the hold, while
//   |y_k| <= max_velocity_mps  and  A = sqrt(F_s^2 + k m_L (v_L - v_M)^2) >= min_ring_share F_c
// (A: the load's swing against the motor, in spring-force units, from the estimate before the
// step; F_c: friction_input's), the measurement sets v_M = y_k alone and v_L, F_s run on the
// model (no correction: y_k says nothing about them while friction is unknown). A small swing
// (below the share) is left to the normal update: a compensator's jitter at rest keeps the motor
// moving enough for it to be seen and damped, and the nominal runs stay as they were.
//
// A sensor on the load (optional; sensors.load). After the motor's update, one more scalar update
// y = h x + e with the load's own reading, whatever the standstill hold did (the load's sensor sees
// the swing the motor's cannot):
//   encoder        y_k = (x_L,k - x_L,k-1) / T, h = [0 1 0]        (the load's velocity, as y_k
//                  is the motor's; none at the first reading)
//   accelerometer  y_k = a_L,k,              h = [0 0 1/m_L]       ((36): a_L = F_s / m_L)
// with the variance of the sensor's declaration (SystemParams::kalman_params): an encoder's two
// counts, 2 (q^2 / 12 + sigma^2) / T^2; an accelerometer's white noise N^2 / (2 T) through its low
// pass of gain g, times g / (2 - g). The low pass's lag and the latency are not modelled. The
// accelerometer's bias is taken out of y before the update: the reading integrates to the load's
// velocity, so over the readings since the first at t_0
//   b_k = (T sum_{j<k} y_j - (v_L,k - v_L,0)) / (tau_b + t_k - t_0)
// (the filter's v_L before this update; a prior of 0 worth tau_b = kalman.accelerometer_bias_prior_s
// of readings, so the first ones hardly count; a reading not believed counts as the filter's own
// a_L + b, so the sum still spans the change of v_L). A MEMS part's 20 mg doubles acceleration
// feedback's pulse cost when left in.
// An encoder's count also measures the spring: with the motor's encoder, F_s = k (x_M - x_L)
// up to the offset b between the two scales (their zeros, the spring's free length), so a second
// scalar update takes
//   z_k = k (x_M,k - x_L,k) - b_k,  h = [0 0 1],  r = k^2 (q_M^2 / 12 + q_L^2 / 12 + sigma^2) + var(b_k).
// b comes from the load's momentum: the spring is the only force on the load (b neglected in
// (34)), so its integral since the first reading at t_0 is m_L (v_L(t) - v_L(t_0)), and
//   b_k = (int_{t_0}^{t_k} k (x_M - x_L) dt - m_L (v_L,k - v_L,0)) / (t_k - t_0)
// (the trapezoid of the readings; the filter's v_L before this update and at the first reading;
// var(b_k) = m_L^2 (P_11,k + P_11,0) / (t_k - t_0)^2, so the first readings hardly count). Why: the
// velocity from two counts steps by q / T (1 mm/s for 1 um at 1 ms), larger than a 5 um swing's
// 0.3 mm/s at the load's 9 Hz, and the spring force integrated from it is lost at rest; the count
// itself resolves that swing to a fifth.
// A reading LoadSensorMonitor judges bad (silent, saturated, jumping) is not used; a sensor that
// failed (bad over its window, or stuck) is not used again: the filter is back on the motor's side.
// Without a sensor the filter is the one above, step for step.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <limits>

#include "pmlsm/estimation/load_sensor_monitor.hpp"
#include "pmlsm/plant/load_sensor.hpp"
#include "pmlsm/plant/plant.hpp"
#include "pmlsm/util/two_mass_model.hpp"

namespace pmlsm {

/// The bearing friction (11) the filter adds to its input: the plant's model with the
/// filter's own constants (identified on a rig; v_eps wider than the plant's, see the config).
struct KalmanFrictionInput {
  bool enabled = false;
  FrictionParams model;
  double force_n(double motor_velocity_mps) const { return friction_force_n(model, motor_velocity_mps); }
};

/// The force ripple (10) the filter adds to its input (identified on a rig against the
/// encoder position): the plant's model with the filter's own constants.
struct KalmanRippleInput {
  bool enabled = false;
  RippleParams model;
  double force_n(double motor_position_m) const { return ripple_force_n(model, motor_position_m); }
};

/// The standstill hold (see the header comment). It acts only with friction_input enabled: it
/// completes that friction model near rest, and its F_c scales the swing that is held (the
/// paper's filter, friction as process noise, has neither).
struct KalmanStandstillHold {
  bool enabled = false;
  double max_velocity_mps = 0;  ///< |y_k| at or below this: the motor may be stuck, > 0
  double min_ring_share = 0;    ///< held only while A >= this x F_c, >= 0
};

/// The load's sensor as the filter takes it (see the header): derived from the sensor's declaration
/// (SystemParams::kalman_params), not a file entry of the filter's own.
struct KalmanLoadMeasurement {
  LoadSensorKind kind = LoadSensorKind::kNone;
  double variance = 0;  ///< of y: (m/s)^2 for an encoder, (m/s^2)^2 for an accelerometer; > 0 with a sensor
  /// An encoder's: the variance of x_M - x_L from the two counts, q_M^2 / 12 + q_L^2 / 12 + sigma^2 [m^2].
  double stretch_variance_m2 = 0;
  LoadSensorMonitorParams monitor;  ///< which readings are believed
  /// The variances of a sensor declared by `sensor`, read every `period_s` beside a motor encoder
  /// of `motor_resolution_m`.
  static KalmanLoadMeasurement of(const LoadSensorParams& sensor, double period_s, double motor_resolution_m);
};

struct KalmanParams {
  TwoMassModel model;  ///< the mechanics (34) the filter assumes: its own, not the plant's
  double period_s = 0;
  Eigen::Vector3d process_noise_diag = Eigen::Vector3d::Zero();       ///< Q diagonal (35)
  double measurement_noise = 0;                                       ///< R
  Eigen::Vector3d initial_covariance_diag = Eigen::Vector3d::Zero();  ///< P_0 diagonal
  KalmanFrictionInput friction_input;                                 ///< off: the paper's filter
  KalmanRippleInput ripple_input;                                     ///< off: the paper's filter
  KalmanStandstillHold standstill_hold;                               ///< off: the paper's filter
  double thrust_lag_s = 0;  ///< tau_i, the current loop's first-order lag; 0: thrust = command (the paper), >= 0
  KalmanLoadMeasurement load_measurement;  ///< none: the filter without a load sensor
  /// tau_b: how many seconds of an accelerometer's readings its prior bias of 0 is worth (header).
  double accelerometer_bias_prior_s = 0;
  void validate() const;
  /// Its own entries under `at` ("kalman"): the model of the mechanics with the plant's ranges,
  /// the noises and the optional inputs; the period comes from the system. Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    TwoMassModel::declare(at + ".model", p.model, v);
    const Plausible noise{0.0, 1e12, "a variance: 0 to 1e12 (a 1 MN or 1 Mm/s standard deviation)"};
    v.vector3(at + ".process_noise_diag", p.process_noise_diag, noise);
    v.real(at + ".measurement_noise", p.measurement_noise,
           {1e-15, 1e6, "a variance: positive (the filter divides by it), up to 1e6"});
    v.real(at + ".thrust_lag_s", p.thrust_lag_s, {0.0, 1.0, "0 (thrust = command) to 1 s"});
    v.real(at + ".accelerometer_bias_prior_s", p.accelerometer_bias_prior_s,
           {1e-3, 1e6, "1 ms (the readings decide at once) to 1e6 s (the bias taken as 0)"});
    v.vector3(at + ".initial_covariance_diag", p.initial_covariance_diag, noise);
    v.flag(at + ".friction_input.enabled", p.friction_input.enabled);
    FrictionParams::declare(at + ".friction_input", p.friction_input.model, v);
    v.flag(at + ".ripple_input.enabled", p.ripple_input.enabled);
    RippleParams::declare(at + ".ripple_input", p.ripple_input.model, v);
    v.flag(at + ".standstill_hold.enabled", p.standstill_hold.enabled);
    v.real(at + ".standstill_hold.max_velocity_mps", p.standstill_hold.max_velocity_mps,
           {1e-6, 1.0, "1 um/s to 1 m/s: a few encoder counts a period"});
    v.real(at + ".standstill_hold.min_ring_share", p.standstill_hold.min_ring_share,
           {0.0, 100.0, "0 (every swing at rest) to 100 times the bearing friction"});
  }
};

struct KalmanInput {
  double motor_velocity_measured_mps = 0;  ///< y_k = (x_k - x_{k-1}) / T
  double thrust_previous_n = 0;            ///< F_{k-1}: the force commanded over the last period
  double motor_position_m = 0;             ///< x_k, the encoder position (used by the ripple input only)
  /// The load's sensor at tick k (NaN: not measured): its encoder's position, its acceleration.
  double load_position_m = std::numeric_limits<double>::quiet_NaN();
  double load_accel_mps2 = std::numeric_limits<double>::quiet_NaN();
  bool load_sensor_saturated = false;  ///< the accelerometer at its rail
};

struct KalmanEstimate {
  double motor_velocity_mps = 0;
  double load_velocity_mps = 0;
  double spring_force_n = 0;
  double load_accel_mps2 = 0;  ///< (36)
  double innovation_mps = 0;   ///< y_k - C x_k^-
  double input_force_n = 0;    ///< u_{k-1} used in the time update (force + modelled disturbance)
  Eigen::Vector3d covariance_diag = Eigen::Vector3d::Zero();
  bool measurement_used = false;
  bool standstill_held = false;        ///< the standstill hold replaced the measurement update
  bool load_measurement_used = false;  ///< the load's sensor corrected the estimate
  double load_innovation = 0;          ///< y - h x^- of the load's update (its unit: m/s or m/s^2)
  double stretch_innovation_n = 0;     ///< z - F_s^- of an encoder's spring update (0 without one)
  double stretch_offset_n = 0;         ///< b_k, the two scales' offset in spring-force units (encoder)
  double accelerometer_bias_mps2 = 0;  ///< the accelerometer's bias as the filter takes it out
  LoadSensorFault load_sensor_problem = LoadSensorFault::kNone;  ///< why this tick's reading was not used
  bool load_sensor_failed = false;                               ///< the sensor failed (latched)
};

/// What the load's sensor did for one estimate (EstimatedState.load_sensor_use).
enum class LoadSensorUse : std::uint8_t {
  kNotUsed = 0,  ///< no sensor declared, or no reading to use yet (an encoder's first)
  kUsed = 1,     ///< its reading corrected the estimate
  kRefused = 2,  ///< its reading was judged bad (load_sensor_problem says why)
  kFailed = 3,   ///< the sensor failed (latched): the estimate is the motor's side alone
};
LoadSensorUse load_sensor_use(const KalmanEstimate& estimate);

struct KalmanCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_measurements = 0;  ///< non-finite y: time update only
  std::uint64_t rejected_inputs =
      0;  ///< non-finite u (or position, with the ripple input): the last finite one is used
  std::uint64_t standstill_holds = 0;  ///< steps the standstill hold kept v_L and F_s on the model
  std::uint64_t load_updates = 0;      ///< steps the load's sensor corrected
};

class KalmanFilter {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter.
  explicit KalmanFilter(const KalmanParams& params);
  void reset(const Eigen::Vector3d& initial_state = Eigen::Vector3d::Zero());
  /// No allocation.
  KalmanEstimate step(const KalmanInput& input);

  const Eigen::Matrix3d& phi() const { return phi_; }
  const Eigen::Vector3d& gamma() const { return gamma_; }
  const Eigen::Vector3d& state() const { return x_; }
  const Eigen::Matrix3d& covariance() const { return p_; }
  const KalmanCounters& counters() const { return counters_; }
  /// The load sensor's judge: its fault, when and how many readings it refused.
  const LoadSensorMonitor& load_monitor() const { return load_monitor_; }
  /// Continuous-time model (34), for tests and the estimator's documentation.
  static Eigen::Matrix3d continuous_a(const KalmanParams& params);
  static Eigen::Vector3d continuous_b(const KalmanParams& params);

 private:
  /// F_friction + F_ripple of the period ending at y_k, x_k (0 when both inputs are off).
  double modelled_disturbance_n(double motor_velocity_measured_mps, double motor_position_m);
  /// The measurement update with y = h x + e, e of variance r (Joseph form); the innovation.
  double scalar_update(const Eigen::RowVector3d& h, double y, double r);
  /// The load sensor's update of the step (see the header) into `out`.
  void load_update(const KalmanInput& in, KalmanEstimate& out);

  KalmanParams params_;
  Eigen::Matrix3d phi_;
  Eigen::Vector3d gamma_;
  Eigen::Matrix3d q_;
  double load_impedance_n_s_per_m_ = 0;  ///< sqrt(k m_L): the standstill hold's v_L - v_M in force units
  LoadSensorMonitor load_monitor_;
  double last_load_position_m_ = 0;  ///< the load encoder's last reading
  bool have_load_position_ = false;
  /// The offset b (see the header): the readings' trapezoid since the first, and the first's v_L.
  struct StretchOffset {
    bool started = false;
    std::uint64_t periods = 0;  ///< (t_k - t_0) / T
    double first_n = 0, last_n = 0, sum_n = 0;
    double first_load_velocity_mps = 0, first_variance = 0;
  } stretch_;
  /// The accelerometer's bias (see the header): its readings' sum since the first (a reading not
  /// believed counted as the filter's a_L plus the bias), the first's v_L, the bias now.
  struct AccelerometerBias {
    bool started = false;
    std::uint64_t periods = 0;
    double sum_mps = 0, first_load_velocity_mps = 0, bias_mps2 = 0;
  } accel_bias_;
  /// The encoder's spring update of the step (see the header) into `out`.
  void stretch_update(double load_position_m, double motor_position_m, KalmanEstimate& out);
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d p_;
  double last_input_n_ = 0;
  double lag_decay_ = 0;        ///< e^{-T / tau_i}
  double lag_over_period_ = 0;  ///< tau_i / T
  double lag_rise_ = 0;         ///< 1 - e^{-T / tau_i}
  double thrust_n_ = 0;         ///< the lag model's thrust at t_{k-1}
  double last_position_m_ = 0;  ///< x_{k-1}, for the ripple input's midpoint
  bool have_last_position_ = false;
  KalmanCounters counters_;
};

}  // namespace pmlsm
