// Frequency-response measurement of the drive under its velocity loop, the pure part: the
// excitation, the response estimated from what was recorded, and the two-mass model fitted to it.
//
// Excitation: a periodic multisine (Schroeder phases, so its crest factor stays low) on lines
// k df, f_min <= k df <= f_max, added to the force command under the velocity loop. Each line
// is a whole number of cycles per period, so the DFT of each period sees it without leakage.
//
// Estimates per excited line, averaged over the measured periods p (after the settling ones):
//   plant        G = sum_p V_p / sum_p F_p     force -> motor velocity (errors-in-variables mean)
//   sensitivity  S = sum_p F_p / sum_p R_p     F = R - C V = R / (1 + C G)
//   open loop    L = C G = 1/S - 1;  closed loop T = L / (1 + L) = 1 - S
//   coherence    |sum_p V_p R_p*|^2 / (sum_p |V_p|^2 sum_p |R_p|^2): 1 when V follows R alone
// with R, F, V the DFTs of excitation, applied force and measured motor velocity.
//
// Two-mass model (motor m_M with viscous friction b, spring k and damper c to the load m_L):
//   1/G(s) = m_M s + b + m_L s (c s + k) / (m_L s^2 + c s + k)
//   G(s)   = (s^2 + n1 s + n0) / (d3 s^3 + d2 s^2 + d1 s + d0)   (numerator and denominator / m_L)
//   n0 = k/m_L (anti-resonance w_a^2), n1 = c/m_L, d3 = m_M, d0 = b k/m_L,
//   d1 = ((m_M + m_L) k + b c)/m_L, d2 = ((m_M + m_L) c + b m_L)/m_L.
// The fit is linear in (n1, n0, d3, d2, d1, d0) once the equation N - G D = 0 is weighted by
// 1/|D| of the previous estimate (Levy's method with Sanathanan-Koerner iterations), so it needs
// no start value and no search. From the coefficients: m_M = d3, m_L and b from d1, d0 and n0,
// k = n0 m_L, c = n1 m_L; resonance from the denominator's oscillatory pair.
#pragma once

#include <complex>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace pmlsm {

struct MultisineParams {
  double amplitude_n = 0;       ///< peak of the summed force [N], > 0
  double min_frequency_hz = 0;  ///< lowest excited line, > 0
  double max_frequency_hz = 0;  ///< highest, below the Nyquist frequency
  double resolution_hz = 0;     ///< line spacing df: the period is 1/df
  double period_s = 0;          ///< the control period the excitation runs at
  /// Every line k df up to this frequency; above it, lines_per_decade lines a decade (on the df
  /// grid), so the loop's crossovers are reached without spreading the force over a thousand
  /// lines. 0: every line up to max_frequency_hz.
  double dense_max_frequency_hz = 0;
  double lines_per_decade = 0;  ///< above dense_max_frequency_hz, > 0 when that is set
  /// @throws std::invalid_argument naming the first invalid value.
  void validate() const;
};

class Multisine {
 public:
  /// @throws std::invalid_argument as MultisineParams::validate, or when no line is excited.
  explicit Multisine(const MultisineParams& params);
  /// The force to add at tick n (periodic in ticks_per_period()). Allocation-free.
  double value(std::uint64_t tick) const { return table_[tick % table_.size()]; }
  std::size_t ticks_per_period() const { return table_.size(); }
  /// The excited DFT bins k (frequency k df) of one period.
  const std::vector<std::size_t>& lines() const { return lines_; }
  double resolution_hz() const { return params_.resolution_hz; }

 private:
  MultisineParams params_;
  std::vector<double> table_;
  std::vector<std::size_t> lines_;
};

struct FrequencyPoint {
  double frequency_hz = 0;
  std::complex<double> plant;        ///< G: motor velocity over force [m/s / N]
  std::complex<double> sensitivity;  ///< S = F / R
  double coherence = 0;              ///< of the velocity with the excitation, [0, 1]
  std::complex<double> open_loop() const { return 1.0 / sensitivity - 1.0; }
  std::complex<double> closed_loop() const { return 1.0 - sensitivity; }
};

/// The estimates per excited line from recorded sequences of one sample per tick, starting at
/// the excitation's tick 0: `excitation` R, applied `force_n` F, measured `velocity_mps` V. The
/// first `settle_periods` periods are skipped; every whole period after them is averaged.
/// @throws std::invalid_argument when the sequences differ in length, hold a non-finite value,
/// or leave fewer than two periods to average.
std::vector<FrequencyPoint> estimate_frequency_response(const Multisine& excitation,
                                                        const std::vector<double>& excitation_n,
                                                        const std::vector<double>& force_n,
                                                        const std::vector<double>& velocity_mps,
                                                        std::size_t settle_periods);

struct TwoMassFit {
  double motor_mass_kg = 0;
  double load_mass_kg = 0;
  double spring_n_per_m = 0;
  double spring_damping_n_s_per_m = 0;  ///< c
  double motor_viscous_n_s_per_m = 0;   ///< b
  double anti_resonance_hz = 0;         ///< w_a / 2 pi = sqrt(k / m_L) / 2 pi
  double anti_resonance_damping = 0;    ///< c / (2 sqrt(k m_L))
  double resonance_hz = 0;              ///< the denominator's oscillatory pair
  double resonance_damping = 0;
  double rms_log_error = 0;  ///< RMS of |ln G_measured - ln G_model| over the lines used
  std::size_t lines_used = 0;
};

/// Fits the two-mass model to the plant estimates whose coherence is at least `min_coherence` and
/// whose frequency is at most `max_frequency_hz` (the mechanics' band: above it the drive's
/// current loop and the sampling shape the response, which the model does not hold).
/// @throws std::invalid_argument when fewer than 6 lines qualify or the fit is not physical
/// (a mass, the spring or the anti-resonance not positive), naming what.
TwoMassFit fit_two_mass(const std::vector<FrequencyPoint>& points, double min_coherence,
                        double max_frequency_hz = 1e300);

/// The two-mass model's undamped modes [Hz]: the anti-resonance sqrt(k / m_L) (the load on a held
/// motor) and the resonance sqrt(k (1/m_L + 1/m_M)) (both masses free).
double anti_resonance_hz(double load_mass_kg, double spring_n_per_m);
double resonance_hz(double motor_mass_kg, double load_mass_kg, double spring_n_per_m);

/// G(j 2 pi f) of the two-mass model with the given parameters.
std::complex<double> two_mass_response(const TwoMassFit& model, double frequency_hz);

// ---- the load's side, with a sensor on the load
//
// The load's velocity over the motor's, per excited line: Q = sum_p V_L,p / sum_p V_M,p. In the
// two-mass model the load is a mass on the spring and damper the motor drives,
//   Q(s) = (c s + k) / (m_L s^2 + c s + k) = (2 z w s + w^2) / (s^2 + 2 z w s + w^2),
// a second-order low pass whose corner w is the motor side's anti-resonance sqrt(k / m_L) and
// whose damping z = c / (2 sqrt(k m_L)) is the load's own: read here directly, not through the
// motor's response, where they are a notch between two resonances. A sensor that reads g times
// the load's motion (a reversed sign, a wrong scale) gives g Q; g is fitted too:
//   Q s^2 + Q n1 s + Q n0 = u1 s + u0,  n1 = 2 z w, n0 = w^2, u1 = g n1, u0 = g n0,
// linear in (n1, n0, u1, u0), each line's equation weighted by 1 / |s|^2 (a least-squares fit of
// real and imaginary parts), g = u0 / n0.

struct LoadRatioPoint {
  double frequency_hz = 0;
  std::complex<double> ratio;  ///< Q = V_L / V_M
  double coherence = 0;        ///< of the load's velocity with the motor's, [0, 1]
};

/// Q per excited line from one sample per tick of the motor's and the load's velocity (the means
/// over the same ticks), from the excitation's tick 0, the first `settle_periods` periods skipped.
/// @throws std::invalid_argument as estimate_frequency_response.
std::vector<LoadRatioPoint> estimate_load_ratio(const Multisine& excitation, const std::vector<double>& velocity_mps,
                                                const std::vector<double>& load_velocity_mps,
                                                std::size_t settle_periods);

struct LoadSideFit {
  double anti_resonance_hz = 0;       ///< w / 2 pi
  double anti_resonance_damping = 0;  ///< z, the load's own
  double gain = 0;                    ///< g: 1 for a sensor that reads the load as the motor's encoder reads the motor
  double rms_log_error = 0;           ///< RMS of |ln Q_measured - ln Q_model| over the lines used
  std::size_t lines_used = 0;
};

/// Fits Q to the lines with both coherences (the load's with the motor's, the motor's with the
/// excitation: near w the motor stands still and Q is not measured) at least `min_coherence`, up
/// to `max_frequency_hz`.
/// @throws std::invalid_argument when fewer than 4 lines qualify or the fit has no corner (w^2 not
/// positive), naming what. An undamped load fits a damping about 0, either side.
LoadSideFit fit_load_side(const std::vector<LoadRatioPoint>& load, const std::vector<FrequencyPoint>& motor,
                          double min_coherence, double max_frequency_hz);

/// A sensor whose gain g is not within `tolerance` of 1: "the load's sensor reads -1.002 times the
/// load's motion against the motor's encoder (fitted over 150 lines): its sign is reversed", or
/// "... its scale is off by ..."; "" when it agrees.
std::string load_sensor_disagreement(const LoadSideFit& fit, double tolerance);

}  // namespace pmlsm
