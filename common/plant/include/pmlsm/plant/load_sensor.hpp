// A sensor on the load, beside the motor's encoder: a second linear encoder on the load (a drive's
// "dual loop" or "full-closed loop", CiA 402's additional position 0x60E4) or an accelerometer on
// it. None by default: the paper's rig had the motor's 1 um encoder only. Read once a control tick
// from the plant's true load position x_l and acceleration a_l at the tick:
//
//   encoder        y_k = T_q(x_l,k-L + n_k)                 n_k ~ N(0, sigma^2)
//   accelerometer  u_k = a_l,k-L + b_k + n_k                 n_k ~ N(0, N^2 f_s / 2)
//                  y_k = sat(y_k-1 + (1 - e^(-2 pi B T)) (u_k - y_k-1), +-range)
//                  b_k+1 = b_k + w_k                         w_k ~ N(0, D^2 T)
//
// T_q floors to the resolution (as the motor's encoder counts); L is the latency in whole ticks;
// N the noise density [m/s^2/sqrt(Hz)], white over the sampling band f_s / 2 = 1 / (2 T); B the
// bandwidth of a first-order low pass (exact at the tick); b the bias, starting at bias_mps2 and
// walking with density D [m/s^2/sqrt(s)]; range the rail the reading saturates at (counted). Pure,
// seeded, no allocation after construction.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

enum class LoadSensorKind { kNone, kEncoder, kAccelerometer };
const char* to_string(LoadSensorKind kind);
/// @throws std::invalid_argument listing the names ("must be one of none, encoder, accelerometer").
LoadSensorKind load_sensor_kind_from_string(const std::string& name);

struct LoadSensorParams {
  LoadSensorKind kind = LoadSensorKind::kNone;
  double resolution_m = 0;                    ///< encoder: the count
  double position_noise_std_m = 0;            ///< encoder: sigma, before the count
  double noise_density_mps2_per_sqrt_hz = 0;  ///< accelerometer: N
  double bandwidth_hz = 0;                    ///< accelerometer: B
  double bias_mps2 = 0;                       ///< accelerometer: b_0
  double bias_drift_mps2_per_sqrt_s = 0;      ///< accelerometer: D
  double range_mps2 = 0;                      ///< accelerometer: the rail
  std::uint32_t latency_ticks = 0;            ///< L, both kinds
  std::uint64_t noise_seed = 0;
  // Judging its readings (pmlsm/estimation/load_sensor_monitor.hpp):
  double fault_after_s = 0;           ///< bad this long in a row, or stuck over it: failed
  double saturated_fail_after_s = 0;  ///< an accelerometer at its rail this long in a row: failed
  double max_speed_mps = 0;           ///< an encoder's reading moving faster than this jumped
  double stuck_travel_m = 0;          ///< an encoder's count unchanged while the motor travelled this far: stuck
  /// The simulated part goes silent (NaN readings) from this time on, a cut cable to rehearse the
  /// failure with; 0: never.
  double silent_after_s = 0;
  /// The declared ranges.
  void validate() const;
  /// Its entries under `at` ("sensors.load").
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    const std::string s = at + ".";
    v.choice(s + "kind", p.kind, &load_sensor_kind_from_string);
    v.real(s + "resolution_m", p.resolution_m,
           {1e-10, 1e-2, "from an interferometer's 0.1 nm to a 10 mm coarse scale"});
    v.real(s + "position_noise_std_m", p.position_noise_std_m, {0.0, 1e-2, "0 to 10 mm of noise"});
    v.real(s + "noise_density_mps2_per_sqrt_hz", p.noise_density_mps2_per_sqrt_hz,
           {0.0, 1.0, "0 to 100 mg/sqrt(Hz): a MEMS part's is 20-300 ug/sqrt(Hz), a piezo's 1-10"});
    v.real(s + "bandwidth_hz", p.bandwidth_hz, {1.0, 1e5, "1 Hz to 100 kHz"});
    v.real(s + "bias_mps2", p.bias_mps2, {-100.0, 100.0, "within +-10 g"});
    v.real(s + "bias_drift_mps2_per_sqrt_s", p.bias_drift_mps2_per_sqrt_s, {0.0, 1.0, "0 to 1 m/s^2 per sqrt(s)"});
    v.real(s + "range_mps2", p.range_mps2, {1.0, 1e5, "a 0.1 g part to a 10,000 g shock sensor"});
    v.integer(s + "latency_ticks", p.latency_ticks, {0.0, static_cast<double>(kMaxLatencyTicks), "0 to 16 ticks"});
    v.integer(s + "noise_seed", p.noise_seed, {0.0, 18446744073709551615.0, "a seed: any whole number of 64 bits"});
    v.real(s + "fault_after_s", p.fault_after_s, {1e-4, 1.0, "0.1 ms to 1 s"});
    v.real(s + "saturated_fail_after_s", p.saturated_fail_after_s, {1e-4, 60.0, "0.1 ms to a minute at the rail"});
    v.real(s + "max_speed_mps", p.max_speed_mps, {1e-3, 1e3, "1 mm/s to 1 km/s"});
    v.real(s + "stuck_travel_m", p.stuck_travel_m, {1e-6, 1.0, "1 um to 1 m of the motor's travel"});
    v.real(s + "silent_after_s", p.silent_after_s, {0.0, 1e6, "0 (never) to 1e6 s into the run"});
  }
  static constexpr std::uint32_t kMaxLatencyTicks = 16;
};

/// One tick's reading; NaN in what the sensor does not measure (both without a sensor).
struct LoadSensorReading {
  double position_m = std::numeric_limits<double>::quiet_NaN();
  double acceleration_mps2 = std::numeric_limits<double>::quiet_NaN();
  bool saturated = false;  ///< the accelerometer at its rail this tick
};

struct LoadSensorCounters {
  std::uint64_t readings = 0;
  std::uint64_t saturated = 0;        ///< readings at the rail
  std::uint64_t rejected_inputs = 0;  ///< non-finite truth: the last reading held
  std::uint64_t silent = 0;           ///< ticks without a reading (silent_after_s)
};

class LoadSensor {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter or a period not in (0, 1] s.
  LoadSensor(const LoadSensorParams& params, double period_s);
  /// Starts from the load at rest at `load_position_m` (the latency line filled with it).
  void reset(double load_position_m);
  /// The reading of tick k from the truth at tick k.
  LoadSensorReading step(double load_position_m, double load_accel_mps2);
  const LoadSensorParams& params() const { return params_; }
  const LoadSensorCounters& counters() const { return counters_; }
  /// The accelerometer's bias now [m/s^2].
  double bias_mps2() const { return bias_mps2_; }
  /// The low pass's gain a tick, 1 - e^(-2 pi B T).
  static double low_pass_gain(double bandwidth_hz, double period_s);

 private:
  struct Truth {
    double position_m = 0, accel_mps2 = 0;
  };
  LoadSensorParams params_;
  double period_s_;
  double low_pass_gain_;   ///< 1 - e^(-2 pi B T)
  double noise_std_mps2_;  ///< N sqrt(f_s / 2)
  double drift_std_mps2_;  ///< D sqrt(T)
  double inv_resolution_;
  std::array<Truth, LoadSensorParams::kMaxLatencyTicks + 1> line_{};  ///< the truth of the last L + 1 ticks
  std::uint64_t next_ = 0;
  std::uint64_t steps_ = 0;        ///< ticks since reset
  std::uint64_t silent_from_ = 0;  ///< the first silent tick (0: never)
  double filtered_mps2_ = 0;
  double bias_mps2_ = 0;
  LoadSensorReading last_{};
  LoadSensorCounters counters_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_;
};

}  // namespace pmlsm
