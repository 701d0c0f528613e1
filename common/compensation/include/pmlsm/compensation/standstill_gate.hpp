// A gate in the compensation path for a load at rest. A compensator acts on the estimated load
// state; with the reference at rest and the motor held by its bearings' static friction, the
// encoder's counts are all the estimate has, and the compensator works on their quantisation: the
// motor slips and sticks a few counts at a time and the force chatters (25-40 N rms, most of it
// at 45-90 Hz). The gate closes the compensation path once the move is over and the motor is
// quiet, and opens it again as soon as the reference moves, the motor is pushed, or the
// compensator asks to damp a swing.
//
//   at rest:  |c(t_k)| <= rest_velocity_mps and |V_ref(t_k)| <= rest_velocity_mps, for settle_s
//             (load_settle_s while a load encoder is read: the load is judged itself)
//   quiet:    a window of window_s with rms(v_M) < quiet_velocity_mps (the measured velocity)
//   closed:   at rest and quiet; the scale ramps 1 -> 0 over fade_s
//   open:     the reference leaves rest (scale 1 at once: a move needs its compensation from the
//             first tick), or a window with rms(v_M) > wake_velocity_mps (a push on the load),
//             or, with wake_on_request, a window spent wholly closed in which the compensator's
//             request has an rms over wake_force_n (the scale ramps back to 1 over fade_s)
//
// With an encoder on the load the gate judges the load itself: the measured stretch
// s = x_M - x_L of the two counts (its offset does not matter: only its range over a window is
// read), swing = (max s - min s) / 2 over the window:
//   quiet:    also swing <= quiet_load_swing_m
//   open:     also a window with swing > wake_load_swing_m
// so it never closes over a swing the motor's encoder cannot see, and reopens for one that grows;
// the request while closed is then no witness (a compensator's offset at rest is no swing).
// An accelerometer on the load witnesses the stretch too: held by its bearings, the motor is a
// wall for a mass on a spring, m_L a_L = k (x_M - x_L), and the controller low-passes the reading
// at the load's mode (VelocityController); its noise leaves 1-3 um of stretch, so its swing is
// judged against quiet_accel_swing_m and wake_accel_swing_m instead.
// A window with a tick of no stretch (no encoder, a silent one, a reading the controller's
// LoadSensorMonitor refuses or a sensor it has failed: VelocityController's LoadWitness) is
// judged on the motor alone.
//
// With a load encoder the gate also pushes the motor after the load's swing (stretch_gain_n_per_m,
// 0: off): a motor its bearings hold creeps at most (the friction's sign is steep but continuous
// near rest, F_fr ~ c_h v_M), so the swing loses energy only through what the motor gives way,
// dE/dt = -k s v_M with s = x_L - x_M. The compensators' laws, sized for moves, push a creeping
// motor too little for that (a swing of 15-40 um on soft, sticky plants decays at 0.6 1/s); a push
// along the stretch, F = G (s - s_0) bounded by stretch_force_max_n, lets the motor follow the
// load and the swing decays at about (k + G) / (2 c_h). It acts only at rest, with the motor held
// (the last window's rms(v_M) under quiet_velocity_mps: a compensator that still moves the motor
// is left to damp the swing its way) and the load encoder read every tick of the last period of
// the load's mode (load_period_s, from the filter's model); s_0, the two encoders' offset, is the
// stretch's mean over that period (a whole period of the swing averages to its centre). The push
// is part of the compensation: the gate's scale fades it with the rest when the load is quiet.
// With an accelerometer it pushes after the stretch the reading gives at the load's mode
// (accel_stretch_gain_n_per_m, 0: off): F = -G s_w bounded by accel_stretch_force_max_n, under the
// same conditions (at rest, the motor held, a whole period of readings), where s_w is (m_L / k) a_L
// band-passed at w_L by the controller (the reading less a full notch there, its poles' damping
// accel_stretch_damping). The band-pass has no lag at the mode and no offset (a bias is the
// reading's mean: no centre to find), and its noise is a band of about pi zeta f_L; the low-passed
// witness the gate judges lags the swing by a quarter period at w_L, so a push after it would be
// in quadrature with the swing. The band must ring down faster than the swing the push damps
// (zeta w_L well over the swing's decay rate): a narrow one turns its phase over as the swing
// decays and the push feeds it.
//
// The last is for a heavy, soft load on sticky bearings: its swing (1.5 mm on 8 kg and 6,850 N/m
// pulls 10 N) may not move a motor held by 30 N, so the motor is quiet while the load still
// swings. Closed, the request is a witness: no force reaches the motor, and the estimate keeps
// the swing (kalman.standstill_hold), so the compensator asks to damp it. It is off in the shipped
// file: the request of a compensator at rest is also its offset and the estimate's friction
// ambiguity (15-25 N rms over a quiet load), so it reopens the gate over and over and the chatter
// is back (docs/results/2026-12-02-standstill-without-a-sensor.md).
// step() never throws and does not allocate; a non-finite input is counted and treated as motion
// (the gate opens).
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

/// Its values come from the system file (compensator.standstill; the period from timing), the
/// one place they live: none has a default of its own here.
struct StandstillGateParams {
  double control_period_s = 0;
  double rest_velocity_mps = 0;           ///< |c| and |V_ref| at or below this: the reference at rest, >= 0
  double settle_s = 0;                    ///< at rest this long before the gate may close, >= 0
  double load_settle_s = 0;               ///< ... when the last window read a load encoder every tick, >= 0
  double window_s = 0;                    ///< the quiet window, at least 2 periods
  double quiet_velocity_mps = 0;          ///< rms(v_M) of a window below this: quiet, > 0
  double wake_velocity_mps = 0;           ///< rms(v_M) of a window above this: pushed, > quiet_velocity_mps
  bool wake_on_request = false;           ///< the request while closed may reopen the gate (wake_force_n)
  double wake_force_n = 0;                ///< the request's rms over a window spent closed above this: a swing, > 0
  double fade_s = 0;                      ///< >= 0 (0: at once)
  double quiet_load_swing_m = 0;          ///< a load encoder's swing over a window at or below this: quiet, > 0
  double wake_load_swing_m = 0;           ///< ... above this: the load moves, open; > quiet_load_swing_m
  double quiet_accel_swing_m = 0;         ///< an accelerometer's witness of the swing at or below this: quiet, > 0
  double wake_accel_swing_m = 0;          ///< ... above this: open; > quiet_accel_swing_m
  double stretch_gain_n_per_m = 0;        ///< G of the push after a load encoder's stretch at rest, >= 0 (0: off)
  double stretch_force_max_n = 0;         ///< the push's bound, > 0
  double accel_stretch_gain_n_per_m = 0;  ///< G of the push after an accelerometer's stretch at the mode, >= 0 (0: off)
  double accel_stretch_damping = 0;       ///< the damping of that stretch's band-pass at w_L, > 0
  double accel_stretch_force_max_n = 0;   ///< that push's bound, > 0
  double load_period_s = 0;               ///< the load's mode's period (the filter's model): the stretch's centre, > 0
  /// @throws std::invalid_argument naming the parameter and its value.
  void validate() const;
  /// Its own entries under `at` ("compensator.standstill"); the period comes from the system.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    v.real(at + ".rest_velocity_mps", p.rest_velocity_mps, {0.0, 10.0, "0 (the command exactly zero) to 10 m/s"});
    v.real(at + ".settle_s", p.settle_s, {0.0, 3600.0, "0 (at once) to an hour at rest"});
    v.real(at + ".load_settle_s", p.load_settle_s,
           {0.0, 3600.0, "0 (at once) to an hour at rest, with a load encoder's witness"});
    v.real(at + ".window_s", p.window_s, {1e-3, 100.0, "1 ms to 100 s of quiet window"});
    v.real(at + ".quiet_velocity_mps", p.quiet_velocity_mps,
           {1e-6, 10.0, "1 um/s to 10 m/s of motor velocity (rms over the window)"});
    v.real(at + ".wake_velocity_mps", p.wake_velocity_mps,
           {1e-6, 10.0, "1 um/s to 10 m/s of motor velocity (rms over the window)"});
    v.real(at + ".fade_s", p.fade_s, {0.0, 60.0, "0 (at once) to a minute"});
    v.flag(at + ".wake_on_request", p.wake_on_request);
    v.real(at + ".wake_force_n", p.wake_force_n,
           {1e-3, 1e5, "1 mN to 100 kN of requested compensation (rms over a window spent closed)"});
    v.real(at + ".quiet_load_swing_m", p.quiet_load_swing_m,
           {1e-9, 1e-2, "1 nm to 10 mm of the load's swing against the motor (half the range over a window)"});
    v.real(at + ".wake_load_swing_m", p.wake_load_swing_m,
           {1e-9, 1e-2, "1 nm to 10 mm of the load's swing against the motor (half the range over a window)"});
    v.real(at + ".quiet_accel_swing_m", p.quiet_accel_swing_m,
           {1e-9, 1e-2, "1 nm to 10 mm of the swing an accelerometer witnesses (half the range over a window)"});
    v.real(at + ".wake_accel_swing_m", p.wake_accel_swing_m,
           {1e-9, 1e-2, "1 nm to 10 mm of the swing an accelerometer witnesses (half the range over a window)"});
    v.real(at + ".stretch_gain_n_per_m", p.stretch_gain_n_per_m,
           {0.0, 1e9, "0 (no push) to 1 kN per um of the load encoder's stretch"});
    v.real(at + ".stretch_force_max_n", p.stretch_force_max_n, {1e-3, 1e5, "1 mN to 100 kN of push"});
    v.real(at + ".accel_stretch_gain_n_per_m", p.accel_stretch_gain_n_per_m,
           {0.0, 1e9, "0 (no push) to 1 kN per um of the accelerometer's stretch at the load's mode"});
    v.real(at + ".accel_stretch_damping", p.accel_stretch_damping,
           {1e-2, 2.0, "0.01 (a narrow band about w_L) to 2 (a wide one)"});
    v.real(at + ".accel_stretch_force_max_n", p.accel_stretch_force_max_n, {1e-3, 1e5, "1 mN to 100 kN of push"});
  }
  /// The longest load_period_s: the centre's ring holds this many seconds of stretch.
  static constexpr double kMaxLoadPeriodS = 2.0;
};

struct StandstillGateInput {
  double command_mps = 0;             ///< c(t_k), the command into the reference model
  double reference_velocity_mps = 0;  ///< V_ref(t_k)
  double motor_velocity_mps = 0;      ///< measured v_M(t_k)
  double compensation_force_n = 0;    ///< the compensator's request, before any scale
  /// The measured stretch x_M - x_L of a load encoder against the motor's (any offset; NaN: none).
  double load_stretch_m = std::numeric_limits<double>::quiet_NaN();
  /// The stretch is an accelerometer's witness, (m_L / k) a_L low-passed at the load's mode: judged
  /// against quiet_accel_swing_m and wake_accel_swing_m (its noise is micrometres of stretch).
  bool stretch_from_accelerometer = false;
  /// An accelerometer's (m_L / k) a_L band-passed at the load's mode: x_M - x_L there with no lag
  /// and no offset (NaN: none), what the push after an accelerometer's stretch reads.
  double load_stretch_at_mode_m = std::numeric_limits<double>::quiet_NaN();
};

struct StandstillGateOutput {
  double scale = 1.0;   ///< multiply the compensation force by this
  bool closed = false;  ///< closing or closed (the scale heads for 0)
  /// The push after the stretch, G (x_L - x_M - s_0) of a load encoder's or -G s_w of an
  /// accelerometer's, bounded (0 when it does not act): add it to the compensation's request,
  /// before the scale.
  double stretch_force_n = 0;
};

struct StandstillGateCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;
  std::uint64_t closings = 0;
  std::uint64_t openings = 0;
  double last_window_rms_mps = 0;        ///< rms(v_M) of the last full window
  double last_closed_force_n = 0;        ///< the request's rms over the last window spent closed
  double last_load_swing_m = 0;          ///< the load's swing of the last full window with a stretch every tick
  std::uint64_t stretch_push_steps = 0;  ///< ticks the push after the stretch acted
};

class StandstillGate {
 public:
  /// @throws std::invalid_argument naming the invalid parameter.
  explicit StandstillGate(const StandstillGateParams& params);

  /// One control period.
  StandstillGateOutput step(const StandstillGateInput& in) noexcept;

  const StandstillGateOutput& output() const noexcept { return out_; }
  const StandstillGateCounters& counters() const noexcept { return counters_; }
  const StandstillGateParams& params() const noexcept { return params_; }

 private:
  void open(bool at_once) noexcept;
  /// The push after the stretch this tick (the centre's ring taken one reading on).
  double stretch_push(const StandstillGateInput& in) noexcept;
  void forget_stretch_centre() noexcept;
  StandstillGateParams params_;
  std::uint64_t settle_steps_;
  std::uint64_t load_settle_steps_;
  std::uint32_t window_steps_;
  double fade_per_step_;
  std::uint64_t at_rest_steps_ = 0;
  std::uint32_t in_window_ = 0;
  double sum_v2_ = 0, sum_f2_ = 0;
  std::uint32_t closed_in_window_ = 0;   ///< ticks of the window with the scale at 0
  std::uint32_t stretch_in_window_ = 0;  ///< ticks of the window with a finite stretch
  double stretch_min_m_ = 0, stretch_max_m_ = 0;
  /// The last load period's stretch (sized at construction); an accelerometer's push counts its fill only.
  std::vector<double> centre_ring_;
  std::size_t centre_next_ = 0, centre_filled_ = 0;
  double centre_sum_m_ = 0;
  bool motor_held_ = false;  ///< the last full window at rest had rms(v_M) under quiet_velocity_mps
  StandstillGateOutput out_;
  StandstillGateCounters counters_;
};

}  // namespace pmlsm
