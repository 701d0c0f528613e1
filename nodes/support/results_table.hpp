// The results table the in-process loop and the distributed evaluator print.
#pragma once

#include <string>

#include "pmlsm/sim/metrics.hpp"

namespace pmlsm::node {

void print_results_header();
/// One row of the table (no newline). A run that is not valid (the drive had its force off or
/// was faulted, see RunValidity) keeps its numbers but is marked on the same line:
///   "pulse pi   65.250 ... 29.770  INVALID: drive force off for 1998 ticks from tick 2 (...)"
/// invalid_reason empty: a valid run, the row as before.
/// has_truth false (a drive without PlantTruth): the columns that need the true load (cost_true,
/// vibration, tracking, settling, the estimator's error) read n/a and the row is marked
/// "(no PlantTruth)".
std::string results_row(const std::string& scenario, const ScenarioMetrics& m, const std::string& invalid_reason = "",
                        bool has_truth = true);
/// Prints results_row() and a newline.
void print_results_row(const std::string& scenario, const ScenarioMetrics& m, const std::string& invalid_reason = "",
                       bool has_truth = true);
void print_results_footer(const std::string& out_dir);

}  // namespace pmlsm::node
