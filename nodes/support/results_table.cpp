#include "results_table.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>

namespace pmlsm::node {

namespace {
// printf into a string of the length it needs.
__attribute__((format(printf, 1, 2))) std::string format(const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, fmt, args);
  va_end(args);
  std::string text(n > 0 ? static_cast<std::size_t>(n) : 0, '\0');
  if (n > 0) std::vsnprintf(&text[0], text.size() + 1, fmt, again);
  va_end(again);
  return text;
}

std::string seconds_or_never(double s) {
  if (!std::isfinite(s)) return "not settled";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", s);
  return buf;
}
}  // namespace

void print_results_header() {
  std::printf("%-24s %10s %10s %14s %14s %12s %12s %14s %12s %11s\n", "scenario", "cost_true", "cost_est",
              "vib_rms_mm/s", "track_rms_mm/s", "settle_2%_s", "peak_F_N", "est_vL_err_mm/s", "F_appl_rms_N",
              "F_off_ticks");
}

std::string results_row(const std::string& scenario, const ScenarioMetrics& m, const std::string& invalid_reason,
                        bool has_truth) {
  std::string row;
  if (has_truth) {
    row = format("%-24s %10.3f %10.3f %14.3f %14.3f %12s %12.1f %14.3f %12.1f %11llu", scenario.c_str(), m.cost_true,
                 m.cost_estimated, 1e3 * m.load_vibration_rms_mps, 1e3 * m.load_tracking_rms_mps,
                 seconds_or_never(m.load_settling_time_s).c_str(), m.peak_force_command_n,
                 1e3 * m.est_load_velocity_rms_error_mps, m.applied_force_rms_n,
                 static_cast<unsigned long long>(m.force_off_ticks));
  } else {
    row = format("%-24s %10s %10.3f %14s %14s %12s %12.1f %14s %12.1f %11llu  (no PlantTruth)", scenario.c_str(), "n/a",
                 m.cost_estimated, "n/a", "n/a", "n/a", m.peak_force_command_n, "n/a", m.applied_force_rms_n,
                 static_cast<unsigned long long>(m.force_off_ticks));
  }
  if (!invalid_reason.empty()) row += "  INVALID: " + invalid_reason;
  return row;
}

void print_results_row(const std::string& scenario, const ScenarioMetrics& m, const std::string& invalid_reason,
                       bool has_truth) {
  std::printf("%s\n", results_row(scenario, m, invalid_reason, has_truth).c_str());
}

void print_results_footer(const std::string& out_dir) {
  std::printf(
      "cost = sum over the scenario's cost window (the first second; a chirp's sweep) of |V_ref - v_L| "
      "(eq. 23), true and Kalman-estimated "
      "v_L; traces in %s/\n",
      out_dir.c_str());
}

}  // namespace pmlsm::node
