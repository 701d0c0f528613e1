#include "evaluator_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_evaluator_command_line(int argc, char** argv, CommonOptions& common, EvaluatorOptions& opt) {
  CLI::App app{"Collects a distributed run's topics per tick, prints the results table, writes the CSV trace"};
  add_common_options(app, common);
  app.add_option("-o,--out", opt.out_dir, "Folder for the CSV trace");
  app.add_option("--header", opt.print_header, "Print the table header (true/false)");
  app.add_option("--label", opt.label, "Names this run in the table and the CSV (<scenario>_<label>.csv), e.g. pi_rnn");
  std::string truth = "required";
  app.add_option("--truth", truth,
                 "required: PlantTruth must come for every tick; optional: a drive without it (a real one, the virtual "
                 "rig in realtime) gets the table from the other topics, the true load's columns n/a")
      ->check(CLI::IsMember({"required", "optional"}))
      ->capture_default_str();
  if (const auto code = parse_command_line(app, argc, argv)) return code;
  opt.truth_optional = truth == "optional";
  return std::nullopt;
}

}  // namespace pmlsm::node
