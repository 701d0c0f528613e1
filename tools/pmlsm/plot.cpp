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
  static const std::vector<TopicColumns> columns = {
      {"/pmlsm/velocity_reference", {"v_ref_mps"}},
      {"/pmlsm/motor_feedback", {"velocity_mps", "applied_force_n", "status", "power_state"}},
      {"/pmlsm/plant_truth", {"load_velocity_mps", "load_position_m", "motor_position_m", "spring_force_n"}},
      {"/pmlsm/estimated_state", {"v_load_mps", "spring_force_n"}},
      {"/pmlsm/force_command", {"force_n", "pi_force_n", "compensation_force_n"}},
  };
  return columns;
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

int run_plot(const PlotOptions& o) {
  if (!std::filesystem::exists(o.file)) throw UsageError("no such file: " + o.file);
  const std::filesystem::path dir =
      o.output_dir.empty() ? std::filesystem::path(o.file).replace_extension("").string() + "_plots" : o.output_dir;
  std::filesystem::create_directories(dir);

  std::map<std::string, Series> by_topic;
  for (const auto& c : plotted()) by_topic[c.topic].columns = &c;
  std::map<std::uint16_t, mcap::Schema> schemas;
  std::map<std::uint16_t, Series*> by_channel;
  // Ticks of the drive's reports with the force off, of all it reported.
  std::uint64_t force_off_ticks = 0, drive_ticks = 0;
  std::uint64_t first_off_tick = 0;
  const Series* feedback_series = &by_topic["/pmlsm/motor_feedback"];

  mcap::ReadCallbacks callbacks;
  callbacks.on_schema = [&](const mcap::Schema& s) { schemas[s.id] = s; };
  callbacks.on_channel = [&](const mcap::Channel& c) {
    const auto found = by_topic.find(c.topic);
    const auto schema = schemas.find(c.schema_id);
    if (found == by_topic.end() || schema == schemas.end() || schema->second.encoding != "omgidl" ||
        c.message_encoding != "cdr") {
      return;
    }
    Series& s = found->second;
    try {
      s.schema = introspect::MessageSchema::parse(schema->second.data, schema->second.name);
    } catch (const introspect::SchemaError& e) {
      std::cerr << "pmlsm plot: " << c.topic << ": schema not usable: " << e.what() << "\n";
      return;
    }
    s.data.open(data_path(dir, c.topic));
    by_channel[c.id] = &s;
  };
  callbacks.on_message = [&](const mcap::Message& m) {
    const auto found = by_channel.find(m.channel_id);
    if (found == by_channel.end()) return;
    Series& s = *found->second;
    const auto decoded = s.schema->decode(m.data, m.size);
    const auto* time = decoded.find("stamp.sim_time_ns");
    if (!decoded.ok() || time == nullptr) {
      if (s.undecodable++ == 0) s.first_error = decoded.ok() ? "no stamp.sim_time_ns" : decoded.error;
      return;
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
    if (&s == feedback_series) {
      const auto* status = decoded.find("status");
      const auto* power = decoded.find("power_state");
      const auto* tick = decoded.find("stamp.tick");
      if (status != nullptr && power != nullptr && status->as_double() && power->as_double()) {
        ++drive_ticks;
        if (force_off(*status->as_double(), *power->as_double())) {
          if (force_off_ticks++ == 0 && tick != nullptr && tick->as_double()) {
            first_off_tick = static_cast<std::uint64_t>(*tick->as_double());
          }
        }
      }
    }
  };
  const mcap::ReadReport report = [&] {
    try {
      return mcap::read(o.file, callbacks);
    } catch (const std::runtime_error& e) {
      throw UsageError(e.what());
    }
  }();
  for (auto& [topic, s] : by_topic) s.data.close();

  const auto have = [&](const char* topic) { return by_topic[topic].rows > 0; };
  const auto file_of = [&](const char* topic) { return "'" + data_path(dir, topic) + "'"; };
  std::ofstream gp(dir / "plots.gp");
  gp << "# Made by pmlsm plot from " << o.file << "\n"
     << "set terminal pngcairo size 1200,800 noenhanced font ',10'\nset grid\nset key top right\n"
     << "set datafile missing 'NaN'\n"
     // The same verdict in gnuplot, on motor_feedback.dat's status ($4) and power state ($5).
     << "force_off(s, p) = ((int(s) & " << kForceOffStatus
     << ") != 0 || int(p) != " << static_cast<int>(ds::POWER_OPERATION_ENABLED) << ") ? 1 : 0\n"
     << "set y2range [0:1]\nunset y2tics\nset style fill transparent solid 0.2 noborder\n";
  std::vector<std::string> made;
  const bool have_drive = have("/pmlsm/motor_feedback");
  char off_text[160] = "";
  if (force_off_ticks > 0) {
    std::snprintf(off_text, sizeof off_text, " - DRIVE FORCE OFF for %llu of %llu ticks from tick %llu",
                  static_cast<unsigned long long>(force_off_ticks), static_cast<unsigned long long>(drive_ticks),
                  static_cast<unsigned long long>(first_off_tick));
  }
  // First on every time plot, under the curves.
  const std::string off_band = file_of("/pmlsm/motor_feedback") +
                               " using 1:(force_off($4, $5)) axes x1y2 with filledcurves x1 lc rgb '#d62728' "
                               "title 'drive force off (safe state, fault, not enabled)'";
  std::vector<std::string> velocity_lines;
  if (have_drive) velocity_lines.push_back(off_band);
  if (have("/pmlsm/velocity_reference"))
    velocity_lines.push_back(file_of("/pmlsm/velocity_reference") +
                             " using 1:2 with lines lw 2 lc rgb 'black' title 'V_ref'");
  if (have("/pmlsm/motor_feedback"))
    velocity_lines.push_back(file_of("/pmlsm/motor_feedback") +
                             " using 1:2 with lines lc rgb '#ff7f0e' title 'v_M measured'");
  if (have("/pmlsm/plant_truth"))
    velocity_lines.push_back(file_of("/pmlsm/plant_truth") + " using 1:2 with lines lc rgb '#2ca02c' title 'v_L true'");
  if (have("/pmlsm/estimated_state"))
    velocity_lines.push_back(file_of("/pmlsm/estimated_state") +
                             " using 1:2 with lines dt 2 lc rgb '#1f77b4' title 'v_L estimated'");
  const auto join = [](const std::vector<std::string>& lines) {
    std::string out;
    for (const auto& l : lines) out += (out.empty() ? "plot " : ", \\\n     ") + l;
    return out + "\n";
  };
  if (!velocity_lines.empty()) {
    gp << "set output '" << (dir / "velocities.png").string()
       << "'\nset xlabel 'time [s]'\nset ylabel 'velocity [m/s]'\n"
       << "set title 'velocities" << off_text << "'\n"
       << join(velocity_lines);
    made.push_back("velocities.png");
  }
  std::vector<std::string> force_lines;
  if (have_drive) {
    force_lines.push_back(off_band);
    force_lines.push_back(file_of("/pmlsm/motor_feedback") +
                          " using 1:3 with lines lw 2 lc rgb '#9467bd' title 'F applied by the drive (previous tick)'");
  }
  if (have("/pmlsm/force_command")) {
    force_lines.push_back(file_of("/pmlsm/force_command") + " using 1:2 with lines lc rgb 'black' title 'F command'");
    force_lines.push_back(file_of("/pmlsm/force_command") + " using 1:3 with lines lc rgb '#ff7f0e' title 'PI part'");
    force_lines.push_back(file_of("/pmlsm/force_command") +
                          " using 1:4 with lines lc rgb '#2ca02c' title 'compensation part'");
  }
  if (have("/pmlsm/plant_truth"))
    force_lines.push_back(file_of("/pmlsm/plant_truth") + " using 1:5 with lines lc rgb '#d62728' title 'F_s true'");
  if (have("/pmlsm/estimated_state"))
    force_lines.push_back(file_of("/pmlsm/estimated_state") +
                          " using 1:3 with lines dt 2 lc rgb '#1f77b4' title 'F_s estimated'");
  if (!force_lines.empty()) {
    gp << "set output '" << (dir / "forces.png").string() << "'\nset xlabel 'time [s]'\nset ylabel 'force [N]'\n"
       << "set title 'forces" << off_text << "'\n"
       << join(force_lines);
    made.push_back("forces.png");
  }
  if (have("/pmlsm/plant_truth")) {
    gp << "set output '" << (dir / "phase_plane.png").string() << "'\nset xlabel 'spring stretch x_L - x_M [m]'\n"
       << "set ylabel 'load velocity v_L [m/s]'\nset title 'load phase plane (true states)'\n"
       << "plot " << file_of("/pmlsm/plant_truth") << " using ($3-$4):2 with lines lc rgb '#2ca02c' title 'load'\n";
    made.push_back("phase_plane.png");
  } else if (have("/pmlsm/estimated_state")) {
    gp << "set output '" << (dir / "phase_plane.png").string() << "'\nset xlabel 'estimated spring force F_s [N]'\n"
       << "set ylabel 'estimated load velocity v_L [m/s]'\nset title 'load phase plane (estimates)'\n"
       << "plot " << file_of("/pmlsm/estimated_state") << " using 3:2 with lines lc rgb '#1f77b4' title 'load'\n";
    made.push_back("phase_plane.png");
  }
  gp.close();

  for (const auto& [topic, s] : by_topic) {
    if (s.undecodable > 0) {
      std::cerr << "pmlsm plot: " << topic << ": " << s.undecodable << " samples not decodable (" << s.first_error
                << ")\n";
    }
  }
  if (!report.complete()) {
    std::cerr << "pmlsm plot: " << o.file << " is not whole; plotted what is:\n";
    for (const auto& p : report.problems) std::cerr << "  " << p << "\n";
  }
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
  if (force_off_ticks > 0) {
    std::cout << "drive force off for " << force_off_ticks << " of " << drive_ticks << " ticks from tick "
              << first_off_tick << " (red band in the plots)\n";
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
