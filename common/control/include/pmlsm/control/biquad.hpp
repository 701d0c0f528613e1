// Second-order filters (biquads) for the velocity loop's force command and the compensation path,
// as a servo drive's filter slots: up to four in a chain, each declared in the system file.
//
// Each kind is a continuous filter H(s) = (n2 s^2 + n1 s + n0) / (d2 s^2 + d1 s + d0), w = 2 pi f:
//   notch     (s^2 + 2 zeta_z w s + w^2) / (s^2 + 2 zeta_p w s + w^2)   zeta_z = damping (0: full
//             notch), zeta_p = second_damping (the width); the depth is zeta_z / zeta_p
//   low_pass  w^2 / (s^2 + 2 zeta w s + w^2)                            zeta = damping
//   lead_lag  (s / w_z + 1) / (s / w_p + 1)                             w_z = frequency, w_p = second
//   general   (s^2/w1^2 + 2 zeta1 s/w1 + 1) / (s^2/w2^2 + 2 zeta2 s/w2 + 1)   w1, zeta1 = frequency,
//             damping; w2, zeta2 = second_frequency, second_damping
// all with unit gain at 0 Hz, made discrete by the bilinear transform prewarped at the filter's
// own frequency (the notch's centre, the corner; the geometric mean of a lead-lag's or a general
// filter's two), so that frequency lands where it was asked:
//   s = K (z - 1) / (z + 1),  K = w0 / tan(w0 T / 2).
// The difference equation is the transposed direct form II:
//   y = b0 x + s1;  s1 = b1 x - a1 y + s2;  s2 = b2 x - a2 y.
#pragma once

#include <array>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

enum class FilterKind : std::uint8_t { kNone, kNotch, kLowPass, kLeadLag, kGeneral };
/// "none", "notch", "low_pass", "lead_lag", "general".
/// @throws std::invalid_argument "must be one of none, notch, ..., got 'x'".
FilterKind filter_kind_from_string(const std::string& name);
const char* to_string(FilterKind kind);

struct BiquadParams {
  FilterKind kind = FilterKind::kNone;
  double frequency_hz = 0;         ///< notch centre, low-pass corner, lead-lag zero, general numerator
  double damping = 0;              ///< notch zeros, low-pass, general numerator
  double second_frequency_hz = 0;  ///< lead-lag pole, general denominator
  double second_damping = 0;       ///< notch poles (its width), general denominator
  double period_s = 0;             ///< the loop's sampling period
  bool operator==(const BiquadParams& o) const {
    return kind == o.kind && frequency_hz == o.frequency_hz && damping == o.damping &&
           second_frequency_hz == o.second_frequency_hz && second_damping == o.second_damping && period_s == o.period_s;
  }
  bool operator!=(const BiquadParams& o) const { return !(*this == o); }
  /// The values the kind uses: frequencies in (0, 0.45 / period_s), dampings in their ranges.
  /// @throws std::invalid_argument naming the first invalid value.
  void validate() const;
  /// A slot's entries under `at`: the kind and the four values each kind may use (which it uses
  /// is checked by validate()); taken live by `live_at` (the velocity loop's chains: the
  /// controller) or nobody. The period comes from the system.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& slot, Visitor& v, const char* live_at = nullptr) {
    v.choice(at + ".kind", slot.kind, &filter_kind_from_string, live_at);
    v.real(at + ".frequency_hz", slot.frequency_hz, {0.0, 1e4, "0 (unused) to 10 kHz", live_at});
    v.real(at + ".damping", slot.damping, {0.0, 10.0, "0 to overdamped tenfold", live_at});
    v.real(at + ".second_frequency_hz", slot.second_frequency_hz, {0.0, 1e4, "0 (unused) to 10 kHz", live_at});
    v.real(at + ".second_damping", slot.second_damping, {0.0, 10.0, "0 to overdamped tenfold", live_at});
  }
};

struct BiquadCoefficients {
  double b0 = 1, b1 = 0, b2 = 0, a1 = 0, a2 = 0;  ///< a0 = 1
};

/// The discrete filter of a kind (kNone: y = x). @throws std::invalid_argument as validate().
BiquadCoefficients biquad_coefficients(const BiquadParams& params);

/// H(e^{j 2 pi f T}) of the discrete filter.
std::complex<double> biquad_response(const BiquadCoefficients& c, double frequency_hz, double period_s);

class Biquad {
 public:
  /// @throws std::invalid_argument as BiquadParams::validate.
  explicit Biquad(const BiquadParams& params);
  /// One sample. A non-finite input is rejected (counted): the last output is held and the
  /// state kept. Allocation-free.
  double step(double x);
  const BiquadCoefficients& coefficients() const { return c_; }
  std::uint64_t rejected_inputs() const { return rejected_; }

 private:
  BiquadCoefficients c_;
  double s1_ = 0, s2_ = 0, last_ = 0;
  std::uint64_t rejected_ = 0;
};

inline constexpr std::size_t kFilterSlots = 4;

/// Up to four biquads in series; the slots of kind none pass their input.
struct FilterChainParams {
  std::array<BiquadParams, kFilterSlots> slots;
  /// Its slots' entries under `at`.slot_1 ... slot_4 (BiquadParams::declare).
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& chain, Visitor& v, const char* live_at) {
    for (std::size_t i = 0; i < chain.slots.size(); ++i) {
      BiquadParams::declare(at + ".slot_" + std::to_string(i + 1), chain.slots[i], v, live_at);
    }
  }
  /// @throws std::invalid_argument naming the slot ("slot 2: frequency_hz: ...").
  void validate() const;
};

class FilterChain {
 public:
  /// @throws std::invalid_argument as FilterChainParams::validate.
  explicit FilterChain(const FilterChainParams& params);
  /// One sample through the slots in use. A non-finite input is rejected (counted): the chain's
  /// last output is held. Allocation-free.
  double step(double x);
  /// The chain's response at f (1 when every slot is none).
  std::complex<double> response(double frequency_hz) const;
  bool empty() const { return count_ == 0; }
  std::uint64_t rejected_inputs() const { return rejected_; }
  /// The slots it was made from.
  const FilterChainParams& params() const { return params_; }

 private:
  FilterChainParams params_;
  std::array<Biquad, kFilterSlots> filters_;
  std::size_t count_ = 0;  ///< the slots in use, first (none are skipped)
  double period_s_ = 0;
  double last_ = 0;
  std::uint64_t rejected_ = 0;
};

}  // namespace pmlsm
