// `pmlsm sweep FILE`: the robustness sweep (pmlsm/analysis/sweep.hpp) in process on every core: a
// family of plants x compensators x scenarios, a verdict per run, a CSV of every run, a table
// per compensator and scenario, and a heat map per scenario (gnuplot PNG). Exit 0 when every
// run passed (clean, and a compensator cheaper than PI alone on the same plant), 6 otherwise.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "system_file_options.hpp"
#include "commands.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/sweep_file.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/util/data_files.hpp"
#include "pmlsm/analysis/sweep.hpp"
#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

struct SweepOptions {
  std::string file;
  std::string config = data_file("configs/system.yaml");
  std::vector<std::string> set;        ///< --set on the system config (the nominal system)
  std::vector<std::string> sweep_set;  ///< --sweep-set on the sweep file
  std::string out_dir = "out/sweep";
  unsigned threads = 0;
  bool plots = true;
};

// A number for the CSV and the table: "nan" / "inf" as such, so no reader takes them for zeros.
std::string num(double x, const char* format = "%.6g") {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char text[64];
  std::snprintf(text, sizeof text, format, x);
  return text;
}

std::string short_key(const std::string& key_path) { return key_path.substr(key_path.find_last_of('.') + 1); }

void write_csv(const std::filesystem::path& path, const SweepFile& file, const SweepResult& result) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path.string());
  out << "plant,label";
  for (const SweepRange& r : file.spec.ranges) out << "," << r.key_path;
  // With the models identified per plant: what the commissioning found (empty otherwise).
  out << ",identified_load_mass_kg,identified_spring_n_per_m,identified_coulomb_n,identified_viscous_n_s_per_m,"
         "identified_at_bound";
  out << ",compensator,scenario,cost,cost_ratio_to_pi,settling_s,last_to_first_window_cost,"
         "tail_stretch_amplitude_mm,tail_decay_rate_per_s,tail_unforced_amplitude_mm,"
         "saturated_share,saturated_tail_share,tail_force_rms_n,tail_compensation_rms_n,"
         "guard_trip_s,rest_tail,standstill,rest_stretch_peak_um,rest_compensation_rms_n,end_position_error_um,faults,"
         "passed\n";
  for (const SweepRun& run : result.runs) {
    const PlantSample& plant = result.plants[run.plant];
    const RunVerdict& v = run.verdict;
    out << run.plant << "," << plant.label;
    // Plant values and identified models round-trip (%.17g): a row's runs are reproduced exactly
    // by closed_loop with those values --set (the loops are sensitive in the sixth digit).
    for (double value : plant.values) out << "," << num(value, "%.17g");
    if (result.identified.empty()) {
      out << ",,,,,";
    } else {
      const IdentifiedLoad& id = result.identified[run.plant];
      out << "," << num(id.load_mass_kg, "%.17g") << "," << num(id.spring_n_per_m, "%.17g") << ","
          << num(id.coulomb_n, "%.17g") << "," << num(id.viscous_n_s_per_m, "%.17g") << ",\"" << id.at_bound << "\"";
    }
    out << "," << to_string(result.compensators[run.compensator]) << "," << file.spec.scenarios[run.scenario].name
        << "," << num(v.cost) << "," << num(run.cost_ratio_to_pi) << "," << num(v.settling_s) << ","
        << num(v.last_to_first_window_cost) << "," << num(v.tail_stretch_amplitude_m * 1e3) << ","
        << num(v.tail_decay_rate_per_s) << "," << num(v.tail_unforced_amplitude_m * 1e3) << ","
        << num(v.saturated_share) << "," << num(v.saturated_tail_share) << "," << num(v.tail_force_rms_n) << ","
        << num(v.tail_compensation_rms_n) << "," << num(v.guard_trip_s) << "," << (v.rest_tail ? 1 : 0) << ","
        << (v.standstill ? 1 : 0) << "," << num(v.rest_stretch_peak_m * 1e6) << "," << num(v.rest_compensation_rms_n)
        << "," << num(v.end_position_error_m * 1e6) << ",\"" << v.faults() << "\"," << (run.passed ? 1 : 0) << "\n";
  }
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// Per compensator and scenario: how many plants passed, what failed, the spread of the cost
// ratio to PI and the worst plant. Returns the runs that failed.
std::size_t print_table(const SystemParams& nominal, const SweepFile& file, const SweepResult& result) {
  std::printf("\n%-6s %-16s %6s %6s %6s %6s %6s %6s %6s %6s %6s %6s %7s %8s %8s %9s  %s\n", "comp", "scenario",
              "plants", "passed", "cycle", "satur", "guard", "slow", "resid", "chat", "nonfin", "sensor", ">=PI",
              "ratio50", "ratio_max", "settle_max", "worst plant");
  std::size_t failed = 0;
  for (std::size_t c = 0; c < result.compensators.size(); ++c) {
    for (std::size_t s = 0; s < file.spec.scenarios.size(); ++s) {
      std::size_t passed = 0, cycles = 0, saturated = 0, guard = 0, slow = 0, residual = 0, chatter = 0, non_finite = 0,
                  sensor = 0, worse = 0;
      std::vector<double> ratios;
      double worst_ratio = -1, worst_settling = 0;
      std::size_t worst_plant = 0;
      for (std::size_t p = 0; p < result.plants.size(); ++p) {
        const SweepRun& run = result.run(p, c, s);
        const RunVerdict& v = run.verdict;
        passed += run.passed ? 1 : 0;
        cycles += v.limit_cycle ? 1 : 0;
        saturated += v.saturated ? 1 : 0;
        guard += v.guard_trip_s >= 0 ? 1 : 0;
        slow += v.slow ? 1 : 0;
        residual += v.residual ? 1 : 0;
        chatter += v.chatter ? 1 : 0;
        non_finite += v.non_finite ? 1 : 0;
        sensor += v.sensor_failed ? 1 : 0;
        if (c != 0 && !(v.cost < result.run(p, 0, s).verdict.cost)) ++worse;
        ratios.push_back(run.cost_ratio_to_pi);
        const double ratio = std::isnan(run.cost_ratio_to_pi) ? INFINITY : run.cost_ratio_to_pi;
        if (ratio > worst_ratio) {
          worst_ratio = ratio;
          worst_plant = p;
        }
        worst_settling = std::max(worst_settling, std::isnan(v.settling_s) ? INFINITY : v.settling_s);
      }
      failed += result.plants.size() - passed;
      std::sort(ratios.begin(), ratios.end());
      const PlantSample& wp = result.plants[worst_plant];
      std::string where = wp.label + " (";
      for (std::size_t d = 0; d < wp.values.size(); ++d) {
        where += (d ? " " : "") + short_key(file.spec.ranges[d].key_path) + "=" + num(wp.values[d], "%.4g");
      }
      where += ")";
      std::printf("%-6s %-16s %6zu %6s %6zu %6zu %6zu %6zu %6zu %6zu %6zu %6zu %7s %8s %8s %9s  %s\n",
                  to_string(result.compensators[c]), file.spec.scenarios[s].name.c_str(), result.plants.size(),
                  c == 0 ? "-" : std::to_string(passed).c_str(), cycles, saturated, guard, slow, residual, chatter,
                  non_finite, sensor, c == 0 ? "-" : std::to_string(worse).c_str(),
                  num(ratios[ratios.size() / 2], "%.3f").c_str(), num(worst_ratio, "%.3f").c_str(),
                  num(worst_settling, "%.3f").c_str(), c == 0 ? "" : where.c_str());
    }
  }
  if (!result.identified.empty()) {
    // How far the commissioning's load mode landed from the plant's (the truth is the sweep's to know).
    double worst_mode_error = 0, worst_mass_error = 0;
    for (std::size_t p = 0; p < result.plants.size(); ++p) {
      const SystemParams plant = plant_variant(nominal, file.spec, result.plants[p]);
      const double true_mode =
          std::sqrt(plant.plant.mechanics.spring_n_per_m / plant.plant.mechanics.load_mass_kg) / (2 * M_PI);
      worst_mode_error = std::max(worst_mode_error, std::fabs(result.identified[p].load_mode_hz() / true_mode - 1));
      worst_mass_error = std::max(
          worst_mass_error, std::fabs(result.identified[p].load_mass_kg / plant.plant.mechanics.load_mass_kg - 1));
    }
    std::printf("models identified on every plant (%s, PI alone): load mode within %.1f %%, load mass within %.1f %%\n",
                file.identification_scenario_file.c_str(), 100 * worst_mode_error, 100 * worst_mass_error);
  }
  std::printf(
      "passed: clean (no limit cycle, no saturated tail, the guard never tripped, a free vibration settled\n"
      "in time, a standstill (the command at rest long enough up to the end) without residual oscillation\n"
      "(resid) or compensation chatter (chat), finite, no load sensor that failed (sensor)) and a cost\n"
      "(eq. 23) below PI alone's on the same plant; ratio: cost / PI's cost on that plant. A moving\n"
      "reference's end is a limit cycle only beyond PI alone's forced response there. PI alone (none)\n"
      "is the baseline: its faults are shown, not judged.\n");
  return failed;
}

// One PNG per scenario: a panel per compensator over the first two parameters, each plant a
// square coloured by log2(cost / PI's cost) (green: cheaper, red: dearer), a black cross on a
// run that failed its verdict.
void write_plots(const std::filesystem::path& dir, const SweepFile& file, const SweepResult& result,
                 std::vector<std::filesystem::path>& pngs) {
  const auto& ranges = file.spec.ranges;
  const std::string x_key = ranges[0].key_path;
  const std::string y_key = ranges.size() > 1 ? ranges[1].key_path : ranges[0].key_path;
  const std::size_t panels = result.compensators.size() - 1;
  if (panels == 0) return;
  for (std::size_t s = 0; s < file.spec.scenarios.size(); ++s) {
    const std::string name = file.spec.scenarios[s].name;
    const std::filesystem::path data = dir / (name + "_heatmap.dat");
    std::ofstream out(data);
    for (std::size_t c = 1; c < result.compensators.size(); ++c) {
      out << "# " << to_string(result.compensators[c]) << "\n";
      for (std::size_t p = 0; p < result.plants.size(); ++p) {
        const SweepRun& run = result.run(p, c, s);
        const double ratio = run.cost_ratio_to_pi;
        const double log_ratio = std::isfinite(ratio) && ratio > 0 ? std::log2(ratio) : 3.0;
        out << num(result.plants[p].values[0], "%.9g") << " "
            << num(ranges.size() > 1 ? result.plants[p].values[1] : 0.0, "%.9g") << " " << num(log_ratio) << " "
            << (run.passed ? 0 : 1) << "\n";
      }
      out << "\n\n";
    }
    out.close();
    const std::filesystem::path png = dir / (name + "_heatmap.png");
    const std::filesystem::path script = dir / (name + "_heatmap.gp");
    std::ofstream gp(script);
    gp << "set terminal pngcairo size " << 520 * panels << ",480 noenhanced\n"
       << "set output '" << png.string() << "'\n"
       << "set multiplot layout 1," << panels << " title '" << name << ": cost / PI alone on the same plant (log2), "
       << result.plants.size() << " plants" << (result.identified.empty() ? "" : ", models identified on each")
       << "; x: failed its verdict'\n"
       << "set palette defined (-4 '#006837', -1 '#a6d96a', 0 '#ffffbf', 1 '#fdae61', 3 '#a50026')\n"
       << "set cbrange [-4:3]\nset cblabel 'log2(cost / cost PI)'\n"
       << "set xlabel '" << x_key << "'\nset ylabel '" << y_key << "'\nset key off\nset grid\n";
    for (std::size_t c = 1; c < result.compensators.size(); ++c) {
      gp << "set title '" << to_string(result.compensators[c]) << "'\n"
         << "plot '" << data.string() << "' index " << c - 1 << " using 1:2:3 with points pt 5 ps 2.2 palette, "
         << "'' index " << c - 1 << " using 1:($4 > 0 ? $2 : 1/0) with points pt 2 ps 2.2 lw 2 lc rgb 'black'\n";
    }
    gp << "unset multiplot\n";
    gp.close();
    if (run_gnuplot(script) != 0) throw std::runtime_error("gnuplot failed on " + script.string());
    pngs.push_back(png);
  }
}

int run_sweep_command(const SweepOptions& o) {
  const SystemParams nominal = load_system_params(o.config, parse_overrides(o.set));
  const SweepFile file = load_sweep_file(o.file, nominal, parse_overrides(o.sweep_set));
  std::vector<double> weights;
  if (std::find(file.spec.compensators.begin(), file.spec.compensators.end(), CompensatorKind::kRnn) !=
      file.spec.compensators.end()) {
    const RnnWeightsFile w = load_rnn_weights(file.weights_path);
    const std::string misfit = rnn_weights_misfit(w, nominal);
    if (!misfit.empty()) throw ConfigError(file.weights_path + ": " + misfit + " (" + o.config + ")");
    weights = w.weights;
  }
  make_output_folder("sweep: -o", o.out_dir);  // before the runs, not after them
  const std::size_t plants = sample_plants(file.spec).size();
  std::size_t compensators = 1;
  for (CompensatorKind k : file.spec.compensators) compensators += k == CompensatorKind::kNone ? 0 : 1;
  const std::size_t total = plants * compensators * file.spec.scenarios.size();
  const unsigned threads = o.threads != 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());
  std::fprintf(stderr, "sweep: %zu runs (%zu plants x %zu compensators x %zu scenarios) on %u threads\n", total, plants,
               compensators, file.spec.scenarios.size(), threads);
  const auto start = std::chrono::steady_clock::now();
  std::size_t reported = 0;
  const SweepResult result = run_sweep(nominal, file.spec, weights, threads, [&](std::size_t done, std::size_t all) {
    if (done * 10 / all > reported || done == all) {
      reported = done * 10 / all;
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::fprintf(stderr, "sweep: %zu/%zu runs (%zu %%), %.1f s\n", done, all, done * 100 / all, s);
    }
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const std::filesystem::path csv = std::filesystem::path(o.out_dir) / "sweep.csv";
  write_csv(csv, file, result);
  const std::size_t failed = print_table(nominal, file, result);
  std::vector<std::filesystem::path> pngs;
  if (o.plots) write_plots(o.out_dir, file, result, pngs);
  std::printf("%zu runs in %.1f s (%.1f runs/s on %u threads); every run: %s", result.runs.size(), seconds,
              static_cast<double>(result.runs.size()) / seconds, threads, csv.c_str());
  for (const auto& png : pngs) std::printf(", %s", png.c_str());
  std::printf("\n");
  if (failed != 0) {
    std::printf("sweep: %zu runs failed their verdict\n", failed);
    return kExitVerdictFailed;
  }
  std::printf("sweep: every run passed\n");
  return kExitOk;
}

}  // namespace

void add_sweep_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<SweepOptions>();
  CLI::App* cmd = app.add_subcommand(
      "sweep",
      "Robustness sweep in process (no DDS): a plant family x compensators x scenarios, a verdict per run, "
      "a table, a CSV and heat maps (configs/sweeps/*.yaml)");
  cmd->add_option("file", o->file, "Sweep file (YAML)")->required()->check(CLI::ExistingFile);
  add_system_file_options(*cmd, o->config, o->set, "The nominal system (YAML)",
                          "Override a system parameter of the nominal system: key.path=value");
  cmd->add_option("--sweep-set", o->sweep_set, "Override a value of the sweep file: key.path=value")->take_all();
  cmd->add_option("-o,--out", o->out_dir, "Folder for sweep.csv and the heat maps")->capture_default_str();
  cmd->add_option("-j,--jobs", o->threads, "Threads (0: one per core)")->capture_default_str();
  cmd->add_flag("!--no-plots", o->plots, "No heat maps (no gnuplot needed)");
  cmd->callback([o, &exit_code] {
    try {
      exit_code = run_sweep_command(*o);
    } catch (const ConfigError& e) {
      throw UsageError(std::string("config error: ") + e.what());
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("config error: ") + e.what());
    }
  });
}

}  // namespace pmlsm::tools
