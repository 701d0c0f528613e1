// A compensator law added in its own folder (compensators/<name>/, pmlsm/sim/compensator_law.hpp)
// as a component: on the topics of accel_feedback and state_feedback, so it can be launched in
// their place, answering every tick k with CompensatorOutput k (FixedLawComponent). Its parameters
// are its section of the system file, `compensator.<name>`; the entries the law declares live are
// this node's (`pmlsm param set <name> compensator.<name>.<key> V`). The build makes one per law
// from a generated source (cmake/PmlsmCompensators.cmake).
#pragma once

#include <cstdio>
#include <string>
#include <utility>

#include "compensator_command_lines.hpp"
#include "compensator_node.hpp"
#include "pmlsm/sim/compensator_law.hpp"

namespace pmlsm::node {

template <typename Law>
class LawCompensator final : public FixedLawComponent {
 public:
  LawCompensator(const char* name, const ComponentContext& context, CommonOptions common)
      : FixedLawComponent(name, context, std::move(common)),
        section_(law_section(name)),
        law_(rt_.cfg.params.section<typename Law::Params>(section_), rt_.period_s) {}

 private:
  double force(const CompensatorView& view) override { return limited_force(law_, view, force_limit_n_, counters_); }
  void retune(const SystemParams& changed) override {
    law_.set_params(changed.section<typename Law::Params>(section_));
  }
  void report(std::uint64_t answered) override {
    rt_.status.status().rejected(inputs_.rejected() + counters_.rejected);
    std::printf("%s: %llu ticks answered, %llu saturated, %llu rejected, %llu skipped\n", node_name_,
                static_cast<unsigned long long>(answered), static_cast<unsigned long long>(counters_.saturated),
                static_cast<unsigned long long>(inputs_.rejected() + counters_.rejected),
                static_cast<unsigned long long>(inputs_.skipped()));
  }

  std::string section_;
  Law law_;
  LawCounters counters_;
};

/// The factory of the law's component: its command line is the common options.
template <typename Law>
MadeComponent make_law_compensator(const char* name, const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  if (const auto code = parse_law_compensator_command_line(argc, argv, Law::kSummary, common)) return {nullptr, *code};
  return {std::make_unique<LawCompensator<Law>>(name, context, std::move(common))};
}

}  // namespace pmlsm::node
