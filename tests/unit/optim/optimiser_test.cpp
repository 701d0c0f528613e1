// pmlsm_optim: DE/rand/1/bin (paper eqs. 21-22), jDE and CMA-ES via pagmo,
// the thread-pool evaluator and checkpoints.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <pagmo/bfe.hpp>
#include <pagmo/problem.hpp>
#include <pagmo/types.hpp>

#include "pmlsm/optim/differential_evolution.hpp"
#include "pmlsm/optim/optimiser.hpp"
#include "pmlsm/optim/thread_pool_evaluator.hpp"
#include "pmlsm/optim/pagmo_optimisers.hpp"

namespace pmlsm {
namespace {

constexpr double kPi = 3.14159265358979323846;
const double kNan = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

double sphere(const std::vector<double>& x) {
  double sum = 0;
  for (double v : x) sum += v * v;
  return sum;
}

/// The sphere moved to (1, ..., 1).
double shifted_sphere_cost(const std::vector<double>& x) {
  double sum = 0;
  for (double v : x) sum += (v - 1) * (v - 1);
  return sum;
}

double rosenbrock(const std::vector<double>& x) {
  double sum = 0;
  for (std::size_t i = 0; i + 1 < x.size(); ++i) {
    sum += 100.0 * std::pow(x[i + 1] - x[i] * x[i], 2) + std::pow(1.0 - x[i], 2);
  }
  return sum;
}

double rastrigin(const std::vector<double>& x) {
  double sum = 10.0 * static_cast<double>(x.size());
  for (double v : x) sum += v * v - 10.0 * std::cos(2.0 * kPi * v);
  return sum;
}

/// Counts the candidates that pass through, then forwards.
class CountingEvaluator final : public BatchEvaluator {
 public:
  explicit CountingEvaluator(BatchEvaluator& inner) : inner_(inner) {}
  void evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) override {
    candidates_seen += candidates.size();
    ++batches;
    inner_.evaluate(candidates, costs);
  }
  std::uint64_t candidates_seen = 0;
  std::uint64_t batches = 0;

 private:
  BatchEvaluator& inner_;
};

/// A "remote" evaluator that returns raw costs, NaN included, without mapping them.
class RawEvaluator final : public BatchEvaluator {
 public:
  explicit RawEvaluator(CostFunction cost) : cost_(std::move(cost)) {}
  void evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) override {
    if (fail_next) {
      fail_next = false;
      throw std::runtime_error("worker lost");
    }
    costs.clear();
    for (const auto& c : candidates) costs.push_back(cost_(c));
  }
  bool fail_next = false;

 private:
  CostFunction cost_;
};

DeParams small_params(std::size_t np, std::size_t dim, std::uint64_t seed = 1) {
  DeParams p;
  p.population_size = np;
  p.dimension = dim;
  p.seed = seed;
  return p;
}

/// Steps until the best cost is below `target` or the budget is spent; returns the last report.
OptimiserReport run_until(Optimiser& optimiser, double target, std::uint64_t max_generations) {
  OptimiserReport r = optimiser.step();
  while (r.best_cost >= target && r.generation < max_generations) r = optimiser.step();
  return r;
}

OptimiserReport run_generations(Optimiser& optimiser, std::uint64_t generations) {
  OptimiserReport r = optimiser.report();
  for (std::uint64_t g = 0; g < generations; ++g) r = optimiser.step();
  return r;
}

std::string temp_path(const std::string& name) { return ::testing::TempDir() + "pmlsm_optimiser_test_" + name; }

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "<no exception>";
}

#define EXPECT_THROW_WITH(statement, exception_type, fragment)                                   \
  do {                                                                                           \
    EXPECT_THROW(statement, exception_type);                                                     \
    EXPECT_NE(error_of([&] { statement; }).find(fragment), std::string::npos)                    \
        << "message: " << error_of([&] { statement; }) << "\nexpected to contain: " << fragment; \
  } while (0)

void expect_same_state(const OptimiserReport& a, const OptimiserReport& b) {
  EXPECT_EQ(a.generation, b.generation);
  EXPECT_EQ(a.evaluations, b.evaluations);
  EXPECT_EQ(a.best_cost, b.best_cost);
  EXPECT_EQ(a.mean_cost, b.mean_cost);
  EXPECT_EQ(a.best, b.best);
}

// ---------------------------------------------------------------------------
// Parameters and factory

TEST(DeParams, DefaultsAreTable1AndValid) {
  const DeParams p;
  EXPECT_EQ(p.population_size, 120u);
  EXPECT_EQ(p.dimension, 91u);
  EXPECT_EQ(p.mutation_factor, 0.8);
  EXPECT_EQ(p.crossover_rate, 0.7);
  EXPECT_EQ(p.init_lower, -1.0);
  EXPECT_EQ(p.init_upper, 1.0);
  EXPECT_NO_THROW(p.validate());
}

TEST(DeParams, BadValuesThrowNamingTheField) {
  const auto with = [](auto change) {
    DeParams p;
    change(p);
    return p;
  };
  EXPECT_THROW_WITH(with([](DeParams& p) { p.population_size = 3; }).validate(), std::invalid_argument,
                    "population_size: must be >= 4, got 3");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.dimension = 0; }).validate(), std::invalid_argument,
                    "dimension: must be >= 1, got 0");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.mutation_factor = 0; }).validate(), std::invalid_argument,
                    "mutation_factor: must be in [1e-09, 2], got 0");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.mutation_factor = 2.5; }).validate(), std::invalid_argument,
                    "mutation_factor");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.mutation_factor = kNan; }).validate(), std::invalid_argument,
                    "mutation_factor: must be finite");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.crossover_rate = 1.5; }).validate(), std::invalid_argument,
                    "crossover_rate: must be in [0, 1], got 1.5");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.init_lower = -kInf; }).validate(), std::invalid_argument,
                    "init_lower: must be finite");
  EXPECT_THROW_WITH(with([](DeParams& p) { p.init_upper = -1; }).validate(), std::invalid_argument,
                    "init_upper: must be > init_lower");
  EXPECT_NO_THROW(with([](DeParams& p) { p.crossover_rate = 0; }).validate());
  EXPECT_NO_THROW(with([](DeParams& p) { p.mutation_factor = 2; }).validate());
}

TEST(DeParams, ConstructorsValidate) {
  ThreadPoolEvaluator evaluator(sphere, 1);
  EXPECT_THROW_WITH(DifferentialEvolution(small_params(3, 2), evaluator), std::invalid_argument, "population_size");
  EXPECT_THROW_WITH(PagmoOptimiser(PagmoAlgorithm::jde, small_params(6, 2), evaluator), std::invalid_argument,
                    "population_size: must be >= 7 for jDE, got 6");
  EXPECT_THROW_WITH(PagmoOptimiser(PagmoAlgorithm::cmaes, small_params(4, 2), evaluator), std::invalid_argument,
                    "population_size: must be >= 5 for CMA-ES, got 4");
  EXPECT_THROW_WITH(make_optimiser(OptimiserKind::de, small_params(10, 0), evaluator), std::invalid_argument,
                    "dimension");
}

TEST(OptimiserFactory, ParsesKindsAndListsTheChoices) {
  EXPECT_EQ(parse_optimiser_kind("de"), OptimiserKind::de);
  EXPECT_EQ(parse_optimiser_kind("jde"), OptimiserKind::jde);
  EXPECT_EQ(parse_optimiser_kind("cmaes"), OptimiserKind::cmaes);
  EXPECT_THROW_WITH(parse_optimiser_kind("pso"), std::invalid_argument, "de, jde, cmaes, got 'pso'");
  ThreadPoolEvaluator evaluator(sphere, 1);
  EXPECT_EQ(make_optimiser(OptimiserKind::de, small_params(10, 2), evaluator)->name(), "DE/rand/1/bin");
  EXPECT_EQ(make_optimiser(OptimiserKind::jde, small_params(10, 2), evaluator)->name(), "jDE");
  EXPECT_EQ(make_optimiser(OptimiserKind::cmaes, small_params(10, 2), evaluator)->name(), "CMA-ES");
}

// ---------------------------------------------------------------------------
// ThreadPoolEvaluator

TEST(ThreadPoolEvaluator, RejectsBadArguments) {
  EXPECT_THROW_WITH(ThreadPoolEvaluator(sphere, 0), std::invalid_argument, "threads: must be >= 1");
  EXPECT_THROW_WITH(ThreadPoolEvaluator(CostFunction{}, 2), std::invalid_argument, "cost");
}

TEST(ThreadPoolEvaluator, ResultsByIndexForAnyThreadCountAndPartition) {
  std::vector<std::vector<double>> candidates;
  for (int i = 0; i < 37; ++i) candidates.push_back({0.1 * i, -0.3 * i, std::sin(i)});
  std::vector<double> expected;
  for (const auto& c : candidates) expected.push_back(rastrigin(c));
  for (unsigned threads : {1u, 2u, 4u, 7u}) {
    for (auto partition : {ThreadPoolEvaluator::Partition::static_blocks, ThreadPoolEvaluator::Partition::dynamic}) {
      ThreadPoolEvaluator evaluator(rastrigin, threads, partition);
      EXPECT_EQ(evaluator.threads(), threads);
      std::vector<double> costs{1, 2, 3};           // stale contents are replaced
      for (int repeat = 0; repeat < 3; ++repeat) {  // the pool is reused between batches
        evaluator.evaluate(candidates, costs);
        EXPECT_EQ(costs, expected) << threads << " threads";
      }
      evaluator.evaluate({}, costs);
      EXPECT_TRUE(costs.empty());
    }
  }
}

TEST(ThreadPoolEvaluator, NonFiniteCostsBecomeInfinity) {
  ThreadPoolEvaluator evaluator(
      [](const std::vector<double>& x) { return x[0] == 0   ? kNan
                                                : x[0] == 1 ? -kInf
                                                            : x[0]; }, 3);
  std::vector<double> costs;
  evaluator.evaluate({{0}, {1}, {2}, {3}}, costs);
  EXPECT_EQ(costs, (std::vector<double>{kInf, kInf, 2, 3}));
}

TEST(ThreadPoolEvaluator, RethrowsTheLowestFailingIndexAfterTheBatch) {
  std::atomic<int> calls{0};
  ThreadPoolEvaluator evaluator(
      [&](const std::vector<double>& x) -> double {
        ++calls;
        if (x[0] >= 5) throw std::runtime_error("blew up at " + std::to_string(static_cast<int>(x[0])));
        return x[0];
      },
      4);
  std::vector<std::vector<double>> candidates;
  for (int i = 0; i < 20; ++i) candidates.push_back({static_cast<double>(i)});
  std::vector<double> costs;
  EXPECT_THROW_WITH(evaluator.evaluate(candidates, costs), std::runtime_error, "blew up at 5");
  EXPECT_EQ(calls.load(), 2 * 20);  // the batch is finished both times (the macro evaluates twice)
  // The pool still works afterwards.
  evaluator.evaluate({{1}, {2}}, costs);
  EXPECT_EQ(costs, (std::vector<double>{1, 2}));
}

// ---------------------------------------------------------------------------
// DE/rand/1/bin

TEST(DifferentialEvolution, SolvesSphere10) {
  ThreadPoolEvaluator evaluator(sphere, 2);
  DifferentialEvolution de(small_params(40, 10), evaluator);
  const auto r = run_until(de, 1e-6, 1000);
  EXPECT_LT(r.best_cost, 1e-6) << "after " << r.generation << " generations";
  EXPECT_EQ(sphere(r.best), r.best_cost);
}

TEST(DifferentialEvolution, SolvesRosenbrock5) {
  ThreadPoolEvaluator evaluator(rosenbrock, 2);
  DeParams p = small_params(50, 5);
  p.init_lower = -2;  // the optimum (1, ..., 1) inside the init box
  p.init_upper = 2;
  p.crossover_rate = 0.9;  // non-separable: more components from the mutant
  DifferentialEvolution de(p, evaluator);
  const auto r = run_until(de, 1e-3, 2000);
  EXPECT_LT(r.best_cost, 1e-3) << "after " << r.generation << " generations";
  for (double x : r.best) EXPECT_NEAR(x, 1.0, 0.05);
}

TEST(DifferentialEvolution, SolvesRastrigin5) {
  ThreadPoolEvaluator evaluator(rastrigin, 2);
  DeParams p = small_params(50, 5);
  p.init_lower = -5.12;
  p.init_upper = 5.12;
  p.mutation_factor = 0.5;
  p.crossover_rate = 0.1;  // separable: few components at a time
  DifferentialEvolution de(p, evaluator);
  const auto r = run_until(de, 1e-2, 2000);
  EXPECT_LT(r.best_cost, 1e-2) << "after " << r.generation
                               << " generations";  // the global minimum 0, not a local one (>= ~1)
}

TEST(DifferentialEvolution, CountsEvaluationsAsNpTimesGenerationsPlusOne) {
  ThreadPoolEvaluator pool(sphere, 2);
  CountingEvaluator counter(pool);
  DifferentialEvolution de(small_params(12, 3), counter);
  const auto before = de.report();
  EXPECT_EQ(before.generation, 0u);
  EXPECT_EQ(before.evaluations, 0u);
  EXPECT_EQ(before.best_cost, kInf);
  EXPECT_TRUE(before.best.empty());
  for (std::uint64_t g = 1; g <= 7; ++g) {
    const auto r = de.step();
    EXPECT_EQ(r.generation, g);
    EXPECT_EQ(r.evaluations, 12 * (g + 1));
    EXPECT_EQ(counter.candidates_seen, r.evaluations);
  }
  EXPECT_EQ(counter.batches, 8u);  // initial population + one batch per generation
}

TEST(DifferentialEvolution, SameSeedSameRunForAnyThreadCountDifferentSeedDifferentRun) {
  const auto run = [](unsigned threads, std::uint64_t seed, ThreadPoolEvaluator::Partition partition) {
    ThreadPoolEvaluator evaluator(rastrigin, threads, partition);
    DifferentialEvolution de(small_params(20, 6, seed), evaluator);
    run_generations(de, 30);
    return std::make_pair(de.report(), de.costs());
  };
  const auto one = run(1, 7, ThreadPoolEvaluator::Partition::dynamic);
  const auto four = run(4, 7, ThreadPoolEvaluator::Partition::dynamic);
  const auto four_static = run(4, 7, ThreadPoolEvaluator::Partition::static_blocks);
  expect_same_state(one.first, four.first);
  EXPECT_EQ(one.second, four.second);
  expect_same_state(one.first, four_static.first);
  EXPECT_EQ(one.second, four_static.second);
  const auto other_seed = run(4, 8, ThreadPoolEvaluator::Partition::dynamic);
  EXPECT_NE(one.first.best, other_seed.first.best);
  EXPECT_NE(one.second, other_seed.second);
}

TEST(DifferentialEvolution, InitialPopulationIsUniformInTheInitBox) {
  DeParams p = small_params(200, 3);
  p.init_lower = 2;
  p.init_upper = 5;
  std::vector<std::vector<double>> first_batch;
  class Recorder final : public BatchEvaluator {
   public:
    explicit Recorder(std::vector<std::vector<double>>& out) : out_(out) {}
    void evaluate(const std::vector<std::vector<double>>& c, std::vector<double>& costs) override {
      if (out_.empty()) out_ = c;
      costs.assign(c.size(), 1.0);
    }
    std::vector<std::vector<double>>& out_;
  } recorder(first_batch);
  DifferentialEvolution recorded(p, recorder);
  recorded.step();
  ASSERT_EQ(first_batch.size(), 200u);
  double sum = 0;
  for (const auto& member : first_batch) {
    for (double x : member) {
      EXPECT_GE(x, 2.0);
      EXPECT_LT(x, 5.0);
      sum += x;
    }
  }
  EXPECT_NEAR(sum / 600.0, 3.5, 0.15);
}

TEST(DifferentialEvolution, NonFiniteCostsAreWorstAndNeverReplaceFiniteOnes) {
  // NaN wherever x_0 > 0.2: half the box blows up. The "remote" evaluator does not map NaN itself.
  RawEvaluator evaluator([](const std::vector<double>& x) { return x[0] > 0.2 ? kNan : sphere(x); });
  DifferentialEvolution de(small_params(30, 4), evaluator);
  de.step();
  std::size_t finite_before = 0;
  for (double c : de.costs()) finite_before += std::isfinite(c) ? 1 : 0;
  for (int g = 0; g < 60; ++g) {
    std::vector<bool> was_finite;
    for (double c : de.costs()) was_finite.push_back(std::isfinite(c));
    const auto r = de.step();
    for (std::size_t i = 0; i < was_finite.size(); ++i) {
      EXPECT_FALSE(std::isnan(de.costs()[i]));
      if (was_finite[i]) {
        EXPECT_TRUE(std::isfinite(de.costs()[i])) << "member " << i << " generation " << g;
      }
    }
    EXPECT_TRUE(std::isfinite(r.mean_cost));
    EXPECT_LE(r.best[0], 0.2);
  }
  std::size_t finite_after = 0;
  for (double c : de.costs()) finite_after += std::isfinite(c) ? 1 : 0;
  EXPECT_GT(finite_before, 0u);
  EXPECT_LT(finite_before, 30u);
  EXPECT_EQ(finite_after, 30u);  // the blown-up members were all replaced by finite trials
}

TEST(DifferentialEvolution, AllNonFiniteStillRuns) {
  RawEvaluator evaluator([](const std::vector<double>&) { return kNan; });
  DifferentialEvolution de(small_params(8, 2), evaluator);
  const auto r = run_generations(de, 3);
  EXPECT_EQ(r.best_cost, kInf);
  EXPECT_EQ(r.mean_cost, kInf);
  EXPECT_EQ(r.best.size(), 2u);
}

TEST(DifferentialEvolution, AFailedBatchLeavesTheRunUnchanged) {
  RawEvaluator flaky(sphere);
  RawEvaluator steady(sphere);
  DifferentialEvolution a(small_params(10, 3), flaky);
  DifferentialEvolution b(small_params(10, 3), steady);
  run_generations(a, 3);
  run_generations(b, 3);
  flaky.fail_next = true;
  EXPECT_THROW(a.step(), std::runtime_error);
  expect_same_state(a.report(), b.report());
  run_generations(a, 4);
  run_generations(b, 4);
  expect_same_state(a.report(), b.report());
  EXPECT_EQ(a.population(), b.population());
}

// ---------------------------------------------------------------------------
// Checkpoints (DE)

TEST(DifferentialEvolutionCheckpoint, ResumedRunIsBitIdenticalToAnUninterruptedOne) {
  ThreadPoolEvaluator evaluator(rastrigin, 2);
  DeParams p = small_params(16, 5, 42);
  const std::string path = temp_path("de_resume.txt");
  for (std::uint64_t k : {0u, 1u, 9u}) {
    DifferentialEvolution uninterrupted(p, evaluator);
    run_generations(uninterrupted, k + 13);

    DifferentialEvolution first(p, evaluator);
    run_generations(first, k);
    first.save_checkpoint(path);
    DeParams other = p;
    other.seed = 999;  // the file's RNG state and seed take over
    DifferentialEvolution resumed(other, evaluator);
    resumed.load_checkpoint(path);
    expect_same_state(resumed.report(), first.report());
    run_generations(resumed, 13);

    expect_same_state(resumed.report(), uninterrupted.report());
    EXPECT_EQ(resumed.population(), uninterrupted.population()) << "k = " << k;
    EXPECT_EQ(resumed.costs(), uninterrupted.costs());
    EXPECT_EQ(resumed.params().seed, 42u);
  }
  std::ifstream tmp(path + ".tmp");
  EXPECT_FALSE(tmp.good()) << "the temporary file is renamed away";
  std::remove(path.c_str());
}

TEST(DifferentialEvolutionCheckpoint, FileIsDocumentedText) {
  ThreadPoolEvaluator evaluator(sphere, 1);
  DifferentialEvolution de(small_params(5, 2), evaluator);
  de.step();
  const std::string path = temp_path("de_text.txt");
  de.save_checkpoint(path);
  const std::string text = read_text(path);
  EXPECT_EQ(text.rfind("pmlsm-optimiser-checkpoint 1\noptimiser DE/rand/1/bin\npopulation_size 5\n", 0), 0u);
  EXPECT_NE(text.find("\nmember 4 "), std::string::npos);
  EXPECT_EQ(text.substr(text.size() - 4), "end\n");
  std::remove(path.c_str());
}

TEST(DifferentialEvolutionCheckpoint, BadFilesThrowNamingTheFileAndLeaveTheOptimiserAlone) {
  ThreadPoolEvaluator evaluator(sphere, 1);
  DifferentialEvolution de(small_params(6, 3), evaluator);
  run_generations(de, 2);
  const std::string good = temp_path("de_good.txt");
  de.save_checkpoint(good);
  const std::string text = read_text(good);
  const std::string bad = temp_path("de_bad.txt");

  DifferentialEvolution target(small_params(6, 3, 5), evaluator);
  run_generations(target, 1);
  const auto target_before = target.report();

  EXPECT_THROW_WITH(target.load_checkpoint(temp_path("does_not_exist.txt")), std::runtime_error,
                    "does_not_exist.txt': cannot open");

  // Truncated anywhere: at a line end, mid-line, in the header.
  for (std::size_t cut : {text.size() - 4, text.size() - 5, text.size() / 2, std::size_t{10}, std::size_t{0}}) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    write_text(bad, text.substr(0, cut));
    EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "de_bad.txt'");
  }
  write_text(bad, text.substr(0, text.find("member 3")));
  EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "truncated");

  // Corrupt number.
  std::string corrupt = text;
  corrupt.replace(corrupt.find("member 2 ") + 9, 1, "x");
  write_text(bad, corrupt);
  EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "is not a number");

  // Corrupt RNG state.
  corrupt = text;
  corrupt.replace(corrupt.find("rng ") + 4, 3, "abc");
  write_text(bad, corrupt);
  EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "RNG state");

  // Not a checkpoint at all.
  write_text(bad, "hello\nworld\n");
  EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "not an optimiser checkpoint");

  // Wrong dimension / population size.
  DifferentialEvolution wider(small_params(6, 4), evaluator);
  EXPECT_THROW_WITH(wider.load_checkpoint(good), std::runtime_error, "de_good.txt': dimension 3 does not match");
  DifferentialEvolution bigger(small_params(7, 3), evaluator);
  EXPECT_THROW_WITH(bigger.load_checkpoint(good), std::runtime_error, "population_size 6 does not match");

  // Wrong optimiser.
  PagmoOptimiser jde(PagmoAlgorithm::jde, small_params(8, 3), evaluator);
  EXPECT_THROW_WITH(jde.load_checkpoint(good), std::runtime_error, "written by DE/rand/1/bin, not by jDE");

  // Inconsistent counters.
  corrupt = text;
  corrupt.replace(corrupt.find("evaluations 18"), 14, "evaluations 17");
  write_text(bad, corrupt);
  EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "inconsistent");

  // Trailing garbage.
  write_text(bad, text + "more\n");
  EXPECT_THROW_WITH(target.load_checkpoint(bad), std::runtime_error, "after 'end'");

  expect_same_state(target.report(), target_before);
  std::remove(good.c_str());
  std::remove(bad.c_str());
}

TEST(DifferentialEvolutionCheckpoint, SaveToAnUnwritablePlaceThrowsNamingTheFile) {
  ThreadPoolEvaluator evaluator(sphere, 1);
  DifferentialEvolution de(small_params(5, 2), evaluator);
  EXPECT_THROW_WITH(de.save_checkpoint("/nonexistent_dir/x.txt"), std::runtime_error,
                    "checkpoint '/nonexistent_dir/x.txt': cannot create");
}

// ---------------------------------------------------------------------------
// jDE and CMA-ES through pagmo

struct PagmoCase {
  PagmoAlgorithm algorithm;
  const char* label;
};

void PrintTo(const PagmoCase& c, std::ostream* out) { *out << c.label; }

class PagmoOptimiserTest : public ::testing::TestWithParam<PagmoCase> {};

TEST_P(PagmoOptimiserTest, SolvesSphere10) {
  ThreadPoolEvaluator evaluator(sphere, 2);
  PagmoOptimiser optimiser(GetParam().algorithm, small_params(30, 10), evaluator);
  const auto r = run_until(optimiser, 1e-6, 1500);
  EXPECT_LT(r.best_cost, 1e-6) << "after " << r.generation << " generations";
  EXPECT_EQ(sphere(r.best), r.best_cost);
}

TEST_P(PagmoOptimiserTest, SolvesRosenbrock5) {
  ThreadPoolEvaluator evaluator(rosenbrock, 2);
  DeParams p = small_params(30, 5);
  p.init_lower = -2;
  p.init_upper = 2;
  PagmoOptimiser optimiser(GetParam().algorithm, p, evaluator);
  const auto r = run_until(optimiser, 1e-3, 3000);
  EXPECT_LT(r.best_cost, 1e-3) << "after " << r.generation << " generations";
  for (double x : r.best) EXPECT_NEAR(x, 1.0, 0.05);
}

TEST_P(PagmoOptimiserTest, CountsEvaluations) {
  ThreadPoolEvaluator pool(sphere, 2);
  CountingEvaluator counter(pool);
  PagmoOptimiser optimiser(GetParam().algorithm, small_params(10, 3), counter);
  EXPECT_EQ(optimiser.report().evaluations, 0u);
  EXPECT_EQ(optimiser.report().best_cost, kInf);
  for (std::uint64_t g = 1; g <= 5; ++g) {
    const auto r = optimiser.step();
    EXPECT_EQ(r.generation, g);
    EXPECT_EQ(r.evaluations, 10 * (g + 1));  // both evaluate NP candidates a generation
    EXPECT_EQ(counter.candidates_seen, r.evaluations);
  }
  // The initial population is one batch; pagmo then evaluates one candidate at a time (no bfe support).
  EXPECT_EQ(counter.batches, 1u + 5u * 10u);
}

TEST_P(PagmoOptimiserTest, SameSeedSameRunForAnyThreadCountDifferentSeedDifferentRun) {
  const auto run = [&](unsigned threads, std::uint64_t seed) {
    ThreadPoolEvaluator evaluator(rosenbrock, threads);
    PagmoOptimiser optimiser(GetParam().algorithm, small_params(12, 4, seed), evaluator);
    run_generations(optimiser, 25);
    return std::make_pair(optimiser.report(), optimiser.costs());
  };
  const auto one = run(1, 3);
  const auto four = run(4, 3);
  expect_same_state(one.first, four.first);
  EXPECT_EQ(one.second, four.second);
  const auto other = run(1, 4);
  EXPECT_NE(one.first.best, other.first.best);
}

TEST_P(PagmoOptimiserTest, StartsFromTheSamePopulationAsDe) {
  std::vector<std::vector<double>> de_batch, pagmo_batch;
  class Recorder final : public BatchEvaluator {
   public:
    explicit Recorder(std::vector<std::vector<double>>& out) : out_(out) {}
    void evaluate(const std::vector<std::vector<double>>& c, std::vector<double>& costs) override {
      if (out_.empty()) out_ = c;
      costs.clear();
      for (const auto& x : c) costs.push_back(sphere(x));
    }
    std::vector<std::vector<double>>& out_;
  };
  Recorder de_recorder(de_batch), pagmo_recorder(pagmo_batch);
  DifferentialEvolution de(small_params(9, 3, 77), de_recorder);
  PagmoOptimiser optimiser(GetParam().algorithm, small_params(9, 3, 77), pagmo_recorder);
  de.step();
  optimiser.step();
  EXPECT_EQ(de_batch, pagmo_batch);
}

TEST_P(PagmoOptimiserTest, NonFiniteCostsAreWorst) {
  RawEvaluator evaluator([](const std::vector<double>& x) { return x[0] > 0.2 ? kNan : sphere(x); });
  PagmoOptimiser optimiser(GetParam().algorithm, small_params(12, 3), evaluator);
  for (int g = 0; g < 40; ++g) {
    const auto r = optimiser.step();
    EXPECT_TRUE(std::isfinite(r.best_cost));
    EXPECT_LE(r.best[0], 0.2);
    for (double c : optimiser.costs()) EXPECT_FALSE(std::isnan(c));
  }
}

TEST_P(PagmoOptimiserTest, ResumedRunIsBitIdenticalToAnUninterruptedOne) {
  ThreadPoolEvaluator evaluator(rosenbrock, 2);
  const DeParams p = small_params(10, 4, 11);
  const std::string path = temp_path(std::string(GetParam().label) + "_resume.txt");
  for (std::uint64_t k : {0u, 1u, 12u}) {
    PagmoOptimiser uninterrupted(GetParam().algorithm, p, evaluator);
    run_generations(uninterrupted, k + 15);

    PagmoOptimiser first(GetParam().algorithm, p, evaluator);
    run_generations(first, k);
    first.save_checkpoint(path);
    DeParams other = p;
    other.seed = 12345;
    PagmoOptimiser resumed(GetParam().algorithm, other, evaluator);
    resumed.load_checkpoint(path);
    expect_same_state(resumed.report(), first.report());
    run_generations(resumed, 15);

    expect_same_state(resumed.report(), uninterrupted.report());
    EXPECT_EQ(resumed.population(), uninterrupted.population()) << "k = " << k;
    EXPECT_EQ(resumed.costs(), uninterrupted.costs());
  }
  std::remove(path.c_str());
}

TEST_P(PagmoOptimiserTest, BadCheckpointsThrowNamingTheFile) {
  ThreadPoolEvaluator evaluator(sphere, 1);
  PagmoOptimiser optimiser(GetParam().algorithm, small_params(10, 3), evaluator);
  run_generations(optimiser, 3);
  const std::string good = temp_path(std::string(GetParam().label) + "_good.txt");
  const std::string bad = temp_path(std::string(GetParam().label) + "_bad.txt");
  optimiser.save_checkpoint(good);
  const std::string text = read_text(good);
  const auto before = optimiser.report();

  for (std::size_t cut : {text.size() - 4, text.size() - 30, text.find("algorithm_state"), text.size() / 3}) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    write_text(bad, text.substr(0, cut));
    EXPECT_THROW_WITH(optimiser.load_checkpoint(bad), std::runtime_error, "_bad.txt'");
  }
  std::string corrupt = text;
  const auto state_at = text.find('\n', text.find("algorithm_state ")) + 1;
  corrupt.replace(state_at, 10, "xxxxxxxxxx");
  write_text(bad, corrupt);
  EXPECT_THROW_WITH(optimiser.load_checkpoint(bad), std::runtime_error, "corrupt algorithm state");

  PagmoOptimiser wider(GetParam().algorithm, small_params(10, 5), evaluator);
  EXPECT_THROW_WITH(wider.load_checkpoint(good), std::runtime_error, "dimension 3 does not match");
  const auto other_kind = GetParam().algorithm == PagmoAlgorithm::jde ? PagmoAlgorithm::cmaes : PagmoAlgorithm::jde;
  PagmoOptimiser other(other_kind, small_params(10, 3), evaluator);
  EXPECT_THROW_WITH(other.load_checkpoint(good), std::runtime_error, "written by");
  DifferentialEvolution de(small_params(10, 3), evaluator);
  EXPECT_THROW_WITH(de.load_checkpoint(good), std::runtime_error, "not by DE/rand/1/bin");

  expect_same_state(optimiser.report(), before);
  std::remove(good.c_str());
  std::remove(bad.c_str());
}

TEST(Optimisers, RunAndCheckpointAtTable1Sizes) {
  // NP = 120, D = 91 (Table 1): a few generations and a checkpoint round trip for each optimiser.
  ThreadPoolEvaluator evaluator(sphere, 2);
  const DeParams table1;
  const std::string path = temp_path("table1.txt");
  for (auto kind : {OptimiserKind::de, OptimiserKind::jde, OptimiserKind::cmaes}) {
    auto optimiser = make_optimiser(kind, table1, evaluator);
    SCOPED_TRACE(optimiser->name());
    const auto first = run_generations(*optimiser, 3);
    EXPECT_EQ(first.evaluations, 120u * 4u);
    EXPECT_EQ(first.best.size(), 91u);
    optimiser->save_checkpoint(path);
    auto resumed = make_optimiser(kind, table1, evaluator);
    resumed->load_checkpoint(path);
    EXPECT_EQ(optimiser->step().best, resumed->step().best);
    EXPECT_LE(optimiser->report().best_cost, first.best_cost);
  }
  std::remove(path.c_str());
}

// A search started from a known candidate: its cost is in the first report and the search never
// ends above it. The candidate is the sphere's optimum here, away from the init box, so only
// the start can have found it; without it no member comes near. The other members are drawn
// as without it, and a wrong-size or non-finite candidate is refused naming the field.
TEST(Optimisers, AFirstMemberStartsTheSearchAndIsNeverLost) {
  ThreadPoolEvaluator evaluator(shifted_sphere_cost, 2);
  DeParams p = small_params(12, 4);
  p.init_lower = 5;
  p.init_upper = 6;
  for (auto kind : {OptimiserKind::de, OptimiserKind::jde, OptimiserKind::cmaes}) {
    auto drawn = make_optimiser(kind, p, evaluator);
    DeParams started = p;
    started.first_member = {1, 1, 1, 1};
    auto from_member = make_optimiser(kind, started, evaluator);
    SCOPED_TRACE(from_member->name());
    const OptimiserReport without = drawn->step();
    const OptimiserReport with = from_member->step();
    EXPECT_GT(without.best_cost, 10.0);
    EXPECT_EQ(with.best_cost, 0.0);
    EXPECT_EQ(with.best, started.first_member);
    EXPECT_EQ(run_generations(*from_member, 5).best_cost, 0.0);
  }
  DeParams wrong = p;
  wrong.first_member = {1, 1, 1};
  EXPECT_THROW_WITH(wrong.validate(), std::invalid_argument, "first_member: expected 4 values, got 3");
  wrong.first_member = {1, 1, kNan, 1};
  EXPECT_THROW_WITH(wrong.validate(), std::invalid_argument, "first_member[2]: must be finite");
}

INSTANTIATE_TEST_SUITE_P(Pagmo, PagmoOptimiserTest,
                         ::testing::Values(PagmoCase{PagmoAlgorithm::jde, "jDE"},
                                           PagmoCase{PagmoAlgorithm::cmaes, "CMAES"}),
                         [](const ::testing::TestParamInfo<PagmoCase>& info) { return info.param.label; });

/// A 2-D pagmo problem (its own fitness is never called here).
struct TwoDimensionalProblem {
  pagmo::vector_double fitness(const pagmo::vector_double& x) const { return {sphere(x)}; }
  std::pair<pagmo::vector_double, pagmo::vector_double> get_bounds() const { return {{-5, -5}, {5, 5}}; }
};

TEST(BatchEvaluatorBfe, ForwardsToTheBatchEvaluatorAndCountsEvaluations) {
  ThreadPoolEvaluator pool(sphere, 2);
  CountingEvaluator counter(pool);
  const pagmo::bfe bfe{BatchEvaluatorBfe{counter}};
  const pagmo::problem problem{TwoDimensionalProblem{}};
  const std::vector<double> dvs{1, 2, 3, 4, 0, 0};
  const auto costs = bfe(problem, dvs);
  EXPECT_EQ(costs, (std::vector<double>{5, 25, 0}));
  EXPECT_EQ(counter.batches, 1u);
  EXPECT_EQ(problem.get_fevals(), 3u);
  EXPECT_THROW(BatchEvaluatorBfe{}(problem, dvs), std::logic_error);
}

}  // namespace
}  // namespace pmlsm
