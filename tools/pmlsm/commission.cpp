// `pmlsm commission`: the plant's frequency response measured on the drive under its velocity
// loop (pmlsm/analysis/frequency_response_measurement.hpp, commissioning.frequency_response of the
// system file), the two-mass model fitted to it, cross-checked against the time-domain fit of
// `pmlsm identify`, and written into a copy of the system file:
//   pmlsm commission --simulate -o configs/system_commissioned.yaml
//   pmlsm commission --simulate --set plant.mechanics.load_mass_kg=8 --report out/commissioning
// It also reads the velocity loop's margins from the measured open loop (with the configured
// filter slots in it), tunes the PI to commissioning.tuning's margins (--tune writes the gains),
// and verifies the commissioned system as the sweep judges a plant (--verify). The report folder
// gets report.md (the Bode plot and everything printed), response.csv (per line: plant, open and
// closed loop, coherence, the fitted model, the filters), samples.csv (the raw excitation, force
// and velocity per tick), verification.csv, bode.png and bode.gp; --family commissions every
// plant of a sweep file's family instead (family.csv, family_verification.csv, family.png).
// Exit 5 when the measurement ended early (a limit breached, the drive faulted or quick-stopped:
// nothing written); 6 when the response is not coherent enough, the filters leave the loop short
// of its margins, --tune finds no gains or the verification fails (nothing written); 2 on bad
// input.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "commands.hpp"
#include "msg_mapping.hpp"
#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/sweep_file.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/commissioning/commissioning.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/frequency_response_measurement.hpp"
#include "pmlsm/analysis/identification.hpp"
#include "pmlsm/analysis/filter_design.hpp"
#include "pmlsm/sim/live_parameters.hpp"
#include "pmlsm/analysis/loop_tuning.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/util/data_files.hpp"
#include "pmlsm/util/validate.hpp"
#include "run_validity.hpp"
#include "system_file_options.hpp"
#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// The command line: the commissioning's choices, and where it reads and writes.
struct CommissionOptions : CommissioningChoices {
  CommissionOptions() { verify = data_file("configs/sweeps/plant_family.yaml"); }
  double peer_timeout_s = 10.0;  ///< a live drive: how long to wait for its feedback
  const dds::ParticipantOptions* dds_options = nullptr;
  std::string config = data_file("configs/system.yaml");
  std::vector<std::string> set;
  std::string identification = data_file("configs/scenarios/identification.yaml");
  std::string out;                           ///< the system file to write ("": report only)
  std::string report = "out/commissioning";  ///< the report folder (out/ as every tool's output)
  bool plots = true;
  std::string family;  ///< a sweep file: measure every plant of its family instead (--simulate)
  unsigned jobs = 0;   ///< --family: plants commissioned at once (0: one per core)
};

double db(std::complex<double> x) { return 20.0 * std::log10(std::abs(x)); }

double degrees(std::complex<double> x) { return std::arg(x) * 180.0 / kPi; }

/// The measurement on the configured simulated plant, with its progress on stderr.
FrequencyResponseMeasurement measure_on_simulated_plant_with_progress(const SystemParams& configured) {
  return measure_on_simulated_plant(configured, [](const FrequencyResponseMeasurement& m, std::uint64_t tick) {
    const double period_s = m.params().period_s;
    if (tick == 0) {
      std::fprintf(stderr, "commission: measuring the frequency response at %.4f m/s, %zu lines %.2f-%.2f Hz, %.1f s\n",
                   m.offset_velocity_mps(), m.excitation().lines().size(), m.params().min_frequency_hz,
                   m.params().max_frequency_hz, static_cast<double>(m.total_ticks()) * period_s);
    }
    if (tick % 5000 == 0) {
      std::fprintf(stderr, "  %5.1f s of %.1f s (%s)\n", static_cast<double>(tick) * period_s,
                   static_cast<double>(m.total_ticks()) * period_s, measurement_phase_name(m.phase()));
    }
  });
}

namespace msg = pmlsm_msgs::msg;

/// The measurement on a live drive over DDS, in the controller's place (no controller may run: the
/// drive follows one ForceCommand writer): every MotorFeedback answered with the measurement's
/// force for that tick, then zero force until the drive's run ends (no feedback for the peer
/// timeout: a lockstep drive's scenario must outlast the measurement). The drive must be in
/// operation enabled (plant_sim enables itself; `pmlsm drive enable` a real one).
FrequencyResponseMeasurement measure_on_live_drive(const dds::ParticipantOptions& dds_options,
                                                   const SystemParams& configured, double peer_timeout_s) {
  FrequencyResponseMeasurement measurement(frequency_response_params(configured), configured.velocity_pi_params());
  dds::Wakeup wakeup;
  dds::Participant participant(with_node_name(dds_options, "pmlsm_commission", "controller"));
  auto feedback_reader = participant.make_reader(dds::topics::kMotorFeedback, wakeup);
  auto command_writer = participant.make_writer(dds::topics::kForceCommand);
  std::fprintf(stderr, "commission: waiting up to %.1f s for a drive's MotorFeedback on domain %d\n", peer_timeout_s,
               dds_options.domain_id);
  const auto timeout = std::chrono::duration<double>(peer_timeout_s);
  msg::MotorFeedback feedback;
  msg::ForceCommand command;
  std::uint64_t answered = 0;
  bool announced = false;
  auto last_feedback = std::chrono::steady_clock::now();
  while (!dds::stop_requested() && std::chrono::steady_clock::now() - last_feedback < timeout) {
    const auto seen = wakeup.generation();
    while (feedback_reader.take(feedback)) {
      last_feedback = std::chrono::steady_clock::now();
      drive::Measurement m;
      node::from_msg(feedback, m);
      node::DriveTickStatus status;
      node::from_msg(feedback, status);
      // Force applied: operation enabled and out of the safe state, as a run's validity judges it.
      const double force_n = measurement.step(m, node::force_applied(status));
      command.stamp(feedback.stamp());
      command.feedback_tick(feedback.stamp().tick());
      command.force_n(force_n);
      command.pi_force_n(force_n);
      command.compensation_force_n(0.0);
      command.velocity_error_mps(measurement.offset_velocity_mps() - m.velocity_mps);
      command.saturated(false);
      command_writer.write(command);
      if (measurement.finished() && !announced) {
        announced = true;
        std::fprintf(stderr, "commission: the measurement %s at tick %llu; zero force until the drive's run ends\n",
                     measurement.phase() == MeasurementPhase::kDone ? "is done" : "ended early",
                     static_cast<unsigned long long>(feedback.stamp().tick()));
      }
      if (++answered % 5000 == 0) {
        std::fprintf(stderr, "  %llu ticks answered (%s)\n", static_cast<unsigned long long>(answered),
                     measurement_phase_name(measurement.phase()));
      }
    }
    wakeup.wait_for(seen, std::chrono::milliseconds(50));
  }
  command_writer.wait_for_acknowledgments(std::chrono::seconds(1));
  std::fprintf(stderr,
               "commission: %llu ticks answered, %llu excitation ticks held late by the drive (recorded as it held "
               "them); the drive's feedback ended\n",
               static_cast<unsigned long long>(answered), static_cast<unsigned long long>(measurement.late_ticks()));
  return measurement;
}

void write_samples_csv(const std::filesystem::path& path, const FrequencyResponseMeasurement& m) {
  std::ofstream csv(path);
  const bool load = m.has_load_sensor();
  csv << "tick,excitation_n,force_n,velocity_mps" << (load ? ",load_velocity_mps" : "") << '\n';
  char line[160];
  for (std::size_t i = 0; i < m.force_n().size(); ++i) {
    std::snprintf(line, sizeof line, "%zu,%.9g,%.9g,%.9g", i, m.excitation_n()[i], m.force_n()[i], m.velocity_mps()[i]);
    csv << line;
    if (load) {
      std::snprintf(line, sizeof line, ",%.9g", m.load_velocity_mps()[i]);
      csv << line;
    }
    csv << '\n';
  }
  if (!csv) throw std::runtime_error("cannot write " + path.string());
}

/// Per line, with a load sensor: Q = V_L / V_M, its coherence, the fitted corner (see
/// frequency_response.hpp).
void write_load_side_csv(const std::filesystem::path& path, const FrequencyResponseResult& r) {
  std::ofstream csv(path);
  csv << "frequency_hz,load_over_motor_db,load_over_motor_deg,coherence,model_db,model_deg\n";
  const LoadSideFit& fit = *r.load_fit;
  const double w = 2.0 * kPi * fit.anti_resonance_hz;
  char line[200];
  for (const LoadRatioPoint& p : r.load_points) {
    const std::complex<double> s(0.0, 2.0 * kPi * p.frequency_hz);
    const std::complex<double> model = fit.gain * (2.0 * fit.anti_resonance_damping * w * s + w * w) /
                                       (s * s + 2.0 * fit.anti_resonance_damping * w * s + w * w);
    std::snprintf(line, sizeof line, "%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", p.frequency_hz, db(p.ratio), degrees(p.ratio),
                  p.coherence, db(model), degrees(model));
    csv << line;
  }
  if (!csv) throw std::runtime_error("cannot write " + path.string());
}

/// Per line: G, L, T, the coherence, the model; the force command's filters H and the loop with
/// them, H L (what the loop will be once they are in it).
void write_response_csv(const std::filesystem::path& path, const FrequencyResponseResult& r,
                        const FilterChain& filters) {
  std::ofstream csv(path);
  csv << "frequency_hz,plant_db,plant_deg,open_loop_db,open_loop_deg,closed_loop_db,closed_loop_deg,coherence,"
         "model_db,model_deg,filters_db,filters_deg,filtered_open_loop_db,filtered_open_loop_deg\n";
  char line[320];
  for (const FrequencyPoint& p : r.points) {
    const std::complex<double> model = two_mass_response(r.fit, p.frequency_hz);
    const std::complex<double> h = filters.response(p.frequency_hz), filtered = h * p.open_loop();
    std::snprintf(line, sizeof line, "%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n",
                  p.frequency_hz, db(p.plant), degrees(p.plant), db(p.open_loop()), degrees(p.open_loop()),
                  db(p.closed_loop()), degrees(p.closed_loop()), p.coherence, db(model), degrees(model), db(h),
                  degrees(h), db(filtered), degrees(filtered));
    csv << line;
  }
  if (!csv) throw std::runtime_error("cannot write " + path.string());
}

/// bode.gp over response.csv: magnitude, phase and coherence, the modes marked, the loop's margins
/// in the title.
void write_bode_script(const std::filesystem::path& dir, const TwoMassFit& fit, const std::string& margins,
                       bool filters) {
  std::ofstream gp(dir / "bode.gp");
  const std::string with_filters_db = filters ? ", '' every ::1 using 1:11 w l dt 3 lw 2 lc rgb 'black' title 'filters "
                                                "H', '' every ::1 using 1:13 w l dt 2 title 'H L'"
                                              : "";
  const std::string with_filters_deg = filters ? ", '' every ::1 using 1:12 w l dt 3 lw 2 lc rgb 'black' title "
                                                 "'filters H', '' every ::1 using 1:14 w l dt 2 title 'H L'"
                                               : "";
  gp << "set terminal pngcairo size 1200,1000 noenhanced font ',10'\nset output '" << (dir / "bode.png").string()
     << "'\nset datafile separator ','\nset grid\nset logscale x\nset key top right\n"
     << "set arrow from " << fit.anti_resonance_hz << ", graph 0 to " << fit.anti_resonance_hz
     << ", graph 1 nohead dt 2 lc rgb 'gray40'\nset arrow from " << fit.resonance_hz << ", graph 0 to "
     << fit.resonance_hz << ", graph 1 nohead dt 2 lc rgb 'gray40'\n"
     << "set multiplot layout 3,1 title 'frequency response: anti-resonance " << fit.anti_resonance_hz
     << " Hz, resonance " << fit.resonance_hz << " Hz; velocity loop: " << margins << "'\n"
     << "set ylabel 'magnitude [dB]'\nplot '" << (dir / "response.csv").string()
     << "' every ::1 using 1:2 w lp pt 7 ps 0.4 title 'plant G = V/F [m/s/N]', '' every ::1 using 1:9 w l lw 2 "
        "title 'two-mass fit', '' every ::1 using 1:4 w l title 'open loop L', '' every ::1 using 1:6 w l "
        "title 'closed loop T'"
     << with_filters_db << "\n"
     << "set ylabel 'phase [deg]'\nplot '" << (dir / "response.csv").string()
     << "' every ::1 using 1:3 w lp pt 7 ps 0.4 title 'plant G', '' every ::1 using 1:10 w l lw 2 title "
        "'two-mass fit', '' every ::1 using 1:5 w l title 'open loop L', '' every ::1 using 1:7 w l title "
        "'closed loop T'"
     << with_filters_deg << "\n"
     << "set ylabel 'coherence'\nset xlabel 'frequency [Hz]'\nset yrange [0:1.05]\nplot '"
     << (dir / "response.csv").string() << "' every ::1 using 1:8 w lp pt 7 ps 0.4 title 'coherence'\n"
     << "unset multiplot\n";
}

/// The fit's table, with the configured model and (simulated) the plant's true values.
void print_fit(const TwoMassFit& fit, const std::optional<IdentifiedLoad>& time_domain, const SystemParams& configured,
               bool simulate, Transcript& transcript) {
  const auto& model = configured.kalman.model;
  const auto& truth = configured.plant.mechanics;
  say(transcript, "  %-22s %12s %12s %12s%s\n", "", "configured", "frequency", "time domain",
      simulate ? "   simulated plant" : "");
  const auto row = [&](const char* name, double was, double now, double other, double real) {
    say(transcript, "  %-22s %12.6g %12.6g ", name, was, now);
    if (std::isnan(other)) {
      say(transcript, "%12s", "-");
    } else {
      say(transcript, "%12.6g", other);
    }
    if (simulate) say(transcript, " %12.6g (%+.2f %%)", real, 100.0 * (now / real - 1.0));
    say(transcript, "\n");
  };
  const double nan = std::nan("");
  row("motor mass [kg]", model.motor_mass_kg, fit.motor_mass_kg, nan, truth.motor_mass_kg);
  row("load mass [kg]", model.load_mass_kg, fit.load_mass_kg, time_domain ? time_domain->load_mass_kg : nan,
      truth.load_mass_kg);
  row("spring [N/m]", model.spring_n_per_m, fit.spring_n_per_m, time_domain ? time_domain->spring_n_per_m : nan,
      truth.spring_n_per_m);
  row("anti-resonance [Hz]", anti_resonance_hz(model.load_mass_kg, model.spring_n_per_m), fit.anti_resonance_hz,
      time_domain ? time_domain->load_mode_hz() : nan, anti_resonance_hz(truth.load_mass_kg, truth.spring_n_per_m));
  row("resonance [Hz]", resonance_hz(model.motor_mass_kg, model.load_mass_kg, model.spring_n_per_m), fit.resonance_hz,
      nan, resonance_hz(truth.motor_mass_kg, truth.load_mass_kg, truth.spring_n_per_m));
  say(transcript, "  fit: %zu lines, rms log error %.3f; damping: anti-resonance %.4f, resonance %.4f\n",
      fit.lines_used, fit.rms_log_error, fit.anti_resonance_damping, fit.resonance_damping);
}

/// The system file with the commissioned values and the designed filter slots, at o.out.
void write_commissioned(const CommissionOptions& o, const TwoMassFit& fit,
                        const std::vector<std::pair<std::string, double>>& values,
                        const std::vector<ConfigOverride>& text_values, Transcript& transcript) {
  char source[320];
  std::snprintf(source, sizeof source,
                "chosen: commissioned by pmlsm commission from %s (frequency response: anti-resonance %.3f Hz, "
                "resonance %.3f Hz; friction from the time-domain fit)",
                o.simulate ? "the simulated plant" : "the drive", fit.anti_resonance_hz, fit.resonance_hz);
  std::vector<ConfigOverride> written;
  for (const auto& [key, value] : values) written.push_back({key, format_value(value)});
  written.insert(written.end(), text_values.begin(), text_values.end());
  write_system_file_with(o.config, written, source, o.out, parse_overrides(o.set));
  say(transcript, "commission: %s written (%zu values, and %zu set with --set); run the nodes with --config %s\n",
      o.out.c_str(), written.size(), o.set.size(), o.out.c_str());
  if (o.tune || !text_values.empty()) {
    say(transcript, "commission: to a controller already running: pmlsm param load controller %s\n", o.out.c_str());
  }
  const auto wrote = [&](const std::string& key) {
    return std::any_of(text_values.begin(), text_values.end(),
                       [&](const ConfigOverride& v) { return v.key_path == key; });
  };
  if (wrote("compensator.acceleration_feedback.gain_kg")) {
    say(transcript, "commission: to acceleration feedback already running: pmlsm param load accel_feedback %s\n",
        o.out.c_str());
  }
  if (wrote("compensator.rnn.output_scale")) {
    say(transcript, "commission: to the RNN already running: pmlsm param load rnn_compensator %s\n", o.out.c_str());
  }
}

/// A family's totals over its rows.
struct FamilyTally {
  std::size_t plants = 0, failed = 0, filter_on = 0, verification_failed = 0;
  double worst_error_percent[5] = {0, 0, 0, 0, 0};
  double worst_load_side_error_percent = std::nan("");  ///< NaN: no plant measured with a load sensor
  double least_phase_deg = 1e9, least_gain_db = 1e9, worst_cost_ratio = 0;
};

/// One plant's row printed and into family.csv, and counted.
void report_family_row(const std::string& label, const MechanicsParams& m, const FamilyRow& row,
                       const TuningTargets& targets, std::ostream& csv, FamilyTally& tally) {
  const bool met = margins_met(row.tuned, targets);
  const CommissionDecision& d = row.decision;
  tally.failed += met && d.exit_code == kExitOk ? 0 : 1;
  for (int i = 0; i < 5; ++i)
    tally.worst_error_percent[i] = std::max(tally.worst_error_percent[i], std::fabs(row.errors[i]));
  if (std::isfinite(row.load_side_error_percent)) {
    tally.worst_load_side_error_percent =
        std::isfinite(tally.worst_load_side_error_percent)
            ? std::max(tally.worst_load_side_error_percent, std::fabs(row.load_side_error_percent))
            : std::fabs(row.load_side_error_percent);
  }
  tally.least_phase_deg = std::min(tally.least_phase_deg, row.tuned.phase_margin_deg);
  tally.least_gain_db = std::min(tally.least_gain_db, row.tuned.gain_margin_db);
  const bool filtered = d.commissioned && d.commissioned->compensator.state_feedback.output_filter_enabled;
  const double gain_kg = d.commissioned ? d.commissioned->compensator.acceleration_feedback.gain_kg : std::nan("");
  const double rnn_scale = d.commissioned ? d.commissioned->compensator.rnn.output_scale : std::nan("");
  tally.filter_on += filtered ? 1 : 0;
  char verified[64] = "-";
  if (d.verification) {
    tally.verification_failed += d.verification->passed ? 0 : 1;
    tally.worst_cost_ratio = std::max(tally.worst_cost_ratio, d.verification->worst_cost_ratio);
    std::snprintf(verified, sizeof verified, "%zu of %zu pass, worst %.3f x PI",
                  d.verification->runs - d.verification->failed_runs, d.verification->runs,
                  d.verification->worst_cost_ratio);
  } else if (d.exit_code != kExitOk) {
    std::snprintf(verified, sizeof verified, "refused before it");
  }
  std::printf(
      "%-10s %6.2f %7.0f %+12.2f%% %+12.2f%% %+6.2f%% %+6.2f%% %+6.2f%% %8.0f %6.1f deg %5.2f dB %6s %5.0f %5.3g "
      "%s%s\n",
      label.c_str(), m.load_mass_kg, m.spring_n_per_m, row.errors[0], row.errors[1], row.errors[2], row.errors[3],
      row.errors[4], row.tuned_kp_n_s_per_m, row.tuned.phase_margin_deg, row.tuned.gain_margin_db,
      filtered ? "on" : "off", gain_kg, rnn_scale, verified, met ? "" : "  margins missed");
  std::fflush(stdout);
  csv << label << ',' << m.load_mass_kg << ',' << m.spring_n_per_m;
  for (const double e : row.errors) csv << ',' << e;
  csv << ',' << row.tuned_kp_n_s_per_m << ',' << row.tuned.phase_margin_deg << ',' << row.tuned.gain_margin_db << ','
      << (filtered ? "on" : "off") << ',' << gain_kg << ',' << rnn_scale << ','
      << (d.verification ? d.verification->runs : 0) << ',' << (d.verification ? d.verification->failed_runs : 0) << ','
      << (d.verification ? d.verification->worst_cost_ratio : std::nan("")) << ',' << row.load_side_error_percent << ','
      << row.load_sensor_gain << ',' << d.exit_code << '\n';
}

/// The plants of a family commissioned on o.jobs threads (each plant's runs are independent and
/// in process), their rows reported in the family's order as soon as every plant before them is
/// done, so that the output and the files do not depend on the threads.
void commission_plants(const CommissionOptions& o, const SystemParams& nominal, const SweepSpec& spec,
                       const std::vector<PlantSample>& plants, const Scenario& identification, std::ostream& csv,
                       std::ostream& verification_csv, FamilyTally& tally) {
  struct Outcome {
    bool done = false;
    MechanicsParams mechanics;  ///< the plant's, for its row
    std::optional<FamilyRow> row;
    std::string why;
    std::string verification_rows;
  };
  std::vector<Outcome> outcomes(plants.size());
  std::mutex mutex;
  std::size_t reported = 0;
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    for (std::size_t i = next++; i < plants.size(); i = next++) {
      const SystemParams p = plant_variant(nominal, spec, plants[i]);
      Outcome outcome;
      outcome.mechanics = p.plant.mechanics;
      std::ostringstream rows;
      try {
        outcome.row = family_row(o, p, identification, rows, plants[i].label, outcome.why);
      } catch (const std::exception& e) {
        outcome.why = e.what();
      }
      outcome.verification_rows = rows.str();
      outcome.done = true;
      const std::lock_guard<std::mutex> lock(mutex);
      outcomes[i] = std::move(outcome);
      for (; reported < plants.size() && outcomes[reported].done; ++reported) {
        const Outcome& r = outcomes[reported];
        verification_csv << r.verification_rows;
        if (r.row) {
          report_family_row(plants[reported].label, r.mechanics, *r.row, tuning_targets(nominal), csv, tally);
        } else {
          std::printf("%-10s %s\n", plants[reported].label.c_str(), r.why.c_str());
          std::fflush(stdout);
          ++tally.failed;
        }
      }
    }
  };
  const unsigned threads = o.jobs != 0 ? o.jobs : std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < std::min<std::size_t>(threads, plants.size()); ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

/// family.gp over family.csv: six panels over the plants' load mass and spring, each plant a
/// square coloured by one column (the fit's errors, the tuned gain margin, the gains chosen, the
/// verification's worst cost over PI alone), a black cross on a plant that failed.
void write_family_plot_script(const std::filesystem::path& dir, const std::string& family) {
  struct Panel {
    int column;
    const char* title;
  };
  const Panel panels[] = {{4, "anti-resonance error [%]"},
                          {6, "load mass error [%]"},
                          {11, "gain margin at the tuned gains [dB]"},
                          {13, "K_a of acceleration feedback [kg]"},
                          {14, "output scale of the RNN"},
                          {17, "worst cost over PI alone"}};
  std::ofstream gp(dir / "family.gp");
  const std::string csv = (dir / "family.csv").string();
  gp << "set terminal pngcairo size 1500,900 noenhanced font ',10'\nset output '" << (dir / "family.png").string()
     << "'\nset datafile separator ','\nset grid\nset key off\nset palette rgbformulae 33,13,10\n"
     << "set xlabel 'load mass [kg]'\nset ylabel 'spring [N/m]'\nset offsets graph 0.05, graph 0.05, graph 0.05, "
        "graph 0.05\n"
     << "set multiplot layout 2,3 title 'pmlsm commission --family " << family
     << ": each plant commissioned (x: failed)'\n";
  for (const Panel& panel : panels) {
    gp << "set title '" << panel.title << "'\nplot '" << csv << "' every ::1 using 2:3:" << panel.column
       << " with points pt 5 ps 2.2 palette, '' every ::1 using 2:($18 != 0 ? $3 : 1/0) with points pt 2 ps 2.2 lw 2 "
          "lc rgb 'black'\n";
  }
  gp << "unset multiplot\n";
  if (!gp) throw std::runtime_error("cannot write " + (dir / "family.gp").string());
}

/// Every plant of a sweep file's family commissioned in process as `pmlsm commission --simulate`
/// commissions one, with the same options (--tune, --design-filters, --verify): measured, fitted,
/// its velocity PI tuned and measured again at the tuned gains, state feedback's output filter
/// and the compensators' gains decided, the commissioned system verified. A row per plant,
/// family.csv (and family_verification.csv) in the report folder, the largest errors and the
/// smallest margins. Exit 6 when a plant's measurement ends early, its response is refused, its
/// tuned loop misses a margin or its commissioning fails (the verification included).
int run_family(const CommissionOptions& o, const SystemParams& nominal) {
  const SweepFile file = load_sweep_file(o.family, nominal);
  const std::vector<PlantSample> plants = sample_plants(file.spec);
  const Scenario identification = load_scenario(o.identification, nominal.timing.control_period_s);
  const std::filesystem::path dir = o.report;
  std::filesystem::create_directories(dir);
  std::ofstream csv(dir / "family.csv");
  csv << "plant,load_mass_kg,spring_n_per_m,anti_resonance_error_percent,resonance_error_percent,"
         "load_mass_error_percent,spring_error_percent,motor_mass_error_percent,tuned_kp_n_s_per_m,"
         "tuned_phase_margin_deg,tuned_gain_margin_db,state_output_filter,accel_gain_kg,rnn_output_scale,"
         "verified_runs,failed_runs,worst_cost_ratio_to_pi,load_side_anti_resonance_error_percent,load_sensor_gain,"
         "exit_code\n";
  std::ofstream verification_csv;
  if (!o.verify.empty()) {
    verification_csv.open(dir / "family_verification.csv");
    verification_csv << "plant," << kVerificationColumns << '\n';
  }
  const TuningTargets& targets = tuning_targets(nominal);
  std::fprintf(stderr, "commission: %zu plants of %s, each measured twice%s%s\n", plants.size(), o.family.c_str(),
               o.tune ? ", tuned" : "", o.verify.empty() ? "" : (" and verified on " + o.verify).c_str());
  std::printf("%-10s %6s %7s %13s %13s %7s %7s %7s %8s %18s %6s %5s %5s %s\n", "plant", "m_L", "k", "anti-res. err",
              "res. err", "m_L err", "k err", "m_M err", "tuned Kp", "margins at it", "filter", "K_a", "RNN x",
              "verification");
  FamilyTally tally;
  tally.plants = plants.size();
  commission_plants(o, nominal, file.spec, plants, identification, csv, verification_csv, tally);
  const double* worst = tally.worst_error_percent;
  std::printf(
      "family of %zu plants (%s): %zu failed; largest errors: anti-resonance %.2f %%, resonance %.2f %%, "
      "load mass %.2f %%, spring %.2f %%, motor mass %.2f %%; tuned loops measured again: phase margin >= "
      "%.1f deg, gain margin >= %.2f dB (targets %.4g deg, %.4g dB)\n",
      tally.plants, o.family.c_str(), tally.failed, worst[0], worst[1], worst[2], worst[3], worst[4],
      tally.least_phase_deg, tally.least_gain_db, targets.min_phase_margin_deg, targets.min_gain_margin_db);
  if (std::isfinite(tally.worst_load_side_error_percent)) {
    std::printf("the load's side (its sensor): the corner within %.3f %% of sqrt(k / m_L) on every plant\n",
                tally.worst_load_side_error_percent);
  }
  if (o.tune && !o.verify.empty()) {
    std::printf("state feedback's output filter on for %zu of %zu plants\n", tally.filter_on, tally.plants);
  }
  if (!o.verify.empty()) {
    std::printf("verification (%s): %zu plants failed it; largest cost over PI alone %.3f; report %s\n",
                o.verify.c_str(), tally.verification_failed, tally.worst_cost_ratio, dir.string().c_str());
  }
  if (o.plots) {
    csv.close();
    write_family_plot_script(dir, o.family);
    if (run_gnuplot(dir / "family.gp") != 0) {
      throw std::runtime_error("gnuplot failed on " + (dir / "family.gp").string());
    }
    std::printf("plot: %s\n", (dir / "family.png").string().c_str());
  }
  return tally.failed == 0 ? kExitOk : kExitVerdictFailed;
}

/// Every file the commissioning will read, read now, and the folder it will write to: a drive
/// moves and a measurement takes its seconds only when nothing after them can fail on an input.
/// @throws ConfigError (a file that does not load) or UsageError (no folder for -o).
void check_inputs(const CommissionOptions& o, const SystemParams& configured) {
  // The measurement's section checked with the system's period and pole pitch (reading the file
  // checked its entries alone).
  try {
    frequency_response_params(configured).validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(o.config + ": " + kFrequencyResponseSection + "." + e.what());
  }
  if (o.simulate) load_scenario(o.identification, configured.timing.control_period_s);
  if (!o.verify.empty()) {
    const SweepFile sweep = load_sweep_file(o.verify, configured);
    if (!sweep.weights_path.empty()) load_rnn_weights(sweep.weights_path);
  }
  if (!o.out.empty()) require_output_folder("commission: -o", o.out);
}

/// The commissioning; what it prints is kept in `transcript` for the report as well.
int commission(const CommissionOptions& o, Transcript& transcript) {
  if (!o.simulate && !o.family.empty()) throw UsageError("commission: --family needs --simulate");
  const SystemParams configured = load_system_params(o.config, parse_overrides(o.set));
  check_inputs(o, configured);
  if (!o.family.empty()) {
    if (!o.out.empty()) throw UsageError("commission: --family measures a family and writes no system file: drop -o");
    return run_family(o, configured);
  }
  const FrequencyResponseMeasurement measurement =
      o.simulate ? measure_on_simulated_plant_with_progress(configured)
                 : measure_on_live_drive(*o.dds_options, configured, o.peer_timeout_s);
  if (measurement.phase() != MeasurementPhase::kDone) {
    say(transcript, "commission: the measurement ended early: %s; nothing written\n",
        measurement.abort_reason().c_str());
    return kExitSafeState;
  }
  const std::filesystem::path dir = o.report;
  std::filesystem::create_directories(dir);
  write_samples_csv(dir / "samples.csv", measurement);
  FrequencyResponseResult result;
  try {
    result = evaluate_measurement(measurement);
  } catch (const std::invalid_argument& e) {
    say(transcript, "commission: %s; nothing written but %s\n", e.what(), (dir / "samples.csv").string().c_str());
    return kExitVerdictFailed;
  }
  std::optional<IdentifiedLoad> time_domain;
  if (o.simulate) {  // a live drive's: `pmlsm identify` on a recording of its identification run
    std::fprintf(stderr, "commission: the time-domain fit (pmlsm identify) on %s\n", o.identification.c_str());
    const Scenario identification = load_scenario(o.identification, configured.timing.control_period_s);
    time_domain = commission_load(configured, identification, IdentificationParams{});
  }
  say(transcript, "commissioned from %s (%zu lines, %zu below coherence %.2f):\n",
      o.simulate ? "the simulated plant" : "the drive", result.points.size(), result.low_coherence_lines,
      measurement.params().min_coherence);
  print_fit(result.fit, time_domain, configured, o.simulate, transcript);
  if (result.load_fit) {
    const LoadSideFit& l = *result.load_fit;
    say(transcript,
        "the load's side (its sensor against the motor's encoder, %zu lines): anti-resonance %.3f Hz (the motor "
        "side's fit %.3f Hz, %+.2f %%), the load's own damping %.4f, the sensor's gain %.4f, rms log error %.4f\n",
        l.lines_used, l.anti_resonance_hz, result.fit.anti_resonance_hz,
        100.0 * (l.anti_resonance_hz / result.fit.anti_resonance_hz - 1.0), l.anti_resonance_damping, l.gain,
        l.rms_log_error);
  }
  say(transcript, "anti-resonance %.3f Hz\nresonance %.3f Hz\n", result.fit.anti_resonance_hz, result.fit.resonance_hz);
  std::ofstream verification_csv;
  if (!o.verify.empty()) {
    verification_csv.open(dir / "verification.csv");
    verification_csv << kVerificationColumns << '\n';
  }
  const CommissionDecision d = decide(o, configured, result, time_domain, verification_csv, "", transcript);
  const FilterChain filters(d.filters);
  write_response_csv(dir / "response.csv", result, filters);
  if (result.load_fit) write_load_side_csv(dir / "load_side.csv", result);
  if (o.plots) {
    write_bode_script(dir, result.fit, d.loop.margins, !filters.empty());
    if (run_gnuplot(dir / "bode.gp") != 0) throw std::runtime_error("gnuplot failed on " + (dir / "bode.gp").string());
  }
  say(transcript, "report: %s\n", dir.string().c_str());
  if (d.exit_code != kExitOk) return d.exit_code;
  if (!o.out.empty()) write_commissioned(o, result.fit, d.values, d.text_values, transcript);
  return kExitOk;
}

/// The commissioning, then report.md in the report folder (when the measurement made one): the
/// Bode plot and everything printed, so that a run's report stands on its own.
int run_commission(const CommissionOptions& o) {
  Transcript transcript;
  const int code = commission(o, transcript);
  const std::filesystem::path dir = o.report;
  if (o.family.empty() && std::filesystem::is_directory(dir) && !transcript.text.empty()) {
    std::ofstream md(dir / "report.md");
    md << "# Commissioning report\n\n"
       << (code == kExitOk ? "Exit 0." : "Exit " + std::to_string(code) + ": not done.")
       << " The system file: " << (o.out.empty() || code != kExitOk ? "not written" : o.out) << ".\n\n";
    if (o.plots && std::filesystem::exists(dir / "bode.png")) md << "![Bode plot](bode.png)\n\n";
    md << "```\n"
       << transcript.text << "```\n\nThe data: response.csv (per line), samples.csv (per tick)"
       << (std::filesystem::exists(dir / "verification.csv") ? ", verification.csv" : "") << ".\n";
  }
  return code;
}

}  // namespace

void add_commission_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto o = std::make_shared<CommissionOptions>();
  o->dds_options = &dds_options;
  CLI::App* cmd = app.add_subcommand(
      "commission",
      "Commissioning: the plant's frequency response under the velocity loop, the two-mass model fitted to it "
      "(checked against pmlsm identify's time-domain fit), a Bode plot, and a copy of the system file");
  cmd->add_flag("--simulate", o->simulate,
                "Measure the configured (simulated) plant in process (without it: the drive on the DDS domain)");
  cmd->add_option("--peer-timeout-s", o->peer_timeout_s,
                  "A live drive: how long to wait for its feedback (at the start, and its end after the run)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  add_system_file_options(*cmd, o->config, o->set, "The system file whose models are replaced");
  cmd->add_option("--identification", o->identification, "The time-domain fit's scenario (as pmlsm identify's)")
      ->capture_default_str()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--out", o->out, "The system file to write (default: the report only)");
  cmd->add_option("--report", o->report, "The report folder: response.csv, samples.csv, bode.png")
      ->capture_default_str();
  cmd->add_flag("!--no-plots", o->plots, "No Bode plot (no gnuplot needed)");
  cmd->add_option("--verify", o->verify,
                  "The sweep file whose scenarios, compensators and verdict verify the commissioned system")
      ->capture_default_str()
      ->check(CLI::ExistingFile);
  cmd->add_flag_callback(
      "--no-verify", [o] { o->verify.clear(); }, "No verification (the system file is written regardless)");
  cmd->add_flag("--tune", o->tune,
                "Write the velocity PI's gains tuned to commissioning.tuning's margins into the system file too");
  cmd->add_flag("--design-filters", o->design_filters,
                "Design notches for the resonances over the two-mass model that limit the loop's gain, into free "
                "slots of filters.force_command (commissioning.filter_design), tune and write with them");
  cmd->add_option("--family", o->family,
                  "With --simulate: commission every plant of this sweep file's family as one is (--tune, "
                  "--design-filters, --verify alike) and print a row per plant: the fit's errors, the tuned "
                  "margins, the verification")
      ->check(CLI::ExistingFile);
  cmd->add_option("-j,--jobs", o->jobs, "With --family: plants commissioned at once (0: one per core)")
      ->capture_default_str();
  cmd->callback([o, &exit_code] {
    try {
      exit_code = run_commission(*o);
    } catch (const ConfigError& e) {
      throw UsageError(std::string("config error: ") + e.what());
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  });
}

}  // namespace pmlsm::tools
