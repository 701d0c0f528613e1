// Notch filters designed from a measured frequency response, as a drive's auto-tuner places its
// anti-resonance filters: a resonance the two-mass model does not explain (a motor frame, an
// encoder mount, a coupling: a mode above the model's band) that limits the velocity loop's gain.
//
// A candidate is a peak of the measured plant over the fitted model,
//   r(f) = 20 log10 |G(f) / G_fit(f)|,
// on the coherent lines above min_frequency_hz, whose prominence (its height over the higher of
// the two lowest points between it and a higher line on either side, or the band's end) is at
// least min_peak_db. Such a peak is a mode (s^2 + 2 z_n w s + w^2) / (s^2 + 2 z_d w s + w^2)
// with height P = z_n / z_d and half-power width 2 z_d f0; its inverse is the notch
//   centre f0 (the peak, refined by a parabola through its three lines in log f),
//   damping (zeros) z_d = width / (2 f0), at least the lines' own spacing around f0,
//   second_damping (poles) z_d P (the depth 1 / P: the peak flattened, no deeper).
// Candidates are tried highest first, each in the first free slot of the force command's chain
// (kind none), and kept only when the gain the tuner then allows (tune_velocity_pi with the
// chain so far) grows by min_gain_increase or more, or a loop no gain could tune becomes
// tunable: a notch that buys nothing costs phase below it and is not placed.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "pmlsm/control/biquad.hpp"
#include "pmlsm/analysis/frequency_response.hpp"
#include "pmlsm/analysis/loop_tuning.hpp"

namespace pmlsm {

/// `pmlsm commission --design-filters`: a notch in a free slot of filters.force_command for each
/// resonance above the two-mass model that limits the velocity loop's gain. The parameter section
/// "commissioning.filter_design" (analysis_params.hpp).
struct FilterDesignParams {
  /// Resonances are looked for above it, > 0: the two-mass fit's band
  /// (commissioning.frequency_response.dense_max_frequency_hz); below it the model holds the modes.
  double min_frequency_hz = 40.0;
  /// A peak's prominence over the model, > 0: a mode standing twice over it. The two-mass plant's
  /// measured response stays within 0.5 dB of its model above 40 Hz (the current loop's roll-off aside).
  double min_peak_db = 6.0;
  /// A notch is kept when the tunable gain grows by this factor, > 1: one that gains less than 5 %
  /// costs phase below it for little.
  double min_gain_increase = 1.05;
  /// @throws std::invalid_argument naming the first invalid value.
  void validate() const;
  /// Its entries under `at` ("commissioning.filter_design"). Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& d, Visitor& v) {
    v.real(at + ".min_frequency_hz", d.min_frequency_hz,
           {1e-3, 1e5, "1 mHz to 100 kHz (above it: resonances; below it: the two-mass model)"});
    v.real(at + ".min_peak_db", d.min_peak_db, {0.1, 60.0, "0.1 to 60 dB"});
    v.real(at + ".min_gain_increase", d.min_gain_increase, {1.000001, 100.0, "a factor above 1, up to 100"});
  }
};

/// A resonance found above the model and what its notch did.
struct ResonancePeak {
  double frequency_hz = 0;       ///< the notch's centre
  double height_db = 0;          ///< the prominence over the model
  double width_hz = 0;           ///< the half-power width the notch was given
  BiquadParams notch;            ///< the notch designed for it
  double gain_scale_before = 0;  ///< the gain the tuner allowed before it (0: none)
  double gain_scale_with = 0;    ///< with it (0: none)
  bool slot_free = false;        ///< a slot of kind none was left to try it in
  bool placed = false;
};

struct FilterDesign {
  FilterChainParams chain;           ///< the configured slots with the placed notches in free ones
  std::vector<ResonancePeak> peaks;  ///< every candidate, highest first, placed or not
  std::size_t placed = 0;
};

/// The resonance peaks of the measured plant over the fitted model (see above) below 0.45 times
/// the sampling frequency (a notch's highest), highest first, each with its notch for a loop
/// sampled every `period_s`.
std::vector<ResonancePeak> resonance_peaks(const std::vector<FrequencyPoint>& points, const TwoMassFit& fit,
                                           double min_coherence, double period_s, const FilterDesignParams& params);

/// Notches for the peaks that raise the gain the tuner allows, in the free slots of `configured`
/// (see above). `period_s` is the loop's sampling period (the notch's discretisation).
/// @throws std::invalid_argument from the parameters' or the targets' validation.
FilterDesign design_notches(const std::vector<FrequencyPoint>& points, const TwoMassFit& fit,
                            const FilterChainParams& configured, const TuningTargets& targets, double min_coherence,
                            double period_s, const FilterDesignParams& params);

}  // namespace pmlsm
