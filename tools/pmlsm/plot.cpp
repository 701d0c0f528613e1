// `pmlsm plot`: PNG plots from a recording (gnuplot): velocities, forces and the load's phase
// plane. The force the drive applied (MotorFeedback) is drawn with the commands, and the ticks
// at which the drive had its force off (STATUS_SAFE_STATE or STATUS_FAULT, or a power state
// other than operation enabled) are a red band on both time plots, so a run spent at zero
// force is seen at a glance; the titles and the tool's output give their count. Samples are decoded from the file's own
// omgidl schemas, so a recording made by an older build still plots as long as the field names are there. A truncated
// or corrupt file gives plots of what is whole and a list of what is not.

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>

#include "DriveState.h"
#include "MotorFeedback.h"
#include "commands.hpp"
#include "tool_support.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"
#include "pmlsm/mcap/mcap.hpp"
#include "run_validity.hpp"

namespace pmlsm::tools {
namespace {

struct PlotOptions {
  std::string file;
  std::string output_dir;
};

/// The columns plotted from one topic: time [s] first, then these fields.
struct TopicColumns {
  const char* topic;
  std::vector<const char*> fields;
};

const std::vector<TopicColumns>& plotted() {
  static const std::vector<TopicColumns> kColumns = {
      {"/pmlsm/velocity_reference", {"v_ref_mps"}},
      {"/pmlsm/motor_feedback", {"velocity_mps", "applied_force_n", "status", "power_state"}},
      {"/pmlsm/plant_truth", {"load_velocity_mps", "load_position_m", "motor_position_m", "spring_force_n"}},
      {"/pmlsm/estimated_state", {"v_load_mps", "spring_force_n"}},
      {"/pmlsm/force_command", {"force_n", "pi_force_n", "compensation_force_n"}},
  };
  return kColumns;
}

struct Series {
  const TopicColumns* columns = nullptr;
  std::optional<introspect::MessageSchema> schema;
  std::ofstream data;
  std::uint64_t rows = 0;
  std::uint64_t undecodable = 0;
  std::string first_error;
};

namespace fb = pmlsm_msgs::msg::MotorFeedback_Constants;
namespace ds = pmlsm_msgs::msg::DriveState_Constants;
constexpr std::uint32_t kForceOffStatus = fb::STATUS_SAFE_STATE | fb::STATUS_FAULT;

// The drive had its force off at this report (the evaluator's verdict, RunValidity).
bool force_off(double status, double power_state) {
  return !node::force_applied({static_cast<std::uint32_t>(status), static_cast<std::uint8_t>(power_state), 0});
}

std::string data_path(const std::filesystem::path& dir, const std::string& topic) {
  return (dir / (topic.substr(std::string("/pmlsm/").size()) + ".dat")).string();
}

/// Ticks of the drive's reports with the force off, of all it reported.
struct ForceOffTicks {
  std::uint64_t off = 0;
  std::uint64_t reported = 0;
  std::uint64_t first_off_tick = 0;
};

/// What a recording gave: one data file per plotted topic (closed), the force-off count and
/// what of the file was not whole.
struct PlotData {
  std::map<std::string, Series> by_topic;
  ForceOffTicks force_off;
  mcap::ReadReport report;

  bool has_rows(const char* topic) const {
    const auto found = by_topic.find(topic);
    return found != by_topic.end() && found->second.rows > 0;
  }
};

/// Opens the series' data file once its channel's schema parses; false (said on stderr) when not.
bool open_plot_series(Series& s, const mcap::Channel& channel, const mcap::Schema* schema,
                      const std::filesystem::path& dir) {
  const std::string& topic = channel.topic;
  std::string why;
  if (recorded_channel(channel, schema, &s.schema, why) == nullptr) {
    std::cerr << "pmlsm plot: " << topic << ": not plotted: " << why << "\n";
    return false;
  }
  s.data.open(data_path(dir, topic));
  return true;
}

/// One row of the series' data file: time [s], then its fields; false when the sample has no time.
bool write_plot_row(Series& s, const introspect::Decoded& decoded) {
  const auto* time = decoded.find("stamp.sim_time_ns");
  if (!decoded.ok() || time == nullptr) {
    if (s.undecodable++ == 0) s.first_error = decoded.ok() ? "no stamp.sim_time_ns" : decoded.error;
    return false;
  }
  s.data << *time->as_double() * 1e-9;
  for (const char* field : s.columns->fields) {
    const auto* f = decoded.find(field);
    const auto v = f != nullptr ? f->as_double() : std::nullopt;
    s.data << ' ';
    if (v) {
      s.data << *v;
    } else {
      s.data << "NaN";  // gnuplot leaves a gap
    }
  }
  s.data << '\n';
  ++s.rows;
  return true;
}

void count_force_off(const introspect::Decoded& feedback, ForceOffTicks& count) {
  const auto* status = feedback.find("status");
  const auto* power = feedback.find("power_state");
  const auto* tick = feedback.find("stamp.tick");
  if (status == nullptr || power == nullptr || !status->as_double() || !power->as_double()) return;
  ++count.reported;
  if (!force_off(*status->as_double(), *power->as_double())) return;
  if (count.off++ == 0 && tick != nullptr && tick->as_double()) {
    count.first_off_tick = static_cast<std::uint64_t>(*tick->as_double());
  }
}

/// Reads `file` into data files in `dir`, one per plotted topic. @throws UsageError when unreadable.
PlotData read_plot_data(const std::string& file, const std::filesystem::path& dir) {
  PlotData data;
  for (const auto& c : plotted()) data.by_topic[c.topic].columns = &c;
  std::map<std::uint16_t, mcap::Schema> schemas;
  std::map<std::uint16_t, Series*> by_channel;
  const Series* feedback_series = &data.by_topic["/pmlsm/motor_feedback"];

  mcap::ReadCallbacks callbacks;
  callbacks.on_schema = [&](const mcap::Schema& s) { schemas[s.id] = s; };
  callbacks.on_channel = [&](const mcap::Channel& c) {
    const auto found = data.by_topic.find(c.topic);
    const auto schema = schemas.find(c.schema_id);
    if (found == data.by_topic.end()) return;
    if (open_plot_series(found->second, c, schema != schemas.end() ? &schema->second : nullptr, dir)) {
      by_channel[c.id] = &found->second;
    }
  };
  callbacks.on_message = [&](const mcap::Message& m) {
    const auto found = by_channel.find(m.channel_id);
    if (found == by_channel.end()) return;
    Series& s = *found->second;
    const auto decoded = s.schema->decode(m.data, m.size);
    if (write_plot_row(s, decoded) && &s == feedback_series) count_force_off(decoded, data.force_off);
  };
  data.report = [&] {
    try {
      return mcap::read(file, callbacks);
    } catch (const std::runtime_error& e) {
      throw UsageError(e.what());
    }
  }();
  for (auto& [topic, s] : data.by_topic) s.data.close();
  return data;
}

std::string quoted_data_path(const std::filesystem::path& dir, const char* topic) {
  return "'" + data_path(dir, topic) + "'";
}

/// One gnuplot `plot` of `lines`, each continued on its own line.
std::string gnuplot_plot_command(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += (out.empty() ? "plot " : ", \\\n     ") + l;
  return out + "\n";
}

/// The drive's force-off ticks for the time plots' titles ("" when there were none).
std::string force_off_title(const ForceOffTicks& count) {
  if (count.off == 0) return "";
  char text[160];
  std::snprintf(text, sizeof text, " - DRIVE FORCE OFF for %llu of %llu ticks from tick %llu",
                static_cast<unsigned long long>(count.off), static_cast<unsigned long long>(count.reported),
                static_cast<unsigned long long>(count.first_off_tick));
  return text;
}

/// The red band of the ticks with the force off: first on every time plot, under the curves.
std::string force_off_band(const std::filesystem::path& dir) {
  return quoted_data_path(dir, "/pmlsm/motor_feedback") +
         " using 1:(force_off($4, $5)) axes x1y2 with filledcurves x1 lc rgb '#d62728' "
         "title 'drive force off (safe state, fault, not enabled)'";
}

std::vector<std::string> velocity_plot_lines(const PlotData& data, const std::filesystem::path& dir) {
  std::vector<std::string> lines;
  if (data.has_rows("/pmlsm/motor_feedback")) lines.push_back(force_off_band(dir));
  if (data.has_rows("/pmlsm/velocity_reference"))
    lines.push_back(quoted_data_path(dir, "/pmlsm/velocity_reference") +
                    " using 1:2 with lines lw 2 lc rgb 'black' title 'V_ref'");
  if (data.has_rows("/pmlsm/motor_feedback"))
    lines.push_back(quoted_data_path(dir, "/pmlsm/motor_feedback") +
                    " using 1:2 with lines lc rgb '#ff7f0e' title 'v_M measured'");
  if (data.has_rows("/pmlsm/plant_truth"))
    lines.push_back(quoted_data_path(dir, "/pmlsm/plant_truth") +
                    " using 1:2 with lines lc rgb '#2ca02c' title 'v_L true'");
  if (data.has_rows("/pmlsm/estimated_state"))
    lines.push_back(quoted_data_path(dir, "/pmlsm/estimated_state") +
                    " using 1:2 with lines dt 2 lc rgb '#1f77b4' title 'v_L estimated'");
  return lines;
}

std::vector<std::string> force_plot_lines(const PlotData& data, const std::filesystem::path& dir) {
  std::vector<std::string> lines;
  if (data.has_rows("/pmlsm/motor_feedback")) {
    lines.push_back(force_off_band(dir));
    lines.push_back(quoted_data_path(dir, "/pmlsm/motor_feedback") +
                    " using 1:3 with lines lw 2 lc rgb '#9467bd' title 'F applied by the drive (previous tick)'");
  }
  if (data.has_rows("/pmlsm/force_command")) {
    const std::string file = quoted_data_path(dir, "/pmlsm/force_command");
    lines.push_back(file + " using 1:2 with lines lc rgb 'black' title 'F command'");
    lines.push_back(file + " using 1:3 with lines lc rgb '#ff7f0e' title 'PI part'");
    lines.push_back(file + " using 1:4 with lines lc rgb '#2ca02c' title 'compensation part'");
  }
  if (data.has_rows("/pmlsm/plant_truth"))
    lines.push_back(quoted_data_path(dir, "/pmlsm/plant_truth") +
                    " using 1:5 with lines lc rgb '#d62728' title 'F_s true'");
  if (data.has_rows("/pmlsm/estimated_state"))
    lines.push_back(quoted_data_path(dir, "/pmlsm/estimated_state") +
                    " using 1:3 with lines dt 2 lc rgb '#1f77b4' title 'F_s estimated'");
  return lines;
}

/// A plot over time into `name`.png titled `name` and the force-off text; false when it has no lines.
bool write_time_plot(std::ostream& gp, const std::filesystem::path& dir, const std::string& name,
                     const std::string& ylabel, const std::string& off_title, const std::vector<std::string>& lines) {
  if (lines.empty()) return false;
  gp << "set output '" << (dir / (name + ".png")).string() << "'\nset xlabel 'time [s]'\nset ylabel '" << ylabel
     << "'\n"
     << "set title '" << name << off_title << "'\n"
     << gnuplot_plot_command(lines);
  return true;
}

/// The load's phase plane from the true states, else from the estimates; false when neither is there.
bool write_phase_plane_plot(std::ostream& gp, const std::filesystem::path& dir, const PlotData& data) {
  if (data.has_rows("/pmlsm/plant_truth")) {
    gp << "set output '" << (dir / "phase_plane.png").string() << "'\nset xlabel 'spring stretch x_L - x_M [m]'\n"
       << "set ylabel 'load velocity v_L [m/s]'\nset title 'load phase plane (true states)'\n"
       << "plot " << quoted_data_path(dir, "/pmlsm/plant_truth")
       << " using ($3-$4):2 with lines lc rgb '#2ca02c' title 'load'\n";
    return true;
  }
  if (data.has_rows("/pmlsm/estimated_state")) {
    gp << "set output '" << (dir / "phase_plane.png").string() << "'\nset xlabel 'estimated spring force F_s [N]'\n"
       << "set ylabel 'estimated load velocity v_L [m/s]'\nset title 'load phase plane (estimates)'\n"
       << "plot " << quoted_data_path(dir, "/pmlsm/estimated_state")
       << " using 3:2 with lines lc rgb '#1f77b4' title 'load'\n";
    return true;
  }
  return false;
}

/// Writes dir/plots.gp; returns the PNGs it makes.
std::vector<std::string> write_plot_script(const std::string& file, const std::filesystem::path& dir,
                                           const PlotData& data) {
  std::ofstream gp(dir / "plots.gp");
  gp << "# Made by pmlsm plot from " << file << "\n"
     << "set terminal pngcairo size 1200,800 noenhanced font ',10'\nset grid\nset key top right\n"
     << "set datafile missing 'NaN'\n"
     // The same verdict in gnuplot, on motor_feedback.dat's status ($4) and power state ($5).
     << "force_off(s, p) = ((int(s) & " << kForceOffStatus
     << ") != 0 || int(p) != " << static_cast<int>(ds::POWER_OPERATION_ENABLED) << ") ? 1 : 0\n"
     << "set y2range [0:1]\nunset y2tics\nset style fill transparent solid 0.2 noborder\n";
  std::vector<std::string> made;
  const std::string off_title = force_off_title(data.force_off);
  if (write_time_plot(gp, dir, "velocities", "velocity [m/s]", off_title, velocity_plot_lines(data, dir)))
    made.push_back("velocities.png");
  if (write_time_plot(gp, dir, "forces", "force [N]", off_title, force_plot_lines(data, dir)))
    made.push_back("forces.png");
  if (write_phase_plane_plot(gp, dir, data)) made.push_back("phase_plane.png");
  return made;
}

/// Undecodable samples per topic and the parts of the file that are not whole, on stderr.
void report_unplotted(const std::string& file, const PlotData& data) {
  for (const auto& [topic, s] : data.by_topic) {
    if (s.undecodable > 0) {
      std::cerr << "pmlsm plot: " << topic << ": " << s.undecodable << " samples not decodable (" << s.first_error
                << ")\n";
    }
  }
  if (!data.report.complete()) {
    std::cerr << "pmlsm plot: " << file << " is not whole; plotted what is:\n";
    for (const auto& p : data.report.problems) std::cerr << "  " << p << "\n";
  }
}

int run_plot(const PlotOptions& o) {
  if (!std::filesystem::exists(o.file)) throw UsageError("no such file: " + o.file);
  const std::filesystem::path dir =
      o.output_dir.empty() ? std::filesystem::path(o.file).replace_extension("").string() + "_plots" : o.output_dir;
  std::filesystem::create_directories(dir);

  const PlotData data = read_plot_data(o.file, dir);
  const std::vector<std::string> made = write_plot_script(o.file, dir, data);
  report_unplotted(o.file, data);
  if (made.empty()) {
    std::cerr << "pmlsm plot: nothing to plot in " << o.file << " (needs one of:";
    for (const auto& c : plotted()) std::cerr << " " << c.topic;
    std::cerr << ")\n";
    return kExitBadConfig;
  }
  if (run_gnuplot(dir / "plots.gp") != 0) {
    std::cerr << "pmlsm plot: gnuplot failed on " << (dir / "plots.gp").string() << "\n";
    return kExitError;
  }
  if (data.force_off.off > 0) {
    std::cout << "drive force off for " << data.force_off.off << " of " << data.force_off.reported
              << " ticks from tick " << data.force_off.first_off_tick << " (red band in the plots)\n";
  }
  for (const auto& png : made) std::cout << (dir / png).string() << "\n";
  return kExitOk;
}

}  // namespace

void add_plot_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<PlotOptions>();
  auto* plot = app.add_subcommand("plot", "PNG plots from a recording: velocities, forces, load phase plane");
  plot->add_option("file", o->file, "MCAP file")->required();
  plot->add_option("-o,--output-dir", o->output_dir, "Folder for the PNGs (default: <file>_plots)");
  plot->callback([o, &exit_code] { exit_code = run_plot(*o); });
}

}  // namespace pmlsm::tools
