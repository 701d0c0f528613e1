// The results table the in-process loop and the distributed evaluator print.
#pragma once

#include <string>

#include "pmlsm/sim/metrics.hpp"

namespace pmlsm::node {

void print_results_header();
void print_results_row(const std::string& scenario, const ScenarioMetrics& m);
void print_results_footer(const std::string& out_dir);

}  // namespace pmlsm::node
