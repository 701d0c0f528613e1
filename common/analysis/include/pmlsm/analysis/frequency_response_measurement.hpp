// Frequency-response measurement on a drive, the tick-by-tick part: a velocity PI holds the motor
// at a constant velocity while a multisine is added to its force (under the loop, inside the
// force limit), and the excitation, the applied force and the measured velocity are recorded for
// estimate_frequency_response. It sees only what a drive reports (drive::Measurement and its
// power state), so the same measurement runs on the simulated drive, the CANopen rig or a real
// drive behind the drive seam.
//
// Why at a constant velocity: at rest the bearings stick (Coulomb friction switches sign with the
// velocity: no linear response below the breakaway force). Moving one way, the friction is a
// constant force and the plant is linear around the motion, as the two-mass fit assumes.
// Why that velocity: the motor's force ripple (one and two cycles per pole pitch tau) is then a
// disturbance at f_r = v0 / tau and 2 f_r, and modulates the response by f_r. With
// f_r = (m + 1/4) df its phase turns by a quarter and a half turn from one excitation period to
// the next, so it cancels from the average of every 4 measured periods; the offset velocity is
// the configured one moved to the nearest such velocity.
//
// Phases, each a whole number of ticks:
//   ramp     velocity command 0 -> v0 over ramp_s, no excitation
//   excite   settle_periods + measure_periods periods of the multisine at v0
//   stop     v0 -> 0 over ramp_s, no excitation
//   done     zero velocity command (the loop holds the motor)
// A breach of a limit (travel from the start, velocity, the force limit, a non-finite reading) or
// a drive that leaves operation enabled ends the measurement at once: zero force from that tick,
// and the reason kept. Nothing is thrown and nothing is allocated per tick.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "pmlsm/control/velocity_pi.hpp"
#include "pmlsm/drive/drive.hpp"
#include "pmlsm/analysis/frequency_response.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

/// The measurement's own entries: the parameter section "commissioning.frequency_response"
/// (analysis_params.hpp). The defaults are chosen for the paper's plant and its family
/// (configs/sweeps/plant_family.yaml): 2 kg to 8 kg of load, 6850 to 27,400 N/m of spring.
struct FrequencyResponseMeasurementParams {
  /// 22 % of the 675 N force limit: about 11 N per line on 153 lines, so every line stands clear
  /// of the 13 N force ripple after averaging.
  double amplitude_n = 150.0;  ///< peak of the multisine [N]
  /// Below the family's lowest anti-resonance (4.7 Hz at 8 kg, 6850 N/m), above the ripple's
  /// 1.3 Hz at the offset velocity.
  double min_frequency_hz = 2.0;
  /// Past the velocity loop's phase crossover (about 170 Hz with the shipped gains), where its gain
  /// margin is read; below the 500 Hz Nyquist frequency.
  double max_frequency_hz = 450.0;
  /// Line spacing df, a period of 1 / df: four lines between the family's closest modes (4.7 and
  /// 5.5 Hz), a 4 s period.
  double resolution_hz = 0.25;
  /// Every line up to it (the two-mass fit's band: twice the family's highest resonance, 19.5 Hz
  /// at 2 kg, 27,400 N/m), log above.
  double dense_max_frequency_hz = 40.0;
  /// Above dense_max_frequency_hz, for the loop's crossovers: a line every 6 % (42 lines to 450 Hz).
  double lines_per_decade = 40.0;
  /// The velocity measured at: the slowest the excitation never reverses (its swing stays above
  /// 2 mm/s on the family), with the ripple's lines below the band.
  double offset_velocity_mps = 0.02;
  /// Periods run before the ones averaged: 8 s for the loop's mode (zeta 0.012 at 9.3 Hz decays to
  /// 0.3 %) and the velocity trim.
  std::size_t settle_periods = 2;
  /// Periods averaged, a multiple of 4: the fewest that cancel the ripple; modes within 0.3 % on
  /// the family's corners.
  std::size_t measure_periods = 4;
  double ramp_s = 0.5;  ///< to and from the offset velocity: 0.04 m/s^2, far from the force limit
  /// Stroke either side of the start the measurement may use: half the paper's 1000 mm (Table 3);
  /// the run needs 0.48 m.
  double max_travel_m = 0.5;
  /// |v| beyond it ends the measurement: five times the offset velocity; the excitation's swing
  /// stays under 0.04 m/s on the family.
  double max_velocity_mps = 0.1;
  /// A line below it is not fitted: one whose velocity is 90 % explained by the excitation (0.975
  /// or more on the family).
  double min_coherence = 0.9;
  /// More lines than this share below min_coherence: the response is refused (nothing fitted or
  /// written).
  double max_low_coherence_share = 0.1;
  // From the system, not the file:
  double period_s = 0;      ///< the control period
  double pole_pitch_m = 0;  ///< tau: the ripple's period in space
  /// What its entries can be checked for without the system: the ranges, the band's order, a
  /// moving offset velocity, whole sets of 4 periods (reading the system file runs it).
  /// @throws std::invalid_argument naming the first invalid value.
  void validate_entries() const;
  /// validate_entries() and, with the system's period and pole pitch, the band below the Nyquist
  /// frequency and a ramp of at least a tick (a measurement made from the system runs it).
  /// @throws std::invalid_argument naming the first invalid value.
  void validate() const;
  /// Its own entries under `at` ("commissioning.frequency_response"); the period and the pole
  /// pitch come from the system. Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& fr, Visitor& v) {
    const std::string a = at + ".";
    v.real(a + "amplitude_n", fr.amplitude_n, {1e-3, 1e5, "1 mN to 100 kN, the range of the force limit"});
    v.real(a + "min_frequency_hz", fr.min_frequency_hz, {0.01, 1e4, "0.01 Hz to 10 kHz"});
    v.real(a + "max_frequency_hz", fr.max_frequency_hz, {0.01, 1e4, "0.01 Hz to 10 kHz, below the Nyquist frequency"});
    v.real(a + "resolution_hz", fr.resolution_hz, {0.01, 100.0, "a period of 10 ms to 100 s"});
    v.real(a + "dense_max_frequency_hz", fr.dense_max_frequency_hz, {0.0, 1e4, "0 (every line) to 10 kHz"});
    v.real(a + "lines_per_decade", fr.lines_per_decade, {0.0, 1000.0, "0 (unused) to 1000"});
    v.real(a + "offset_velocity_mps", fr.offset_velocity_mps, {-10.0, 10.0, "either direction, up to 10 m/s"});
    v.integer(a + "settle_periods", fr.settle_periods, {1.0, 100.0, "1 to 100 periods"});
    v.integer(a + "measure_periods", fr.measure_periods, {4.0, 400.0, "4 to 400 periods, a multiple of 4"});
    v.real(a + "ramp_s", fr.ramp_s, {1e-3, 60.0, "a tick to a minute"});
    v.real(a + "max_travel_m", fr.max_travel_m, {1e-6, 100.0, "1 um to 100 m of stroke"});
    v.real(a + "max_velocity_mps", fr.max_velocity_mps, {1e-6, 100.0, "1 um/s to 100 m/s"});
    v.real(a + "min_coherence", fr.min_coherence, {0.0, 1.0, "a coherence: 0 to 1"});
    v.real(a + "max_low_coherence_share", fr.max_low_coherence_share, {0.0, 1.0, "a share of the lines: 0 to 1"});
  }
};

enum class MeasurementPhase : std::uint8_t { kRamp, kExcite, kStop, kDone, kAborted };
const char* measurement_phase_name(MeasurementPhase phase);

class FrequencyResponseMeasurement {
 public:
  /// Checks the run against its limits before it starts: the travel of the whole run at the
  /// offset velocity within max_travel_m, the excitation's peak within the force limit, the
  /// offset velocity within max_velocity_mps.
  /// @throws std::invalid_argument naming the limit the run would break, with both values.
  FrequencyResponseMeasurement(const FrequencyResponseMeasurementParams& params, const VelocityPiParams& velocity_pi);

  /// One tick: the drive's reading at the tick's start and whether it is in operation enabled;
  /// returns the force to apply over the tick. Allocation-free, never throws.
  double step(const drive::Measurement& measurement, bool operation_enabled);

  MeasurementPhase phase() const { return phase_; }
  bool finished() const { return phase_ == MeasurementPhase::kDone || phase_ == MeasurementPhase::kAborted; }
  /// Why the measurement was aborted ("" when it was not).
  const std::string& abort_reason() const { return abort_reason_; }
  std::uint64_t ticks() const { return tick_; }
  /// Ticks of the whole run (ramp, excitation, stop).
  std::uint64_t total_ticks() const { return stop_end_tick_; }
  double offset_velocity_mps() const { return offset_velocity_mps_; }
  const Multisine& excitation() const { return excitation_; }
  const FrequencyResponseMeasurementParams& params() const { return params_; }

  /// Excitation ticks whose force the drive reported held differently from the one sent (it
  /// came late; the drive held the one before): recorded as the drive held them.
  std::uint64_t late_ticks() const { return late_ticks_; }
  /// The excitation R, the applied force F (as the drive reports it held, else as sent) and the
  /// velocity V measured over the tick F was held, one sample per excitation tick, from the
  /// excitation's tick 0.
  const std::vector<double>& excitation_n() const { return excitation_n_; }
  const std::vector<double>& force_n() const { return force_n_; }
  const std::vector<double>& velocity_mps() const { return velocity_mps_; }
  /// With a load encoder (a finite load_position_m in every reading of the excitation): the load's
  /// velocity over the same ticks, (x_L,k - x_L,k-1) / T; empty without one, or when its reading
  /// went missing (load_lost()).
  const std::vector<double>& load_velocity_mps() const { return load_velocity_mps_; }
  bool has_load_sensor() const {
    return !load_lost_ && load_velocity_mps_.size() == velocity_mps_.size() && !load_velocity_mps_.empty();
  }
  bool load_lost() const { return load_lost_; }
  /// The estimates per line after a completed measurement.
  /// @throws std::invalid_argument when the measurement did not complete.
  std::vector<FrequencyPoint> response() const;

 private:
  /// Ends the measurement with zero force; limit NaN: `what` alone names the cause.
  void abort(const char* what, double value, double limit);
  double velocity_command_mps() const;

  FrequencyResponseMeasurementParams params_;
  Multisine excitation_;
  VelocityPi velocity_pi_;
  double offset_velocity_mps_ = 0;
  std::uint64_t ramp_ticks_ = 0;
  std::uint64_t excite_end_tick_ = 0;
  std::uint64_t measure_start_tick_ = 0;
  double trim_gain_per_s_ = 0;
  double velocity_trim_mps_ = 0;
  std::uint64_t stop_end_tick_ = 0;
  MeasurementPhase phase_ = MeasurementPhase::kRamp;
  std::string abort_reason_;
  std::uint64_t tick_ = 0;
  bool have_start_ = false;
  double start_position_m_ = 0;
  double last_force_n_ = 0;
  double last_excitation_n_ = 0;
  bool last_recorded_ = false;  ///< the force applied over the last tick was an excitation tick's
  std::uint64_t late_ticks_ = 0;
  std::vector<double> excitation_n_, force_n_, velocity_mps_;
  std::vector<double> load_velocity_mps_;
  double last_load_position_m_ = std::numeric_limits<double>::quiet_NaN();
  bool load_lost_ = false;  ///< a load reading was there and went missing during the excitation
};

/// The plant's response and the two-mass fit of a completed measurement; with a load encoder the
/// load's side and its fit too.
struct FrequencyResponseResult {
  std::vector<FrequencyPoint> points;
  TwoMassFit fit;
  std::size_t low_coherence_lines = 0;
  std::vector<LoadRatioPoint> load_points;  ///< empty without a load encoder
  std::optional<LoadSideFit> load_fit;
};

/// Runs a measurement on a drive to its end: enables the drive (shutdown, switch on, enable
/// operation), steps until finished, then disables the drive (zero force, disable operation).
/// `progress(tick, total)` is called once a second of drive time. The drive must be at rest. A
/// drive that refuses to enable ends the measurement at its first tick (not in operation enabled).
template <typename Progress>
void run_measurement(drive::Drive& drive, FrequencyResponseMeasurement& measurement, Progress&& progress) {
  for (const drive::DriveCommand command :
       {drive::DriveCommand::kShutdown, drive::DriveCommand::kSwitchOn, drive::DriveCommand::kEnableOperation}) {
    drive.sample();
    drive.request(command);
    drive.apply(0.0);
  }
  const auto ticks_per_second = static_cast<std::uint64_t>(1.0 / measurement.params().period_s + 0.5);
  while (!measurement.finished()) {
    const drive::Measurement m = drive.sample();
    const double force_n = measurement.step(m, drive.power_state() == drive::PowerState::kOperationEnabled);
    drive.apply(force_n);
    if (measurement.ticks() % ticks_per_second == 0) progress(measurement.ticks(), measurement.total_ticks());
  }
  drive.sample();
  drive.apply(0.0);
  drive.request(drive::DriveCommand::kSwitchOn);  // disable operation (transition 5)
}

/// The estimates and the fit of a completed measurement, with the coherence rule applied; with a
/// load encoder the load's side fitted over the two-mass fit's band and its sensor checked against
/// the motor's encoder (its gain within kLoadSensorGainTolerance of 1).
/// @throws std::invalid_argument when the measurement did not complete, when more than
/// max_low_coherence_share of the lines fall below min_coherence (naming how many and the
/// worst), from the fits, or when the load's sensor disagrees with the motor's encoder (its sign
/// or scale, with what was measured).
FrequencyResponseResult evaluate_measurement(const FrequencyResponseMeasurement& measurement);

/// How far a load sensor's gain against the motor's encoder may be from 1: a 5 % scale error or a
/// reversed sign is a misconfigured part, not noise (the family's fits: within 0.5 %).
inline constexpr double kLoadSensorGainTolerance = 0.05;

}  // namespace pmlsm
