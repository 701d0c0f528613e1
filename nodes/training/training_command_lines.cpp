#include "training_command_lines.hpp"
#include "system_file_options.hpp"

#include <unistd.h>

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::string default_worker_id() {
  char host[128] = {};
  gethostname(host, sizeof(host) - 1);
  return std::string(host) + "-" + std::to_string(getpid());
}

std::optional<int> parse_de_trainer_command_line(int argc, char** argv, TrainerOptions& opt) {
  CLI::App app{"Offline weight search of the RNN compensator (DE/rand/1/bin, jDE or CMA-ES)"};
  add_dds_options(app, opt.dds);
  add_system_file_options(app, opt.config_path, opt.overrides);
  app.add_option("-t,--training", opt.training_path, "Training parameters (YAML)")
      ->check(CLI::ExistingFile)
      ->capture_default_str();
  app.add_option("--train-set", opt.training_overrides, "Override a training parameter: key=value (e.g. optimiser=jde)")
      ->take_all();
  app.add_option("-o,--out", opt.out_path, "Weights file written at the end")->capture_default_str();
  app.add_option("--checkpoint", opt.checkpoint_path, "Checkpoint file (default: <out>.checkpoint)");
  app.add_option("--history", opt.history_path,
                 "CSV of best and mean cost per generation (default: <out>.history.csv)");
  app.add_flag("--resume", opt.resume, "Go on from the checkpoint");
  app.add_option("--threads", opt.threads, "Local evaluation threads (used when no worker is there)")
      ->check(CLI::Range(1u, 256u))
      ->capture_default_str();
  app.add_option("--wait-workers", opt.wait_workers, "Wait for this many de_workers before starting");
  app.add_option("--wait-workers-s", opt.wait_workers_s, "How long to wait for them")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--worker-timeout-s", opt.worker_timeout_s, "A worker silent this long is dead")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("--no-progress", opt.no_progress, "No progress bar on stderr");
  app.add_option("--first-version", opt.first_version,
                 "Version of the first NetworkWeights set (each better set: +1). A compensator takes only "
                 "versions above the one it uses: to replace a newer set (a rollback, or a new run after an "
                 "earlier one) start above that version")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--linger-s", opt.linger_s,
                 "Stay on the domain this long after the end, so compensators that start later still get the "
                 "final NetworkWeights (transient-local lives only as long as its writer)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--weights-readers", opt.weights_readers,
                 "Before exiting, wait (up to --wait-workers-s) until this many NetworkWeights readers matched "
                 "and acknowledged the final set: a compensator running meanwhile gets it however late discovery "
                 "found it")
      ->check(CLI::NonNegativeNumber);
  return parse_command_line(app, argc, argv);
}

std::optional<int> parse_de_worker_command_line(int argc, char** argv, WorkerOptions& opt) {
  CLI::App app{"Evaluation worker of the distributed weight search (joins any de_trainer on the domain)"};
  add_dds_options(app, opt.dds);
  app.add_option("--threads", opt.threads, "Evaluations run at once")
      ->check(CLI::Range(1u, 256u))
      ->capture_default_str();
  app.add_option("--id", opt.worker_id, "Worker id (unique on the domain)")->capture_default_str();
  app.add_option("--idle-exit-s", opt.idle_exit_s,
                 "Exit after this long without a request, counted from the first setup (0: run until SIGINT)")
      ->check(CLI::NonNegativeNumber);
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node
