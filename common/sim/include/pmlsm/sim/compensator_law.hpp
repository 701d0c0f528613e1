// A compensator law added in its own folder: compensators/<name>/<name>.hpp holds one class and
// the line that registers it,
//
//   PMLSM_COMPENSATOR(spring_force_feedback, SpringForceFeedback);
//
// and the build makes the rest (cmake/PmlsmCompensators.cmake): its parameter section
// `compensator.<name>` in the system file (pmlsm/util/parameter_section.hpp), its program and its
// container type (a component answering CompensatorOutput on the topics every compensator uses,
// nodes/compensator/law_compensator.hpp), its place in the launch agent's and the security
// policy's lists. docs/writing-a-compensator.md walks through one.
//
// A law is a class with:
//   struct Params        its parameters, each with its default as the member's initial value;
//                        static declare(at, self, v, live_at) over real, integer and flag
//                        entries (as every component's, pmlsm/util/parameter_table.hpp); and,
//                        when values must agree with each other, validate()
//   kSummary             one line for its program's --help
//   Law(const Params&, double control_period_s)     throws std::invalid_argument on bad values
//   double step(const CompensatorView&)             the force F_c [N] for the view of tick k
//   void set_params(const Params&)                  a live change at a tick boundary; throws
//                                                   std::invalid_argument and keeps the old ones
// The law never sees a non-finite view, and its force is held within the velocity loop's force
// limit, by the code around it (limited_force), the same in the node and the in-process loop.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/velocity_controller.hpp"
#include "pmlsm/util/parameter_section.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

namespace law_detail {
template <typename T, typename = void>
struct IsLaw : std::false_type {};
template <typename T>
struct IsLaw<T, std::void_t<typename T::Params, decltype(T::kSummary),
                            decltype(T(std::declval<const typename T::Params&>(), 1.0)),
                            decltype(std::declval<double&>() = std::declval<T&>().step(CompensatorView{})),
                            decltype(std::declval<T&>().set_params(std::declval<const typename T::Params&>()))>>
    : std::true_type {};
}  // namespace law_detail

template <typename Law>
inline constexpr bool kIsCompensatorLaw = law_detail::IsLaw<Law>::value;

/// The section a law's parameters have in the system file.
inline std::string law_section(const std::string& name) { return "compensator." + name; }

/// Checks a law's parameters as the system file's reader does (their declared ranges, named
/// `<name>.<key>`), then their validate() when they have one.
/// @throws std::invalid_argument naming the first value refused.
template <typename Params>
void check_law_params(const std::string& name, const Params& params) {
  RangeCheck check;
  Params::declare(name, params, check, nullptr);
  if constexpr (HasValidate<Params>::value) params.validate();
}

struct LawCounters {
  std::uint64_t rejected = 0;   ///< a view or a force not finite: 0 N
  std::uint64_t saturated = 0;  ///< a force beyond the limit: held at it
};

/// The law's force for the view of a tick, as the node and the in-process loop both apply it: a
/// view with a non-finite value is not stepped (0 N, counted), a non-finite force gives 0 N
/// (counted), a force beyond +-force_limit_n is held at the limit (counted).
template <typename Law>
double limited_force(Law& law, const CompensatorView& view, double force_limit_n, LawCounters& counters) {
  if (!all_finite(view.load_accel_mps2, view.v_ref_mps, view.v_load_mps, view.spring_force_n, view.command_mps,
                  view.a_ref_mps2)) {
    ++counters.rejected;
    return 0.0;
  }
  const double force_n = law.step(view);
  if (!std::isfinite(force_n)) {
    ++counters.rejected;
    return 0.0;
  }
  if (std::fabs(force_n) > force_limit_n) {
    ++counters.saturated;
    return std::copysign(force_limit_n, force_n);
  }
  return force_n;
}

/// The in-process loop with the law `name` as the compensator (its Params from the system's
/// section), which the node's distributed trace equals byte for byte.
/// @throws std::invalid_argument from the parameters or the scenario.
template <typename Law>
std::vector<TickRecord> run_with_law(const SystemParams& params, const Scenario& scenario, const std::string& name,
                                     std::uint64_t max_ticks = UINT64_MAX) {
  Law law(params.section<typename Law::Params>(law_section(name)), params.timing.control_period_s);
  const double limit_n = params.velocity_loop.force_limit_n;
  LawCounters counters;
  return run_compensated(
      params, scenario,
      [&](const CompensatorView& view) {
        return clamped_compensation(limited_force(law, view, limit_n, counters), limit_n);
      },
      max_ticks);
}

}  // namespace pmlsm

/// Registers a compensator law, once, in its folder's header (compensators/<name>/<name>.hpp), at
/// the start of a line after the class: name is the folder's and the program's, Law the class.
#define PMLSM_COMPENSATOR(name, Law)             \
  static_assert(::pmlsm::kIsCompensatorLaw<Law>, \
                #name ": " #Law " needs Params, kSummary, Law(Params, period_s), step(view), set_params(Params)")
