// de_trainer: the offline weight search of section 3.3. Each evaluation is a
// closed-loop run of the full plant with the RNN in the loop, scored by (23).
// Generations go to de_worker processes on the domain when there are any, to
// local threads otherwise. Every generation is checkpointed; --resume goes on
// from the checkpoint. Publishes TrainerProgress every generation, and the
// best NetworkWeights (reliable, transient-local) when it improves; writes the
// weights file at the end (and on SIGINT, after the current generation).
//
// A component made from its command line (configs loaded, plants commissioned, the cost
// built, participant and endpoints created), then run once. It computes for minutes on its
// own threads, so it runs alone in its process, never on a container's chain thread.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <thread>

#include "NetworkWeightsPubSubTypes.h"
#include "TrainerProgressPubSubTypes.h"
#include "node_support.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/optim/pagmo_optimisers.hpp"
#include "pmlsm/util/atomic_file.hpp"
#include "pmlsm/util/data_files.hpp"
#include "training_command_lines.hpp"
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
                 static_cast<unsigned long long>(r.evaluations), static_cast<unsigned long long>(budget), r.best_cost,
                 r.mean_cost, elapsed_s, eta_s, tty_ ? "  " : "\n");
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

using node::TrainerOptions;

/// The training file with its plants commissioned where they ask for it (printed).
TrainingParams load_training(const TrainerOptions& opt, const SystemParams& params) {
  TrainingParams training =
      load_training_params(opt.training_path, params.timing.control_period_s, parse_overrides(opt.training_overrides));
  if (!training.identify_models) return training;
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
  return training;
}

SystemParams load_system(const TrainerOptions& opt) {
  return load_system_params(opt.config_path, parse_overrides(opt.overrides));
}

std::shared_ptr<const RnnCost> make_cost(const SystemParams& params, const TrainingParams& training) {
  if (training.judge_runs) {
    return std::make_shared<const RnnCost>(params, training.scenarios, training.cost_velocity, training.plants,
                                           training.plant_objective, training.verdict);
  }
  return std::make_shared<const RnnCost>(params, training.scenarios, training.cost_velocity, training.plants,
                                         training.plant_objective);
}

DeParams make_de_params(const SystemParams& params, const TrainingParams& training, std::size_t dimension) {
  DeParams de = training.search;
  de.dimension = dimension;
  if (training.start == TrainingStart::kAccelerationFeedback) {
    de.first_member = rnn_weights_from_acceleration_feedback(params);
  }
  return de;
}

std::chrono::milliseconds to_ms(double seconds) {
  return std::chrono::milliseconds(static_cast<long long>(seconds * 1000));
}

class DeTrainerComponent final : public node::Component {
 public:
  explicit DeTrainerComponent(TrainerOptions options)
      : opt_(std::move(options)),
        params_(load_system(opt_)),
        training_(load_training(opt_, params_)),
        cost_(make_cost(params_, training_)),
        de_(make_de_params(params_, training_, cost_->dimension())),
        participant_(node::named(opt_.dds, "de_trainer")),
        run_id_(static_cast<std::uint64_t>(wall_time_ns()) ^ (static_cast<std::uint64_t>(getpid()) << 40)),
        setup_writer_(participant_.make_writer(pdds::topics::kTrainingSetup)),
        progress_writer_(participant_.make_writer(pdds::topics::kTrainerProgress)),
        weights_writer_(participant_.make_writer(pdds::topics::kNetworkWeights)),
        evaluator_(
            participant_, wakeup_, [cost = cost_](const std::vector<double>& w) { return (*cost)(w); }, opt_.threads,
            run_id_, to_ms(opt_.worker_timeout_s)) {}

  int run() override;

 private:
  /// The search's state between generations.
  struct Search {
    OptimiserReport report;
    std::uint64_t start_evaluations = 0;
    std::chrono::steady_clock::time_point start;
    std::uint64_t version = 0;  // the last NetworkWeights published; first_version - 1 before the first
    double published_cost = std::numeric_limits<double>::infinity();
    bool interrupted = false;
  };

  std::unique_ptr<Optimiser> make_started_optimiser();
  void search(Optimiser& optimiser, Search& s);
  void publish_generation(const Search& s, double elapsed_s, double eta_s);
  void write_weights_file(const Optimiser& optimiser, const OptimiserReport& report) const;
  void print_summary(const Search& s, double elapsed_s) const;

  TrainerOptions opt_;
  SystemParams params_;
  TrainingParams training_;
  std::shared_ptr<const RnnCost> cost_;
  DeParams de_;
  pdds::Wakeup wakeup_;  // outlives the participant, whose listeners signal it
  pdds::Participant participant_;
  std::uint64_t run_id_;
  pdds::Writer<msg::TrainingSetupPubSubType> setup_writer_;
  pdds::Writer<msg::TrainerProgressPubSubType> progress_writer_;
  pdds::Writer<msg::NetworkWeightsPubSubType> weights_writer_;
  training::DdsEvaluator evaluator_;
  msg::TrainerProgress progress_msg_;
  msg::NetworkWeights weights_msg_;
};

int DeTrainerComponent::run() {
  setup_writer_.write(training::make_setup(run_id_, opt_.config_path, opt_.overrides, training_));
  if (opt_.wait_workers > 0) {
    const std::size_t live = evaluator_.wait_for_workers(opt_.wait_workers, to_ms(opt_.wait_workers_s));
    std::printf("de_trainer: %zu of %zu worker(s) joined\n", live, opt_.wait_workers);
    if (live < opt_.wait_workers) return kExitPeerMissing;
  }
  const std::unique_ptr<Optimiser> optimiser = make_started_optimiser();
  Search s;
  s.report = optimiser->report();
  s.start_evaluations = s.report.evaluations;
  s.start = std::chrono::steady_clock::now();
  s.version = opt_.first_version - 1;
  search(*optimiser, s);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - s.start).count();
  if (s.report.best.empty()) throw std::runtime_error("interrupted before the first generation: no weights");
  write_weights_file(*optimiser, s.report);
  print_summary(s, elapsed);
  if (opt_.weights_readers > 0) {
    // Discovery may find a running compensator only after a short search ends: wait for it on the
    // match, with a deadline, not on a fixed time.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(opt_.wait_workers_s);
    while (weights_writer_.matched_readers() < opt_.weights_readers && !pdds::stop_requested() &&
           std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (weights_writer_.matched_readers() < opt_.weights_readers) {
      // The weights file is written; what was asked beyond it, the readers, did not all come.
      std::fprintf(stderr, "de_trainer: %zu of %zu NetworkWeights reader(s) matched within %.1f s\n",
                   weights_writer_.matched_readers(), opt_.weights_readers, opt_.wait_workers_s);
      return kExitPeerMissing;
    }
  }
  weights_writer_.wait_for_acknowledgments(std::chrono::seconds(2));
  const auto linger_end = std::chrono::steady_clock::now() + std::chrono::duration<double>(opt_.linger_s);
  while (std::chrono::steady_clock::now() < linger_end && !pdds::stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return s.interrupted ? 130 : kExitOk;
}

std::unique_ptr<Optimiser> DeTrainerComponent::make_started_optimiser() {
  std::unique_ptr<Optimiser> optimiser = make_optimiser(parse_optimiser_kind(training_.optimiser), de_, evaluator_);
  if (opt_.resume) {
    optimiser->load_checkpoint(opt_.checkpoint_path);
    std::printf("de_trainer: resumed from %s at generation %llu, %llu evaluations\n", opt_.checkpoint_path.c_str(),
                static_cast<unsigned long long>(optimiser->report().generation),
                static_cast<unsigned long long>(optimiser->report().evaluations));
  }
  std::printf(
      "de_trainer: %s, NP %llu, D %zu, F %.2f, CR %.2f, seed %llu, start %s, budget %llu evaluations, cost "
      "on %s V_load, run %llu\n",
      optimiser->name().c_str(), static_cast<unsigned long long>(de_.population_size), de_.dimension,
      de_.mutation_factor, de_.crossover_rate, static_cast<unsigned long long>(de_.seed), to_string(training_.start),
      static_cast<unsigned long long>(training_.max_evaluations), to_string(training_.cost_velocity),
      static_cast<unsigned long long>(run_id_));
  progress_msg_.optimiser(optimiser->name().substr(0, 32));
  progress_msg_.population_size(static_cast<std::uint32_t>(de_.population_size));
  progress_msg_.max_generations(0);
  for (int size : params_.compensator.rnn.layer_sizes) {
    weights_msg_.layer_sizes().push_back(static_cast<std::uint16_t>(size));
  }
  weights_msg_.input_scale(params_.compensator.rnn.input_scale_s2_per_m);
  weights_msg_.gain_n(params_.compensator.rnn.gain_n);
  return optimiser;
}

/// Generations until the budget, the target cost or a stop request; each one checkpointed,
/// written to the history and published.
void DeTrainerComponent::search(Optimiser& optimiser, Search& s) {
  std::ofstream history(opt_.history_path, opt_.resume ? std::ios::app : std::ios::trunc);
  if (!history) throw std::runtime_error(opt_.history_path + ": cannot write");
  if (!opt_.resume) history << "generation,evaluations,best_cost,mean_cost,elapsed_s,best_weight_0\n";
  ProgressBar bar(!opt_.no_progress);
  const std::uint64_t budget = training_.max_evaluations;
  while (s.report.evaluations < budget) {
    if (pdds::stop_requested()) {
      s.interrupted = true;
      break;
    }
    s.report = optimiser.step();
    optimiser.save_checkpoint(opt_.checkpoint_path);
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - s.start).count();
    const double rate = static_cast<double>(s.report.evaluations - s.start_evaluations) / std::max(elapsed, 1e-9);
    const double eta = static_cast<double>(budget - std::min(budget, s.report.evaluations)) / std::max(rate, 1e-9);
    char line[256];
    std::snprintf(line, sizeof(line), "%llu,%llu,%.17g,%.17g,%.3f,%.17g\n",
                  static_cast<unsigned long long>(s.report.generation),
                  static_cast<unsigned long long>(s.report.evaluations), s.report.best_cost, s.report.mean_cost,
                  elapsed, s.report.best.empty() ? 0.0 : s.report.best[0]);
    history << line << std::flush;
    if (s.report.best_cost < s.published_cost) {
      s.published_cost = s.report.best_cost;
      weights_msg_.version(++s.version);
      weights_msg_.weights(s.report.best);
      weights_msg_.cost(s.report.best_cost);
      weights_msg_.source(("de_trainer gen " + std::to_string(s.report.generation)).substr(0, 64));
      weights_msg_.stamp(node::make_stamp(s.report.generation, params_.timing.control_period_s));
      weights_writer_.write(weights_msg_);
    }
    publish_generation(s, elapsed, eta);
    bar.update(s.report, budget, elapsed, eta);
    if (training_.target_cost > 0 && s.report.best_cost <= training_.target_cost) break;
  }
  bar.finish();
}

void DeTrainerComponent::publish_generation(const Search& s, double elapsed_s, double eta_s) {
  progress_msg_.stamp(node::make_stamp(s.report.generation, params_.timing.control_period_s));
  progress_msg_.generation(s.report.generation);
  progress_msg_.evaluations(s.report.evaluations);
  progress_msg_.best_weights_version(s.version);
  progress_msg_.best_cost(s.report.best_cost);
  progress_msg_.mean_cost(s.report.mean_cost);
  progress_msg_.elapsed_s(elapsed_s);
  progress_msg_.eta_s(eta_s);
  progress_writer_.write(progress_msg_);
}

void DeTrainerComponent::write_weights_file(const Optimiser& optimiser, const OptimiserReport& report) const {
  RnnWeightsFile file;
  file.layer_sizes = params_.compensator.rnn.layer_sizes;
  file.input_scale_s2_per_m = params_.compensator.rnn.input_scale_s2_per_m;
  file.on_reference_error = params_.compensator.rnn.on_reference_error;
  file.gain_n = params_.compensator.rnn.gain_n;
  file.cost = report.best_cost;
  // The system overrides the search ran with belong to its provenance: the same command remakes
  // the same bits, and a check of the file's cost must judge it as it was searched.
  std::string searched_with;
  for (const auto& o : opt_.overrides) searched_with += " " + o;
  file.source = optimiser.name() + " seed " + std::to_string(de_.seed) + " gen " + std::to_string(report.generation) +
                " evals " + std::to_string(report.evaluations) + " (" + to_string(training_.cost_velocity) +
                " V_load, " + opt_.training_path + (searched_with.empty() ? "" : ", --set" + searched_with) + ")";
  file.weights = report.best;
  save_rnn_weights(opt_.out_path, file);
}

void DeTrainerComponent::print_summary(const Search& s, double elapsed_s) const {
  const auto& c = evaluator_.counters();
  std::printf(
      "de_trainer: %s after %llu generations, %llu evaluations (%llu remote, %llu local, %llu re-queued, "
      "%llu worker(s) lost) in %.1f s: %.0f evaluations/s\n",
      s.interrupted ? "interrupted" : "done", static_cast<unsigned long long>(s.report.generation),
      static_cast<unsigned long long>(s.report.evaluations), static_cast<unsigned long long>(c.remote_evaluations),
      static_cast<unsigned long long>(c.local_evaluations), static_cast<unsigned long long>(c.requeued),
      static_cast<unsigned long long>(c.workers_lost), elapsed_s,
      static_cast<double>(s.report.evaluations - s.start_evaluations) / std::max(elapsed_s, 1e-9));
  std::printf("de_trainer: best cost %.4f -> %s (checkpoint %s, history %s)\n", s.report.best_cost,
              opt_.out_path.c_str(), opt_.checkpoint_path.c_str(), opt_.history_path.c_str());
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(de_trainer, make_de_trainer, kRunsAlone);

MadeComponent make_de_trainer(const ComponentContext& /*context*/, int argc, char** argv) {
  TrainerOptions opt;
  if (const auto code = parse_de_trainer_command_line(argc, argv, opt)) return {nullptr, *code};
  if (opt.checkpoint_path.empty()) opt.checkpoint_path = opt.out_path + ".checkpoint";
  if (opt.history_path.empty()) opt.history_path = opt.out_path + ".history.csv";
  if (opt.resume && !file_exists(opt.checkpoint_path))
    throw ConfigError("--resume: no checkpoint at " + opt.checkpoint_path);
  // Before the search: it ends by writing these.
  for (const auto& [option, path] : {std::pair<const char*, const std::string&>{"-o", opt.out_path},
                                     {"--checkpoint", opt.checkpoint_path},
                                     {"--history", opt.history_path}}) {
    if (const std::string missing = missing_folder_of(path); !missing.empty()) {
      throw ConfigError(std::string(option) + " " + path + ": " + missing);
    }
  }
  return {std::make_unique<DeTrainerComponent>(std::move(opt))};
}

}  // namespace pmlsm::node
