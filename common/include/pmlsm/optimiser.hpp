// Population-based optimisers for training the vibration compensator (paper
// section 3.3), behind one interface so that the trainer can switch between
// the paper's DE/rand/1/bin and pagmo2's jDE and CMA-ES
// (pmlsm/pagmo_optimisers.hpp) without changing anything else.
//
// Evaluation seam: an optimiser never calls the cost itself; it hands whole
// batches of candidates to a BatchEvaluator, which may run them on local
// threads (ThreadPoolEvaluator) or on remote workers.
//
// Determinism: for a given seed the sequence of candidates and the result are
// identical for any evaluator and any thread count, because all random numbers
// are drawn in one thread before the batch is evaluated and costs are returned
// by index.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace pmlsm {

/// Cost of one candidate; must be deterministic and thread-safe (called concurrently).
using CostFunction = std::function<double(const std::vector<double>& candidate)>;

/// Evaluates a batch of candidates, costs[i] for candidates[i]. The seam where remote workers plug in.
/// Implementations resize `costs` to candidates.size().
class BatchEvaluator {
 public:
  virtual ~BatchEvaluator() = default;
  virtual void evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) = 0;
};

/// Runs a CostFunction on N local threads (N >= 1: the calling thread plus N-1
/// pool threads kept alive between batches). Results are stored by index, so
/// the thread count and partition never change the results. Non-finite costs
/// are mapped to +infinity (a candidate that blows the simulation up is simply
/// worst). If the cost throws, the batch is finished and the exception of the
/// lowest failing index is rethrown from evaluate().
/// evaluate() may be called from several threads; calls are serialised.
class ThreadPoolEvaluator final : public BatchEvaluator {
 public:
  enum class Partition {
    static_blocks,  ///< thread t evaluates the contiguous block [t n / N, (t+1) n / N)
    dynamic,        ///< threads take the next unevaluated index (uneven costs balance out)
  };

  /// @throws std::invalid_argument if `cost` is empty or threads == 0.
  ThreadPoolEvaluator(CostFunction cost, unsigned threads, Partition partition = Partition::dynamic);
  ~ThreadPoolEvaluator() override;
  ThreadPoolEvaluator(const ThreadPoolEvaluator&) = delete;
  ThreadPoolEvaluator& operator=(const ThreadPoolEvaluator&) = delete;

  void evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) override;
  unsigned threads() const { return threads_; }
  Partition partition() const { return partition_; }

 private:
  struct Pool;  // worker threads and their hand-over state
  /// The indices of `slot` (0..N-1, the caller is N-1) under the partition.
  void run_share(unsigned slot, const std::vector<std::vector<double>>& candidates, double* costs);
  void evaluate_one(std::size_t index, const std::vector<std::vector<double>>& candidates, double* costs);
  CostFunction cost_;
  unsigned threads_;
  Partition partition_;
  std::unique_ptr<Pool> pool_;
};

struct OptimiserReport {
  std::uint64_t generation = 0;   // generations completed
  std::uint64_t evaluations = 0;  // cost evaluations so far (including the initial population)
  double best_cost = 0;           // +infinity before the first step()
  double mean_cost = 0;           // over the current population (finite members; +infinity if none)
  std::vector<double> best;       // best candidate so far (empty before the first step())
};

class Optimiser {
 public:
  virtual ~Optimiser() = default;
  virtual std::string name() const = 0;  // "DE/rand/1/bin", "jDE", "CMA-ES"
  /// One generation (the first call also evaluates the initial population).
  virtual OptimiserReport step() = 0;
  virtual OptimiserReport report() const = 0;
  /// Atomic: writes path + ".tmp", fsyncs it, renames it to path, fsyncs the directory.
  /// @throws std::runtime_error naming the file if it cannot be written.
  virtual void save_checkpoint(const std::string& path) const = 0;
  /// Replaces the whole state by the checkpoint's; the optimiser is unchanged if this throws.
  /// @throws std::runtime_error naming the file and what is wrong (missing, wrong optimiser,
  ///         wrong dimension, corrupt or truncated).
  virtual void load_checkpoint(const std::string& path) = 0;
};

struct DeParams {
  std::size_t population_size = 120;           // NP, Table 1; >= 4 (jDE needs >= 7, CMA-ES >= 5)
  std::size_t dimension = 91;                  // D, Table 1; >= 1
  double mutation_factor = 0.8;                // F_s, (21); in (0, 2]
  double crossover_rate = 0.7;                 // CR, (22); in [0, 1]
  double init_lower = -1.0, init_upper = 1.0;  // Table 1; lower < upper, finite
  std::uint64_t seed = 1;
  /// @throws std::invalid_argument "population_size: must be >= 4, got 3" style.
  void validate() const;
};

/// DE/rand/1/bin exactly as the paper, eqs. (21)-(22):
///   init      x_i,j ~ U[init_lower, init_upper]
///   mutation  v_i = x_r3 + F_s (x_r1 - x_r2),  r1, r2, r3 distinct and != i      (21)
///   crossover u_i,j = v_i,j if rand_j < CR or j == j_rand, else x_i,j          (22)
///   selection x_i <- u_i if cost(u_i) <= cost(x_i)
/// A generation's random numbers are drawn first, then all NP trials are
/// evaluated as one batch, then selection (so the result does not depend on
/// the evaluator). There is no bound handling after the initialisation: the
/// paper has none, and the network weights may leave the initial box.
///
/// Checkpoint: a text file, see save_checkpoint() in optimiser.cpp for the
/// format. A resumed run continues bit-identically to an uninterrupted one.
/// population_size and dimension must match the optimiser's; the other
/// parameters (F_s, CR, init box, seed) and the RNG state are taken from the
/// file so that the saved run continues as it was.
class DifferentialEvolution final : public Optimiser {
 public:
  /// The evaluator must outlive the optimiser.
  /// @throws std::invalid_argument naming the first invalid parameter.
  DifferentialEvolution(const DeParams& params, BatchEvaluator& evaluator);

  std::string name() const override { return "DE/rand/1/bin"; }
  OptimiserReport step() override;
  OptimiserReport report() const override;
  void save_checkpoint(const std::string& path) const override;
  void load_checkpoint(const std::string& path) override;

  const DeParams& params() const { return params_; }
  /// Current population and its costs (empty before the first step()).
  const std::vector<std::vector<double>>& population() const { return population_; }
  const std::vector<double>& costs() const { return costs_; }

 private:
  void initialise_population();
  std::size_t best_index() const;

  DeParams params_;
  BatchEvaluator* evaluator_;  // not owned
  std::mt19937_64 rng_;
  bool initialised_ = false;
  std::uint64_t generation_ = 0;
  std::uint64_t evaluations_ = 0;
  std::vector<std::vector<double>> population_;
  std::vector<double> costs_;
};

enum class OptimiserKind { de, jde, cmaes };

/// "de" | "jde" | "cmaes". @throws std::invalid_argument listing the choices.
OptimiserKind parse_optimiser_kind(const std::string& text);

/// jDE/CMA-ES use population_size, dimension, init bounds and seed from `common`
/// (mutation_factor and crossover_rate are DE-only). The evaluator must outlive the optimiser.
/// @throws std::invalid_argument naming the first invalid parameter.
std::unique_ptr<Optimiser> make_optimiser(OptimiserKind kind, const DeParams& common, BatchEvaluator& evaluator);

// Random-number mappings used by the optimisers, defined here (not
// std::uniform_*_distribution, whose output is implementation-defined) so a
// seed gives the same run with any standard library.

/// Uniform in [0, 1) from the top 53 bits of one draw.
inline double uniform_unit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Uniform integer in [0, n), n >= 1, unbiased by rejection of the draws below 2^64 mod n.
inline std::uint64_t uniform_index(std::mt19937_64& rng, std::uint64_t n) {
  const std::uint64_t reject_below = (0 - n) % n;  // (2^64 - n) mod n == 2^64 mod n
  std::uint64_t draw = rng();
  while (draw < reject_below) draw = rng();
  return draw % n;
}

namespace detail {

// Checkpoint plumbing shared by optimiser.cpp and pagmo_optimisers.cpp; not an API.

/// Writes path + ".tmp", fsyncs it, renames it over path and fsyncs the directory,
/// so that path holds either the old or the new contents after a crash.
/// @throws std::runtime_error "checkpoint '<path>': <what failed>: <strerror>".
void write_file_atomically(const std::string& path, const std::string& contents);

/// 17 significant digits ("%.17g"): reads back (strtod) to the same double; "inf", "nan" for non-finite.
std::string format_exact(double value);

/// Line-oriented reader of a checkpoint text file. Every error is a
/// std::runtime_error "checkpoint '<path>': <what> (line N)".
class CheckpointReader {
 public:
  /// Reads the whole file. @throws if it cannot be opened or read.
  explicit CheckpointReader(std::string path);

  /// First two lines: "pmlsm-optimiser-checkpoint 1" and "optimiser <name>"; throws unless name == optimiser.
  void expect_header(const std::string& optimiser);
  /// Next line "<key> <tokens...>": the tokens after the key.
  std::vector<std::string> fields(const std::string& key);
  /// Next line "<key> <text>": everything after "<key> ".
  std::string text(const std::string& key);
  std::uint64_t count(const std::string& key);  // one unsigned decimal integer
  /// count(key), which must equal the optimiser's own value (population size, dimension).
  std::uint64_t matching_count(const std::string& key, std::uint64_t expected);
  double number(const std::string& key);        // one double
  /// Next line "member <index> <cost> <dimension components>", index checked; the cost is
  /// returned for the caller to check, the components go to `member`.
  double member(std::size_t index, std::size_t dimension, std::vector<double>& member);
  /// Next line "<key> <n doubles>".
  std::vector<double> numbers(const std::string& key, std::size_t n);
  /// Exactly n raw characters followed by a newline.
  std::string raw(std::size_t n);
  /// The line "end" and nothing after it.
  void expect_end();

  std::uint64_t parse_count(const std::string& token) const;
  double parse_number(const std::string& token) const;
  [[noreturn]] void fail(const std::string& what) const;
  const std::string& path() const { return path_; }

 private:
  std::string next_line(const std::string& expected);

  std::string path_;
  std::string contents_;
  std::size_t offset_ = 0;
  std::size_t line_number_ = 0;  // of the line last read
};

}  // namespace detail

}  // namespace pmlsm
