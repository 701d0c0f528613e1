// Compensators added in their own folders (pmlsm/sim/compensator_law.hpp): their parameter
// sections join the system file's table (pmlsm/util/parameter_section.hpp) with the declaration's
// defaults, the file and --set may set them, every check of the file applies, the live entries
// are the node's; and the tutorial's law, spring-force feedback, driven directly.
#include "pmlsm/sim/compensator_law.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "config_edit.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/sim/live_parameters.hpp"
#include "spring_force_feedback/spring_force_feedback.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

const std::string kSectionAt = "compensator.spring_force_feedback";

/// The shipped file with `section` (YAML, indented as under `compensator:`) put into its
/// compensator section.
std::string with_compensator_section(const std::string& section) {
  std::string text = test::system_text();
  const std::string anchor = "\ncompensator:\n";
  const std::size_t at = text.find(anchor);
  EXPECT_NE(at, std::string::npos);
  text.insert(at + anchor.size(), section);
  return text;
}

TEST(ParameterSections, EveryReaderOfTheSystemFileHasTheRegisteredOnesWithTheirDefaults) {
  ASSERT_FALSE(registered_parameter_sections().empty());
  const SystemParams& p = test::shipped_params();
  ASSERT_EQ(p.sections.size(), registered_parameter_sections().size());
  const auto law = p.section<SpringForceFeedback::Params>(kSectionAt);
  const SpringForceFeedback::Params declared;
  EXPECT_EQ(law.gain, declared.gain);
  EXPECT_EQ(law.cutoff_hz, declared.cutoff_hz);
  EXPECT_EQ(parameter_text(p, kSectionAt + ".gain"), "40");
  EXPECT_EQ(live_keys(p, "spring_force_feedback"), std::vector<std::string>{kSectionAt + ".gain"});
}

TEST(ParameterSections, TheFileAndTheCommandLineSetTheirEntries) {
  const SystemParams in_file =
      parse_system_params(with_compensator_section("  spring_force_feedback:\n    gain: 12.5\n"), "system.yaml");
  const auto law = in_file.section<SpringForceFeedback::Params>(kSectionAt);
  EXPECT_EQ(law.gain, 12.5);
  EXPECT_EQ(law.cutoff_hz, SpringForceFeedback::Params{}.cutoff_hz) << "an entry left out keeps its default";

  const SystemParams set =
      parse_system_params(test::system_text(), "system.yaml", parse_overrides({kSectionAt + ".cutoff_hz=250"}));
  EXPECT_EQ(set.section<SpringForceFeedback::Params>(kSectionAt).cutoff_hz, 250.0);
  // A sourced leaf, as every entry of the shipped file is.
  const SystemParams sourced = parse_system_params(
      with_compensator_section("  spring_force_feedback:\n    gain: {value: 20, source: \"chosen: a test\"}\n"),
      "system.yaml");
  EXPECT_EQ(sourced.section<SpringForceFeedback::Params>(kSectionAt).gain, 20.0);
}

TEST(ParameterSections, TheirEntriesAreCheckedAsTheFilesOwn) {
  struct Case {
    std::string section;           ///< put under `compensator:` ("": the shipped file as it is)
    std::vector<std::string> set;  ///< --set overrides
    std::string expected;          ///< in the ConfigError
  };
  const std::vector<Case> cases{
      {"", {kSectionAt + ".gain=2000"}, "system.yaml: compensator.spring_force_feedback.gain: must be in [0, 1000]"},
      {"  spring_force_feedback:\n    gian: 3\n", {}, "compensator.spring_force_feedback.gian: unknown key"},
      {"  spring_force_feedback:\n    gain: strong\n", {}, "compensator.spring_force_feedback.gain: expected a number"},
      {"  spring_force_feedback: 3\n", {}, "compensator.spring_force_feedback: must be a mapping of keys"},
      {"", {kSectionAt + ".gian=3"}, "no key 'compensator.spring_force_feedback.gian'"},
  };
  for (const Case& c : cases) {
    const std::string text = c.section.empty() ? test::system_text() : with_compensator_section(c.section);
    const std::string error = test::error_of([&] { parse_system_params(text, "system.yaml", parse_overrides(c.set)); });
    EXPECT_NE(error.find(c.expected), std::string::npos) << error;
  }
}

TEST(ParameterSections, ALiveChangeIsCheckedKeptAndRefusedAsAnyOther) {
  const SystemParams& shipped = test::shipped_params();
  LiveParameters live(shipped, live_keys(shipped, "spring_force_feedback"));
  const LiveAnswer a = live.set(kSectionAt + ".gain", "25");
  ASSERT_TRUE(a.accepted) << a.reason;
  EXPECT_TRUE(live.take_pending());
  EXPECT_EQ(live.params().section<SpringForceFeedback::Params>(kSectionAt).gain, 25.0);
  const LiveAnswer refused = live.set(kSectionAt + ".gain", "-1");
  EXPECT_FALSE(refused.accepted);
  EXPECT_NE(refused.reason.find("compensator.spring_force_feedback.gain: must be in [0, 1000]"), std::string::npos)
      << refused.reason;
  EXPECT_EQ(live.params().section<SpringForceFeedback::Params>(kSectionAt).gain, 25.0);
  EXPECT_FALSE(live.set(kSectionAt + ".cutoff_hz", "50").accepted) << "read at start only";
}

// A section's whole numbers and flags keep their kinds through the values it is held in.
struct CountsAndFlags {
  std::uint32_t window_ticks = 8;
  bool enabled = true;
  double scale = 0.5;
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
    v.integer(at + ".window_ticks", p.window_ticks, {1, 1000, "a window of ticks", live_at});
    v.flag(at + ".enabled", p.enabled);
    v.real(at + ".scale", p.scale, {0, 1, "a share"});
  }
  void validate() const {
    if (enabled && window_ticks < 2) throw std::invalid_argument("window_ticks: must be >= 2 when enabled");
  }
};

class CollectSection final : public SectionVisitor {
 public:
  void real(const std::string& path, double& value, const Plausible&) override { seen[path] = value; }
  void integer(const std::string& path, std::int64_t& value, const Plausible& range) override {
    seen[path] = static_cast<double>(value);
    if (range.live_at != nullptr) live = range.live_at;
    value = 12;
  }
  void flag(const std::string& path, bool& value) override {
    seen[path] = value ? 1 : 0;
    value = false;
  }
  std::map<std::string, double> seen;
  std::string live;
};

TEST(ParameterSections, WholeNumbersAndFlagsKeepTheirKindsAndValidateRuns) {
  const ParameterSection section = parameter_section<CountsAndFlags>("test.counts", "a_node", "here.hpp");
  SectionValues values;
  CollectSection collect;
  section.visit(section, values, collect);
  EXPECT_EQ(collect.seen.at("test.counts.window_ticks"), 8.0);
  EXPECT_EQ(collect.seen.at("test.counts.enabled"), 1.0);
  EXPECT_EQ(collect.live, "a_node");
  const auto p = section_params<CountsAndFlags>(values, "test.counts");
  EXPECT_EQ(p.window_ticks, 12u) << "what the visitor wrote is kept";
  EXPECT_FALSE(p.enabled);
  values["test.counts.enabled"] = 1;
  values["test.counts.window_ticks"] = 1;
  EXPECT_THROW(section.validate(section, values), std::invalid_argument);
}

// --- the tutorial's law ------------------------------------------------------------------------

constexpr double kLawPeriodS = 1e-3;

CompensatorView spring_force_view(double force_n) {
  CompensatorView v;
  v.spring_force_n = force_n;
  return v;
}

TEST(SpringForceFeedback, FeedsTheLowPassedSpringForceBackAgainstTheMotor) {
  SpringForceFeedback::Params p;
  p.gain = 10;
  p.cutoff_hz = 100;
  SpringForceFeedback law(p, kLawPeriodS);
  const double alpha = 1.0 - std::exp(-2.0 * M_PI * 100.0 * kLawPeriodS);
  EXPECT_NEAR(law.step(spring_force_view(5.0)), -10.0 * alpha * 5.0, 1e-12);
  // A held force: the filter reaches it (a first-order lag, 1.6 ms time constant).
  double force = 0;
  for (int k = 0; k < 50; ++k) force = law.step(spring_force_view(5.0));
  EXPECT_NEAR(force, -50.0, 1e-6);
  // A live change of the gain keeps the filter's state: the next force is the new gain at once.
  p.gain = 20;
  law.set_params(p);
  EXPECT_NEAR(law.step(spring_force_view(5.0)), -100.0, 1e-6);
}

TEST(SpringForceFeedback, RefusesValuesOutsideItsDeclarationNamingThem) {
  SpringForceFeedback::Params p;
  p.gain = -1;
  try {
    SpringForceFeedback law(p, kLawPeriodS);
    ADD_FAILURE() << "a negative gain was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("spring_force_feedback.gain: must be in [0, 1000]"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(SpringForceFeedback(SpringForceFeedback::Params{}, 0.0), std::invalid_argument);
  SpringForceFeedback law(SpringForceFeedback::Params{}, kLawPeriodS);
  SpringForceFeedback::Params bad;
  bad.cutoff_hz = 0;
  EXPECT_THROW(law.set_params(bad), std::invalid_argument);
  EXPECT_NEAR(law.step(spring_force_view(1.0)), -40.0 * (1.0 - std::exp(-2.0 * M_PI * 100.0 * kLawPeriodS)), 1e-12)
      << "the old parameters are kept";
}

TEST(LimitedForce, NeverStepsOnANonFiniteViewAndHoldsTheLimit) {
  SpringForceFeedback::Params p;
  p.gain = 1000;
  p.cutoff_hz = 1e5;
  SpringForceFeedback law(p, kLawPeriodS);
  LawCounters counters;
  EXPECT_EQ(limited_force(law, spring_force_view(std::numeric_limits<double>::quiet_NaN()), 675.0, counters), 0.0);
  EXPECT_EQ(counters.rejected, 1u);
  EXPECT_EQ(limited_force(law, spring_force_view(10.0), 675.0, counters), -675.0);
  EXPECT_EQ(counters.saturated, 1u);
  // The NaN never reached the filter: a small force passes unsaturated afterwards.
  EXPECT_TRUE(std::isfinite(limited_force(law, spring_force_view(0.0), 675.0, counters)));
  EXPECT_EQ(counters.rejected, 1u);
}

TEST(SpringForceFeedback, DampsTheFreeVibrationInTheInProcessLoop) {
  const SystemParams& params = test::shipped_params();
  const Scenario scenario = test::shipped_scenario("free_vibration");
  SystemParams off = params;
  set_parameter(off, kSectionAt + ".gain", "0");
  const auto damped = run_with_law<SpringForceFeedback>(params, scenario, "spring_force_feedback");
  const auto undamped = run_with_law<SpringForceFeedback>(off, scenario, "spring_force_feedback");
  ASSERT_EQ(damped.size(), undamped.size());
  // The load's velocity over the last half of the run: the damped swing has died away.
  auto late_swing = [](const std::vector<TickRecord>& trace) {
    double peak = 0;
    for (std::size_t k = trace.size() / 2; k < trace.size(); ++k)
      peak = std::max(peak, std::fabs(trace[k].load_velocity_mps));
    return peak;
  };
  EXPECT_LT(late_swing(damped), 0.1 * late_swing(undamped));
}

}  // namespace
}  // namespace pmlsm
