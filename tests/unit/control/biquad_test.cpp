// The filter slots (pmlsm/control/biquad.hpp): each kind's response where its definition pins
// it (a notch's depth at its centre, a low-pass's peak at its corner, a lead-lag's phase at its
// centre), the difference equation against that response, the chain, and what is refused.
#include "pmlsm/control/biquad.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace pmlsm {
namespace {

constexpr double kPeriod = 1e-3;
constexpr double kTwoPiBiquad = 6.28318530717958647692;

BiquadParams slot(FilterKind kind, double f, double zeta, double f2, double zeta2) {
  return {kind, f, zeta, f2, zeta2, kPeriod};
}

double magnitude(const BiquadParams& p, double f) {
  return std::abs(biquad_response(biquad_coefficients(p), f, kPeriod));
}

TEST(Biquad, EachKindHasItsResponseWhereItsDefinitionPinsIt) {
  // Notch at 10.2 Hz, zeros damped 0.02, poles 0.2: depth 0.1 at the centre (prewarped there),
  // unity at 0 Hz and far from it.
  const BiquadParams notch = slot(FilterKind::kNotch, 10.2, 0.02, 0.0, 0.2);
  EXPECT_NEAR(magnitude(notch, 10.2), 0.1, 1e-9);
  EXPECT_NEAR(magnitude(notch, 0.0), 1.0, 1e-12);
  EXPECT_NEAR(magnitude(notch, 200.0), 1.0, 0.01);
  EXPECT_LT(magnitude(slot(FilterKind::kNotch, 10.2, 0.0, 0.0, 0.2), 10.2), 1e-9);
  // Low-pass at 100 Hz, zeta 0.3: 1 / (2 zeta) at the corner, unity at 0 Hz.
  const BiquadParams low = slot(FilterKind::kLowPass, 100.0, 0.3, 0.0, 0.0);
  EXPECT_NEAR(magnitude(low, 100.0), 1.0 / 0.6, 1e-9);
  EXPECT_NEAR(magnitude(low, 0.0), 1.0, 1e-12);
  EXPECT_LT(magnitude(low, 400.0), 0.1);
  // Lead-lag, zero 20 Hz, pole 80 Hz: gain 1 -> 4, the largest lead asin(3/5) = 36.87 deg at
  // the geometric mean, 40 Hz (prewarped there).
  const BiquadParams lead = slot(FilterKind::kLeadLag, 20.0, 0.0, 80.0, 0.0);
  EXPECT_NEAR(magnitude(lead, 0.0), 1.0, 1e-12);
  EXPECT_NEAR(std::arg(biquad_response(biquad_coefficients(lead), 40.0, kPeriod)) * 180.0 / M_PI,
              std::asin(3.0 / 5.0) * 180.0 / M_PI, 1e-6);
  EXPECT_NEAR(magnitude(lead, 40.0), 2.0, 1e-9);
  // General with equal numerator and denominator: the identity.
  const BiquadParams same = slot(FilterKind::kGeneral, 30.0, 0.5, 30.0, 0.5);
  for (const double f : {0.0, 5.0, 30.0, 300.0}) EXPECT_NEAR(magnitude(same, f), 1.0, 1e-12) << f;
  // None: y = x.
  const BiquadCoefficients none = biquad_coefficients(slot(FilterKind::kNone, 0, 0, 0, 0));
  EXPECT_EQ(none.b0, 1.0);
  EXPECT_EQ(none.a1, 0.0);
}

// A sine through the difference equation settles to the amplitude and phase of the response.
TEST(Biquad, TheDifferenceEquationFollowsItsResponse) {
  for (const BiquadParams& p :
       {slot(FilterKind::kNotch, 10.2, 0.02, 0.0, 0.2), slot(FilterKind::kLowPass, 100.0, 0.3, 0.0, 0.0),
        slot(FilterKind::kLeadLag, 20.0, 0.0, 80.0, 0.0), slot(FilterKind::kGeneral, 15.0, 0.1, 25.0, 0.7)}) {
    for (const double f : {3.0, 10.2, 47.0}) {
      Biquad filter(p);
      const std::complex<double> h = biquad_response(filter.coefficients(), f, kPeriod);
      double worst = 0;
      for (int k = 0; k < 20000; ++k) {
        const double y = filter.step(std::sin(kTwoPiBiquad * f * k * kPeriod));
        if (k >= 15000) {
          worst = std::max(worst, std::fabs(y - std::abs(h) * std::sin(kTwoPiBiquad * f * k * kPeriod + std::arg(h))));
        }
      }
      EXPECT_LT(worst, 1e-6) << to_string(p.kind) << " at " << f << " Hz";
    }
  }
}

TEST(FilterChain, SlotsOfKindNonePassTheInputAndANonFiniteOneIsHeld) {
  FilterChainParams chain;
  for (BiquadParams& s : chain.slots) s.period_s = kPeriod;
  FilterChain empty(chain);
  EXPECT_TRUE(empty.empty());
  for (const double x : {0.1, -3.7e5, 1e-300}) EXPECT_EQ(empty.step(x), x);
  chain.slots[2] = slot(FilterKind::kLowPass, 100.0, 0.7, 0.0, 0.0);
  chain.slots[3] = slot(FilterKind::kNotch, 10.2, 0.0, 0.0, 0.2);
  FilterChain two(chain);
  EXPECT_FALSE(two.empty());
  EXPECT_NEAR(std::abs(two.response(10.2)), 0.0, 1e-9);
  const std::complex<double> expected = biquad_response(biquad_coefficients(chain.slots[2]), 50.0, kPeriod) *
                                        biquad_response(biquad_coefficients(chain.slots[3]), 50.0, kPeriod);
  EXPECT_NEAR(std::abs(two.response(50.0) - expected), 0.0, 1e-12);
  const double y = two.step(1.0);
  EXPECT_EQ(two.step(std::numeric_limits<double>::quiet_NaN()), y);
  EXPECT_EQ(two.rejected_inputs(), 1u);
}

TEST(FilterChain, AFilterTheKindCannotUseIsRefusedNamingTheSlotAndValue) {
  struct Case {
    BiquadParams slot;
    const char* expected;
  };
  for (const Case& c : {Case{slot(FilterKind::kNotch, 10.0, 0.3, 0.0, 0.2), "slot 2: damping: must be in [0, 0.2]"},
                        Case{slot(FilterKind::kLowPass, 600.0, 0.7, 0.0, 0.0), "slot 2: frequency_hz: must be in"},
                        Case{slot(FilterKind::kLowPass, 100.0, 0.0, 0.0, 0.0), "slot 2: damping"},
                        Case{slot(FilterKind::kLeadLag, 20.0, 0.0, 0.0, 0.0), "slot 2: second_frequency_hz"},
                        Case{slot(FilterKind::kGeneral, 20.0, 0.5, 30.0, 0.0), "slot 2: second_damping"}}) {
    FilterChainParams chain;
    for (BiquadParams& s : chain.slots) s.period_s = kPeriod;
    chain.slots[1] = c.slot;
    try {
      FilterChain filters(chain);
      ADD_FAILURE() << "accepted: " << c.expected;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(filter_kind_from_string("band_pass"), std::invalid_argument);
  for (const FilterKind k :
       {FilterKind::kNone, FilterKind::kNotch, FilterKind::kLowPass, FilterKind::kLeadLag, FilterKind::kGeneral}) {
    EXPECT_EQ(filter_kind_from_string(to_string(k)), k);
  }
}

}  // namespace
}  // namespace pmlsm
