// de_trainer: the offline weight search of section 3.3. Each evaluation is a
// closed-loop run of the full plant with the RNN in the loop, scored by (23).
// Generations go to de_worker processes on the domain when there are any, to
// local threads otherwise. Every generation is checkpointed; --resume goes on
// from the checkpoint. Publishes TrainerProgress every generation, and the
// best NetworkWeights (reliable, transient-local) when it improves; writes the
// weights file at the end (and on SIGINT, after the current generation).
#include "pmlsm/util/data_files.hpp"
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <thread>

#include "NetworkWeightsPubSubTypes.h"
#include "TrainerProgressPubSubTypes.h"
#include "node_support.hpp"
#include "pmlsm/optim/pagmo_optimisers.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "training_support.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;

bool file_exists(const std::string& path) { return std::ifstream(path).good(); }

/// One line that rewrites itself on a terminal; a plain line every 10 % otherwise.
class ProgressBar {
 public:
  explicit ProgressBar(bool enabled) : enabled_(enabled), tty_(isatty(fileno(stderr)) != 0) {}
  void update(const OptimiserReport& r, std::uint64_t budget, double elapsed_s, double eta_s) {
    if (!enabled_) return;
    const double fraction = std::min(1.0, static_cast<double>(r.evaluations) / static_cast<double>(budget));
    const int decile = static_cast<int>(fraction * 10);
    if (!tty_ && decile == last_decile_) return;
    last_decile_ = decile;
    char bar[31];
    const int filled = static_cast<int>(fraction * 30);
    for (int i = 0; i < 30; ++i) bar[i] = i < filled ? '#' : '.';
    bar[30] = '\0';
    std::fprintf(stderr, "%s[%s] %3.0f%% gen %llu  evals %llu/%llu  best %.3f  mean %.3f  %.0f s, %.0f s left%s",
                 tty_ ? "\r" : "", bar, 100 * fraction, static_cast<unsigned long long>(r.generation),
                 static_cast<unsigned long long>(r.evaluations), static_cast<unsigned long long>(budget),
                 r.best_cost, r.mean_cost, elapsed_s, eta_s, tty_ ? "  " : "\n");
    std::fflush(stderr);
  }
  void finish() {
    if (enabled_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  bool enabled_;
  bool tty_;
  int last_decile_ = -1;
};

int run(int argc, char** argv) {
  CLI::App app{"Offline weight search of the RNN compensator (DE/rand/1/bin, jDE or CMA-ES)"};
  pdds::ParticipantOptions dds_options;
  node::add_dds_options(app, dds_options);
  std::string config_path = pmlsm::data_file("configs/system.yaml");
  std::string training_path = pmlsm::data_file("configs/training.yaml");
  std::vector<std::string> overrides, training_overrides;
  std::string out_path = "out/rnn_weights.yaml";
  std::string checkpoint_path;
  std::string history_path;
  bool resume = false;
  bool no_progress = false;
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  std::size_t wait_workers = 0;
  double wait_workers_s = 10.0;
  double worker_timeout_s = 1.5;
  app.add_option("-c,--config", config_path, "System parameters (YAML)")->check(CLI::ExistingFile)->capture_default_str();
  app.add_option("--set", overrides, "Override a system parameter: key.path=value")->take_all();
  app.add_option("-t,--training", training_path, "Training parameters (YAML)")->check(CLI::ExistingFile)->capture_default_str();
  app.add_option("--train-set", training_overrides, "Override a training parameter: key=value (e.g. optimiser=jde)")->take_all();
  app.add_option("-o,--out", out_path, "Weights file written at the end")->capture_default_str();
  app.add_option("--checkpoint", checkpoint_path, "Checkpoint file (default: <out>.checkpoint)");
  app.add_option("--history", history_path, "CSV of best and mean cost per generation (default: <out>.history.csv)");
  app.add_flag("--resume", resume, "Go on from the checkpoint");
  app.add_option("--threads", threads, "Local evaluation threads (used when no worker is there)")->check(CLI::Range(1u, 256u))->capture_default_str();
  app.add_option("--wait-workers", wait_workers, "Wait for this many de_workers before starting");
  app.add_option("--wait-workers-s", wait_workers_s, "How long to wait for them")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--worker-timeout-s", worker_timeout_s, "A worker silent this long is dead")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_flag("--no-progress", no_progress, "No progress bar on stderr");
  std::uint64_t first_version = 1;
  app.add_option("--first-version", first_version,
                 "Version of the first NetworkWeights set (each better set: +1). A compensator takes only "
                 "versions above the one it uses: to replace a newer set (a rollback, or a new run after an "
                 "earlier one) start above that version")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  double linger_s = 0;
  app.add_option("--linger-s", linger_s,
                 "Stay on the domain this long after the end, so compensators that start later still get the "
                 "final NetworkWeights (transient-local lives only as long as its writer)")
      ->check(CLI::NonNegativeNumber);
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  if (checkpoint_path.empty()) checkpoint_path = out_path + ".checkpoint";
  if (history_path.empty()) history_path = out_path + ".history.csv";

  std::vector<ConfigOverride> parsed_overrides, parsed_training_overrides;
  for (const auto& o : overrides) parsed_overrides.push_back(ConfigOverride::parse(o));
  for (const auto& o : training_overrides) parsed_training_overrides.push_back(ConfigOverride::parse(o));
  const SystemParams params = load_system_params(config_path, parsed_overrides);
  TrainingParams training =
      load_training_params(training_path, params.timing.control_period_s, parsed_training_overrides);
  if (training.identify_models) {
    training.plants = commissioned_plants(params, std::move(training.plants), training.identification_scenario);
    for (const PlantVariant& plant : training.plants) {
      if (!plant.commission) {
        std::printf("de_trainer: plant %s on the configured models (commission: false)\n", plant.name.c_str());
        continue;
      }
      std::printf("de_trainer: plant %s commissioned (%s):", plant.name.c_str(),
                  training.identification_scenario_file.c_str());
      for (const auto& [key, value] : plant.models) std::printf(" %s=%.6g", key.c_str(), value);
      std::printf("\n");
    }
  }
  if (resume && !file_exists(checkpoint_path)) {
    throw ConfigError("--resume: no checkpoint at " + checkpoint_path);
  }

  const auto cost = training.judge_runs
                        ? std::make_shared<const RnnCost>(params, training.scenarios, training.cost_velocity,
                                                          training.plants, training.plant_objective, training.verdict)
                        : std::make_shared<const RnnCost>(params, training.scenarios, training.cost_velocity,
                                                          training.plants, training.plant_objective);
  DeParams de;
  de.population_size = training.population_size;
  de.dimension = cost->dimension();
  de.mutation_factor = training.mutation_factor;
  de.crossover_rate = training.crossover_rate;
  de.init_lower = training.init_lower;
  de.init_upper = training.init_upper;
  de.seed = training.seed;
  if (training.start == TrainingStart::kAccelerationFeedback) {
    de.first_member = rnn_weights_from_acceleration_feedback(params);
  }

  dds_options.node_name = "de_trainer";
  pdds::Wakeup wakeup;  // outlives the participant, whose listeners signal it
  pdds::Participant participant(dds_options);
  const std::uint64_t run_id =
      static_cast<std::uint64_t>(wall_time_ns()) ^ (static_cast<std::uint64_t>(getpid()) << 40);
  auto setup_writer = participant.make_writer<msg::TrainingSetupPubSubType>(pdds::topics::kTrainingSetup);
  setup_writer.write(training::make_setup(run_id, config_path, overrides, training));
  auto progress_writer = participant.make_writer<msg::TrainerProgressPubSubType>(pdds::topics::kTrainerProgress);
  auto weights_writer = participant.make_writer<msg::NetworkWeightsPubSubType>(pdds::topics::kNetworkWeights);
  training::DdsEvaluator evaluator(participant, wakeup, [cost](const std::vector<double>& w) { return (*cost)(w); },
                                   threads, run_id,
                                   std::chrono::milliseconds(static_cast<long long>(worker_timeout_s * 1000)));
  if (wait_workers > 0) {
    const std::size_t live = evaluator.wait_for_workers(
        wait_workers, std::chrono::milliseconds(static_cast<long long>(wait_workers_s * 1000)));
    std::printf("de_trainer: %zu of %zu worker(s) joined\n", live, wait_workers);
    if (live < wait_workers) return kExitPeerMissing;
  }

  std::unique_ptr<Optimiser> optimiser = make_optimiser(parse_optimiser_kind(training.optimiser), de, evaluator);
  if (resume) {
    optimiser->load_checkpoint(checkpoint_path);
    std::printf("de_trainer: resumed from %s at generation %llu, %llu evaluations\n", checkpoint_path.c_str(),
                static_cast<unsigned long long>(optimiser->report().generation),
                static_cast<unsigned long long>(optimiser->report().evaluations));
  }
  std::printf("de_trainer: %s, NP %llu, D %zu, F %.2f, CR %.2f, seed %llu, start %s, budget %llu evaluations, cost on %s V_load, run %llu\n",
              optimiser->name().c_str(), static_cast<unsigned long long>(de.population_size), de.dimension,
              de.mutation_factor, de.crossover_rate, static_cast<unsigned long long>(de.seed), to_string(training.start),
              static_cast<unsigned long long>(training.max_evaluations), to_string(training.cost_velocity),
              static_cast<unsigned long long>(run_id));

  std::ofstream history(history_path, resume ? std::ios::app : std::ios::trunc);
  if (!history) throw std::runtime_error(history_path + ": cannot write");
  if (!resume) history << "generation,evaluations,best_cost,mean_cost,elapsed_s,best_weight_0\n";

  ProgressBar bar(!no_progress);
  msg::TrainerProgress progress;
  progress.optimiser(optimiser->name().substr(0, 32));
  progress.population_size(static_cast<std::uint32_t>(de.population_size));
  progress.max_generations(0);
  msg::NetworkWeights weights_msg;
  for (int size : params.compensator.rnn_layer_sizes) weights_msg.layer_sizes().push_back(static_cast<std::uint16_t>(size));
  weights_msg.input_scale(params.compensator.rnn_input_scale_s2_per_m);
  weights_msg.gain_n(params.compensator.rnn_gain_n);
  std::uint64_t version = first_version - 1;  // the last published; 0 before the first
  double published_cost = std::numeric_limits<double>::infinity();

  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t start_evaluations = optimiser->report().evaluations;
  OptimiserReport report = optimiser->report();
  bool interrupted = false;
  while (report.evaluations < training.max_evaluations) {
    if (pdds::stop_requested()) {
      interrupted = true;
      break;
    }
    report = optimiser->step();
    optimiser->save_checkpoint(checkpoint_path);
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double rate = static_cast<double>(report.evaluations - start_evaluations) / std::max(elapsed, 1e-9);
    const double eta = static_cast<double>(training.max_evaluations - std::min(training.max_evaluations, report.evaluations)) / std::max(rate, 1e-9);
    char line[256];
    std::snprintf(line, sizeof(line), "%llu,%llu,%.17g,%.17g,%.3f,%.17g\n",
                  static_cast<unsigned long long>(report.generation),
                  static_cast<unsigned long long>(report.evaluations), report.best_cost, report.mean_cost, elapsed,
                  report.best.empty() ? 0.0 : report.best[0]);
    history << line << std::flush;
    if (report.best_cost < published_cost) {
      published_cost = report.best_cost;
      weights_msg.version(++version);
      weights_msg.weights(report.best);
      weights_msg.cost(report.best_cost);
      weights_msg.source(("de_trainer gen " + std::to_string(report.generation)).substr(0, 64));
      weights_msg.stamp(node::make_stamp(report.generation, params.timing.control_period_s));
      weights_writer.write(weights_msg);
    }
    progress.stamp(node::make_stamp(report.generation, params.timing.control_period_s));
    progress.generation(report.generation);
    progress.evaluations(report.evaluations);
    progress.best_weights_version(version);
    progress.best_cost(report.best_cost);
    progress.mean_cost(report.mean_cost);
    progress.elapsed_s(elapsed);
    progress.eta_s(eta);
    progress_writer.write(progress);
    bar.update(report, training.max_evaluations, elapsed, eta);
    if (training.target_cost > 0 && report.best_cost <= training.target_cost) break;
  }
  bar.finish();
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (report.best.empty()) throw std::runtime_error("interrupted before the first generation: no weights");

  RnnWeightsFile file;
  file.layer_sizes = params.compensator.rnn_layer_sizes;
  file.input_scale_s2_per_m = params.compensator.rnn_input_scale_s2_per_m;
  file.on_reference_error = params.compensator.rnn_on_reference_error;
  file.gain_n = params.compensator.rnn_gain_n;
  file.cost = report.best_cost;
  // The system overrides the search ran with belong to its provenance: the same command remakes
  // the same bits, and a check of the file's cost must judge it as it was searched.
  std::string searched_with;
  for (const auto& o : overrides) searched_with += " " + o;
  file.source = optimiser->name() + " seed " + std::to_string(de.seed) + " gen " + std::to_string(report.generation) +
                " evals " + std::to_string(report.evaluations) + " (" + to_string(training.cost_velocity) +
                " V_load, " + training_path + (searched_with.empty() ? "" : ", --set" + searched_with) + ")";
  file.weights = report.best;
  save_rnn_weights(out_path, file);
  const auto& c = evaluator.counters();
  std::printf("de_trainer: %s after %llu generations, %llu evaluations (%llu remote, %llu local, %llu re-queued, %llu worker(s) lost) in %.1f s: %.0f evaluations/s\n",
              interrupted ? "interrupted" : "done", static_cast<unsigned long long>(report.generation),
              static_cast<unsigned long long>(report.evaluations), static_cast<unsigned long long>(c.remote_evaluations),
              static_cast<unsigned long long>(c.local_evaluations), static_cast<unsigned long long>(c.requeued),
              static_cast<unsigned long long>(c.workers_lost), elapsed,
              static_cast<double>(report.evaluations - start_evaluations) / std::max(elapsed, 1e-9));
  std::printf("de_trainer: best cost %.4f -> %s (checkpoint %s, history %s)\n", report.best_cost, out_path.c_str(),
              checkpoint_path.c_str(), history_path.c_str());
  weights_writer.wait_for_acknowledgments(std::chrono::seconds(2));
  const auto linger_end = std::chrono::steady_clock::now() + std::chrono::duration<double>(linger_s);
  while (std::chrono::steady_clock::now() < linger_end && !pdds::stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return interrupted ? 130 : kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("de_trainer", [&] { return run(argc, argv); });
}
