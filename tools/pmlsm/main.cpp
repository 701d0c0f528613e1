// pmlsm: the one command-line tool of the system, in the style of `ros2`:
//   pmlsm topic list|echo|hz|delay   what is on the domain
//   pmlsm record | play | plot       MCAP recordings
//   pmlsm launch FILE ...            the launcher (same options)
//   pmlsm agent ...                  the launch agent of this host (launch_agent)
//   pmlsm drive status|enable|...    the drive's CiA 402 power state
//   pmlsm setpoint VALUE             a live velocity setpoint for the controller
//   pmlsm param list|get|set NODE    a running node's live parameters
//   pmlsm security create|...        the DDS Security keystore
//   pmlsm sweep FILE                 the robustness sweep over a plant family (in process)
//   pmlsm identify [RECORDING]       the load fitted to a commissioning run (a recording or --simulate)
//   pmlsm commission --simulate      frequency response, two-mass fit, Bode plot, system file
#include "pmlsm/util/data_files.hpp"
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "commands.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"
#include "pmlsm/security/policy.hpp"

namespace {

// `pmlsm launch ...` is the launcher beside this program, `pmlsm agent ...` the launch agent,
// given the rest of the command line.
int exec_launcher(int argc, char** argv, int launch_index, const char* program = "launcher") {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::string launcher = (ec ? std::filesystem::path(".") : self.parent_path()) / program;
  std::vector<char*> args{const_cast<char*>(launcher.c_str())};
  for (int i = launch_index + 1; i < argc; ++i) args.push_back(argv[i]);
  args.push_back(nullptr);
  execv(launcher.c_str(), args.data());
  std::cerr << "pmlsm: cannot run " << launcher << ": " << std::strerror(errno) << "\n";
  return pmlsm::kExitError;
}

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word == "launch") return exec_launcher(argc, argv, i);
    if (word == "agent") return exec_launcher(argc, argv, i, "launch_agent");
    if (word.empty() || word[0] != '-') break;  // only global options may come before it
  }

  CLI::App app{"pmlsm: watch, record, replay and plot the PMLSM control system's DDS topics"};
  app.require_subcommand(1);
  pmlsm::dds::ParticipantOptions dds_options;
  dds_options.profiles_file = pmlsm::data_file("configs/dds/profiles.xml");
  app.add_option("--profiles", dds_options.profiles_file, "Fast DDS XML profiles")->capture_default_str();
  app.add_option("--participant-profile", dds_options.participant_profile, "Participant profile in them")
      ->capture_default_str();
  app.add_option("--domain", dds_options.domain_id, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  app.add_option("--node-name", dds_options.node_name, "Participant name others see (default: pmlsm_<command>)");
  // As the nodes' --keystore (nodes/support): an empty value falls back to the environment.
  dds_options.keystore = pmlsm::dds::resolve_keystore("");
  app.add_option_function<std::string>(
      "--keystore", [&dds_options](const std::string& v) { dds_options.keystore = pmlsm::dds::resolve_keystore(v); },
      "DDS Security keystore (default: $PMLSM_KEYSTORE, else open; 'none': open)");
  app.add_option(
      "--identity", dds_options.identity,
      "Identity in the keystore (default: pmlsm_topic, pmlsm_record, pmlsm_play, pmlsm_drive or pmlsm_setpoint)");
  app.add_subcommand(
      "launch", "Starts a launch description: `pmlsm launch FILE [--host H | --agents] ...` (see `launcher --help`)");
  app.add_subcommand("agent",
                     "The launch agent of this host: `pmlsm agent [--host H] [--keystore K | --insecure]` (see "
                     "`launch_agent --help`)");

  int exit_code = pmlsm::kExitOk;
  pmlsm::tools::add_topic_commands(app, dds_options, exit_code);
  pmlsm::tools::add_record_command(app, dds_options, exit_code);
  pmlsm::tools::add_play_command(app, dds_options, exit_code);
  pmlsm::tools::add_plot_command(app, exit_code);
  pmlsm::tools::add_drive_command(app, dds_options, exit_code);
  pmlsm::tools::add_setpoint_command(app, dds_options, exit_code);
  pmlsm::tools::add_param_command(app, dds_options, exit_code);
  pmlsm::tools::add_security_command(app, exit_code);
  pmlsm::tools::add_sweep_command(app, exit_code);
  pmlsm::tools::add_identify_command(app, exit_code);
  pmlsm::tools::add_commission_command(app, dds_options, exit_code);
  pmlsm::tools::add_config_command(app, exit_code);
  pmlsm::tools::add_ethercat_command(app, exit_code);

  pmlsm::dds::install_shutdown_handlers();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : pmlsm::kExitBadConfig;
  } catch (const pmlsm::tools::UsageError& e) {
    std::cerr << "pmlsm: " << e.what() << "\n";
    return pmlsm::kExitBadConfig;
  } catch (const pmlsm::dds::SecurityConfigError& e) {
    std::cerr << "pmlsm: security error: " << e.what() << "\n";
    return pmlsm::kExitBadConfig;
  } catch (const pmlsm::security::SecurityError& e) {
    std::cerr << "pmlsm: security error: " << e.what() << "\n";
    return pmlsm::kExitBadConfig;
  } catch (const std::exception& e) {
    std::cerr << "pmlsm: " << e.what() << "\n";
    return pmlsm::kExitError;
  }
  return exit_code;
}
