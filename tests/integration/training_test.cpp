// The distributed weight search: de_trainer alone, with de_worker processes,
// with a worker killed mid-run, killed itself and resumed from its checkpoint.
// Costs are pure functions of the weights and DE draws its random numbers in
// one thread, so every variant must end with bit-identical weights.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>

#include "child_process.hpp"
#include "integration_support.hpp"
#include "pmlsm/config/weights_file.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

using test::bin;
using test::read_file;
using test::source;
using test::test_domain;

fs::path train_dir(const std::string& name) { return test::fresh_dir("pmlsm_train", name); }

// The search every test runs: NP 8, 160 evaluations of a ~5 ms closed-loop run each: the
// initial population and 19 generations (generation g has made NP (g + 1) evaluations).
constexpr unsigned long long kPopulation = 8, kBudget = 160, kGenerations = kBudget / kPopulation - 1;
const std::vector<std::string> kTrainSet{"--train-set", "population_size=" + std::to_string(kPopulation),
                                         "max_evaluations=" + std::to_string(kBudget)};

std::vector<std::string> trainer_args(const std::string& domain, const fs::path& out, std::vector<std::string> extra) {
  extra.insert(extra.begin(), {"--out", out.string()});
  return test::trainer_args(domain, std::move(extra));
}

/// Worker ids carry the test program's process id: two test runs that meet on one
/// domain (PMLSM_TEST_DOMAIN_BASE not set apart) must not share worker names.
std::vector<std::string> worker_args(const std::string& domain, const std::string& id) {
  return {bin("de_worker"),
          "--domain",
          domain,
          "--profiles",
          source("configs/dds/profiles.xml"),
          "--threads",
          "1",
          "--id",
          id + "-" + std::to_string(getpid())};
}

/// Runs whose TrainingSetup a worker's log says it took, other than `run`: another
/// trainer on the test's domain (a second test run on the machine).
std::vector<std::string> foreign_setups(const std::string& worker_log, const std::string& trainer_out) {
  std::smatch m;
  if (!std::regex_search(trainer_out, m, std::regex(R"(, run (\d+)\n)"))) return {};
  const std::string run = m[1];
  std::vector<std::string> foreign;
  const std::regex taken(R"(setup of run (\d+) taken)");
  for (auto it = std::sregex_iterator(worker_log.begin(), worker_log.end(), taken); it != std::sregex_iterator();
       ++it) {
    if ((*it)[1] != run) foreign.push_back((*it)[1]);
  }
  return foreign;
}

template <typename... Vs>
std::vector<std::string> join(std::vector<std::string> a, const Vs&... more) {
  (a.insert(a.end(), more.begin(), more.end()), ...);
  return a;
}

struct Dispatch {
  unsigned long long remote = 0, local = 0, requeued = 0, lost = 0;
};

/// The trainer's summary line "(R remote, L local, Q re-queued, W worker(s) lost)".
std::optional<Dispatch> dispatch_of(const std::string& out) {
  std::smatch m;
  if (!std::regex_search(out, m,
                         std::regex(R"(\((\d+) remote, (\d+) local, (\d+) re-queued, (\d+) worker\(s\) lost\))"))) {
    return std::nullopt;
  }
  return Dispatch{std::stoull(m[1]), std::stoull(m[2]), std::stoull(m[3]), std::stoull(m[4])};
}

/// Runs a trainer to its end (exit 0 expected) and returns its output.
std::string run_trainer(const std::vector<std::string>& args, const fs::path& log) {
  test::ChildProcess trainer(args, log.string());
  const auto code = trainer.wait_for(seconds(120));
  EXPECT_TRUE(code.has_value()) << "still running:\n" << trainer.output();
  if (code) {
    EXPECT_EQ(*code, 0) << trainer.output();
  }
  return trainer.output();
}

struct Reference {
  RnnWeightsFile weights;
  /// Set when workers answered the local-threads run: the test program started none yet, so
  /// they belong to another test run on the same domain (PMLSM_TEST_DOMAIN_BASE not set apart).
  std::string shared_domain;
};

/// The local-threads run of kTrainSet, once per test program, on the calling test's
/// domain before it starts any worker there (so that no worker of its own can join it).
const Reference& local_reference(int domain_offset) {
  static const Reference reference = [domain_offset] {
    const fs::path dir = train_dir("reference");
    const std::string domain = test_domain(domain_offset);
    const std::string out = run_trainer(trainer_args(domain, dir / "w.yaml", kTrainSet), dir / "trainer.log");
    Reference r;
    const auto d = dispatch_of(out);
    EXPECT_TRUE(d.has_value()) << out;
    if (d && d->remote > 0) {
      r.shared_domain = "domain " + domain + " is shared with another test run (its workers answered the local run): " +
                        "set PMLSM_TEST_DOMAIN_BASE apart per test run\n" + out;
    } else if (d) {
      EXPECT_EQ(d->local, kBudget) << out;
    }
    r.weights = load_rnn_weights((dir / "w.yaml").string());
    fs::remove_all(dir);
    return r;
  }();
  return reference;
}

/// Bit-identical weights and cost (== on doubles: no tolerance).
void expect_same_result(const RnnWeightsFile& got, const RnnWeightsFile& expected) {
  EXPECT_EQ(got.layer_sizes, expected.layer_sizes);
  EXPECT_EQ(got.cost, expected.cost);
  ASSERT_EQ(got.weights.size(), expected.weights.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < got.weights.size(); ++i) differing += got.weights[i] != expected.weights[i];
  EXPECT_EQ(differing, 0u) << "weights differ from the local-threads run (cost " << got.cost << " vs " << expected.cost
                           << ")";
}

/// Stops a worker with SIGINT and expects a clean exit; returns its evaluation count.
unsigned long long stop_worker(test::ChildProcess& worker) {
  worker.signal(SIGINT);
  const auto code = worker.wait_for(seconds(30));
  EXPECT_TRUE(code.has_value()) << worker.output();
  if (code) {
    EXPECT_EQ(*code, 0) << worker.output();
  }
  std::smatch m;
  const std::string out = worker.output();
  if (!std::regex_search(out, m, std::regex(R"(: (\d+) evaluations\n)"))) {
    ADD_FAILURE() << "no evaluation count: " << out;
    return 0;
  }
  return std::stoull(m[1]);
}

/// Lines of a file after its header (0 when absent).
std::size_t data_lines(const fs::path& p) {
  const std::string text = read_file(p);
  const auto n = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
  return n > 0 ? n - 1 : 0;
}

/// Polls until `ready` holds; false at the deadline.
template <typename Ready>
bool poll_until(std::chrono::duration<double> timeout, Ready&& ready) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(timeout);
  while (std::chrono::steady_clock::now() < deadline) {
    if (ready()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // polling interval, not a synchronisation
  }
  return false;
}

TEST(TrainingDistributed, WorkersGiveTheSameResultAsLocalThreads) {
  const Reference& ref = local_reference(15);
  if (!ref.shared_domain.empty()) GTEST_SKIP() << ref.shared_domain;
  const RnnWeightsFile& reference = ref.weights;
  const fs::path dir = train_dir("workers");
  const std::string domain = test_domain(16);
  test::ChildProcess w1(worker_args(domain, "w1"), (dir / "w1.log").string());
  test::ChildProcess w2(worker_args(domain, "w2"), (dir / "w2.log").string());
  const std::string out = run_trainer(
      trainer_args(domain, dir / "w.yaml",
                   join(kTrainSet, std::vector<std::string>{"--wait-workers", "2", "--wait-workers-s", "30"})),
      dir / "trainer.log");
  EXPECT_NE(out.find("2 of 2 worker(s) joined"), std::string::npos) << out;
  const auto d = dispatch_of(out);
  ASSERT_TRUE(d.has_value()) << out;
  EXPECT_GT(d->remote, 0u) << out;
  EXPECT_EQ(d->remote + d->local, kBudget) << out;
  const unsigned long long e1 = stop_worker(w1), e2 = stop_worker(w2);
  EXPECT_GT(e1, 0u) << w1.output();
  EXPECT_GT(e2, 0u) << w2.output();
  ASSERT_TRUE(fs::exists(dir / "w.yaml")) << out;
  expect_same_result(load_rnn_weights((dir / "w.yaml").string()), reference);
  if (!HasFailure()) fs::remove_all(dir);
}

// The robust search (configs/training_robust.yaml: nine plants, two scenarios, each run judged
// whole) on a worker gives the local result bit for bit: TrainingSetup carries the plants and the
// verdict, so a worker that dropped either would score differently and steer the search elsewhere.
TEST(TrainingDistributed, AJudgedSearchOverPlantsGivesTheSameResultOnAWorker) {
  const fs::path dir = train_dir("judged");
  const std::vector<std::string> robust{"--train-set", "population_size=8", "max_evaluations=16"};
  const auto with_robust_file = [](std::vector<std::string> args) {
    const auto at = std::find(args.begin(), args.end(), "--training");
    if (at != args.end()) *(at + 1) = source("configs/training_robust.yaml");
    return args;
  };
  const std::string local_domain = test_domain(86);
  const std::string local_out =
      run_trainer(with_robust_file(trainer_args(local_domain, dir / "local.yaml", robust)), dir / "local.log");
  const auto local = dispatch_of(local_out);
  ASSERT_TRUE(local.has_value()) << local_out;
  if (local->remote > 0) GTEST_SKIP() << "domain " << local_domain << " is shared with another test run";
  const std::string domain = test_domain(87);
  test::ChildProcess worker(worker_args(domain, "judged"), (dir / "worker.log").string());
  const std::string out =
      run_trainer(with_robust_file(trainer_args(
                      domain, dir / "remote.yaml",
                      join(robust, std::vector<std::string>{"--wait-workers", "1", "--wait-workers-s", "30"}))),
                  dir / "remote.log");
  const auto d = dispatch_of(out);
  ASSERT_TRUE(d.has_value()) << out;
  EXPECT_GT(d->remote, 0u) << out;
  stop_worker(worker);
  ASSERT_TRUE(fs::exists(dir / "remote.yaml")) << out;
  expect_same_result(load_rnn_weights((dir / "remote.yaml").string()), load_rnn_weights((dir / "local.yaml").string()));
  if (!HasFailure()) fs::remove_all(dir);
}

TEST(TrainingDistributed, KilledWorkerLosesNothing) {
  const Reference& ref = local_reference(17);
  if (!ref.shared_domain.empty()) GTEST_SKIP() << ref.shared_domain;
  const RnnWeightsFile& reference = ref.weights;
  const fs::path dir = train_dir("killed_worker");
  const std::string domain = test_domain(17);
  test::ChildProcess w1(worker_args(domain, "w1"), (dir / "w1.log").string());
  test::ChildProcess w2(worker_args(domain, "w2"), (dir / "w2.log").string());
  test::ChildProcess trainer(
      trainer_args(domain, dir / "w.yaml",
                   join(kTrainSet, std::vector<std::string>{"--wait-workers", "2", "--wait-workers-s", "30",
                                                            "--worker-timeout-s", "1"})),
      (dir / "trainer.log").string());
  // A first generation done by the workers, then one of them dies without a word.
  ASSERT_TRUE(poll_until(seconds(60), [&] { return data_lines(dir / "w.yaml.history.csv") >= 1; })) << trainer.output();
  w1.signal(SIGKILL);
  ASSERT_TRUE(w1.wait_for(seconds(10)).has_value());
  const std::size_t generation_at_kill = data_lines(dir / "w.yaml.history.csv");

  const auto code = trainer.wait_for(seconds(120));
  ASSERT_TRUE(code.has_value()) << trainer.output();
  EXPECT_EQ(*code, 0) << trainer.output();
  const std::string out = trainer.output();
  for (const test::ChildProcess* w : {&w1, &w2}) {
    const auto foreign = foreign_setups(w->output(), out);
    if (!foreign.empty() && !HasFailure()) {
      GTEST_SKIP() << "domain " << domain << " is shared with another trainer (a worker took the setup of run "
                   << foreign.front() << "): set PMLSM_TEST_DOMAIN_BASE apart per test run\n"
                   << w->output();
    }
  }
  const auto d = dispatch_of(out);
  ASSERT_TRUE(d.has_value()) << out;
  EXPECT_LT(generation_at_kill, kGenerations) << "the run was over before the kill: the test proves nothing";
  EXPECT_GE(d->lost, 1u) << out;
  EXPECT_GT(d->remote, 0u) << out;
  EXPECT_EQ(d->remote + d->local, kBudget) << out;
  std::printf("killed worker after %zu generation(s): %llu re-queued, %llu lost\n", generation_at_kill, d->requeued,
              d->lost);
  EXPECT_GT(stop_worker(w2), 0u) << w2.output();
  ASSERT_TRUE(fs::exists(dir / "w.yaml")) << out;
  expect_same_result(load_rnn_weights((dir / "w.yaml").string()), reference);
  if (!HasFailure()) fs::remove_all(dir);
}

/// The "generation N" of a checkpoint file (nullopt when absent or unreadable).
std::optional<unsigned long long> checkpoint_generation(const fs::path& p) {
  std::smatch m;
  const std::string text = read_file(p);
  if (!std::regex_search(text, m, std::regex(R"(\ngeneration (\d+)\n)"))) return std::nullopt;
  return std::stoull(m[1]);
}

TEST(TrainingDistributed, KilledTrainerResumesFromCheckpoint) {
  const Reference& ref = local_reference(18);
  if (!ref.shared_domain.empty()) GTEST_SKIP() << ref.shared_domain;
  const RnnWeightsFile& reference = ref.weights;
  const fs::path dir = train_dir("resume");
  const std::string domain = test_domain(18);
  const std::vector<std::string> args = trainer_args(domain, dir / "w.yaml", kTrainSet);
  unsigned long long killed_at = 0;
  {
    test::ChildProcess trainer(args, (dir / "trainer1.log").string());
    ASSERT_TRUE(poll_until(seconds(60), [&] {
      const auto g = checkpoint_generation(dir / "w.yaml.checkpoint");
      return g && *g >= 2;
    })) << trainer.output();
    trainer.signal(SIGKILL);
    const auto code = trainer.wait_for(seconds(10));
    ASSERT_TRUE(code.has_value());
    EXPECT_EQ(*code, -SIGKILL) << "the trainer ended before the kill: " << trainer.output();
    killed_at = checkpoint_generation(dir / "w.yaml.checkpoint").value_or(0);
  }
  ASSERT_FALSE(fs::exists(dir / "w.yaml")) << "the first run finished: the test proves nothing";
  ASSERT_GE(killed_at, 2u);
  ASSERT_LT(killed_at, kGenerations);

  const std::string out = run_trainer(join(args, std::vector<std::string>{"--resume"}), dir / "trainer2.log");
  EXPECT_NE(out.find("at generation " + std::to_string(killed_at)), std::string::npos) << out;
  const auto d = dispatch_of(out);
  ASSERT_TRUE(d.has_value()) << out;
  EXPECT_EQ(d->local, kBudget - kPopulation * (killed_at + 1))
      << "only the remaining generations are evaluated: " << out;
  ASSERT_TRUE(fs::exists(dir / "w.yaml")) << out;
  expect_same_result(load_rnn_weights((dir / "w.yaml").string()), reference);
  if (!HasFailure()) fs::remove_all(dir);
}

TEST(TrainingDistributed, BadTrainingConfigExits2) {
  const fs::path dir = train_dir("badcfg");
  const std::vector<std::pair<std::string, std::string>> cases{
      {"nonsense=1", "nonsense"},
      {"crossover_rate=2", "crossover_rate"},
      {"population_size=3", "population_size"},
      {"max_evaluations=8", "max_evaluations"},  // below NP (120)
  };
  int i = 0;
  for (const auto& [set, key] : cases) {
    test::ChildProcess trainer(trainer_args(test_domain(19), dir / "w.yaml", {"--train-set", set}),
                               (dir / ("trainer" + std::to_string(i++) + ".log")).string());
    const auto code = trainer.wait_for(seconds(30));
    ASSERT_TRUE(code.has_value()) << set << ": still running\n" << trainer.output();
    EXPECT_EQ(*code, 2) << set << ": " << trainer.output();
    EXPECT_NE(trainer.output().find(key), std::string::npos) << set << ": " << trainer.output();
    EXPECT_NE(trainer.output().find("training.yaml"), std::string::npos) << set << ": " << trainer.output();
  }
  // A worker with a bad option is refused the same way.
  test::ChildProcess worker({bin("de_worker"), "--domain", test_domain(19), "--threads", "0"},
                            (dir / "worker.log").string());
  const auto code = worker.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value()) << worker.output();
  EXPECT_EQ(*code, 2) << worker.output();
  EXPECT_NE(worker.output().find("--threads"), std::string::npos) << worker.output();
  // Nowhere to write the result: refused before the search starts, not at its end.
  test::ChildProcess nowhere(trainer_args(test_domain(19), dir / "no" / "w.yaml", {}), (dir / "nowhere.log").string());
  const auto nowhere_code = nowhere.wait_for(seconds(30));
  ASSERT_TRUE(nowhere_code.has_value()) << nowhere.output();
  EXPECT_EQ(*nowhere_code, 2) << nowhere.output();
  EXPECT_NE(nowhere.output().find("-o " + (dir / "no" / "w.yaml").string() + ": no folder"), std::string::npos)
      << nowhere.output();
  EXPECT_FALSE(fs::exists(dir / "w.yaml"));
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm
