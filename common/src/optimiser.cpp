// DE/rand/1/bin (paper eqs. 21-22), the thread-pool evaluator and the
// checkpoint plumbing.
//
// DE checkpoint file (text, one item a line, doubles with 17 significant
// digits so that they read back exactly; "inf" for an infinite cost):
//
//   pmlsm-optimiser-checkpoint 1
//   optimiser DE/rand/1/bin
//   population_size <NP>
//   dimension <D>
//   mutation_factor <F_s>
//   crossover_rate <CR>
//   init_lower <x_lo>
//   init_upper <x_hi>
//   seed <seed>
//   generation <generations completed>
//   evaluations <cost evaluations so far>
//   initialised <0|1>                      (0: step() has not run, no members follow)
//   rng <std::mt19937_64 state, as its operator<< writes it>
//   member <i> <cost_i> <x_i,0> ... <x_i,D-1>   (NP lines, i = 0..NP-1, if initialised)
//   end
#include "pmlsm/optimiser.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>

#include "pmlsm/pagmo_optimisers.hpp"
#include "pmlsm/validate.hpp"

namespace pmlsm {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr const char* kCheckpointTag = "pmlsm-optimiser-checkpoint";
constexpr std::uint64_t kCheckpointVersion = 1;

/// A cost that is NaN or infinite (a run that blew up) is simply the worst.
double finite_or_worst(double cost) { return std::isfinite(cost) ? cost : kInfinity; }

/// Runs one batch through the evaluator and checks what came back.
void evaluate_batch(BatchEvaluator& evaluator, const std::vector<std::vector<double>>& candidates,
                    std::vector<double>& costs) {
  evaluator.evaluate(candidates, costs);
  if (costs.size() != candidates.size()) {
    throw std::runtime_error("BatchEvaluator returned " + std::to_string(costs.size()) + " costs for " +
                             std::to_string(candidates.size()) + " candidates");
  }
  for (double& cost : costs) cost = finite_or_worst(cost);
}

std::string checkpoint_prefix(const std::string& path) { return "checkpoint '" + path + "': "; }

[[noreturn]] void throw_system_error(const std::string& path, const std::string& what) {
  const int error = errno;
  throw std::runtime_error(checkpoint_prefix(path) + what + ": " + std::strerror(error));
}

}  // namespace

// ---------------------------------------------------------------------------
// ThreadPoolEvaluator

struct ThreadPoolEvaluator::Pool {
  // Hand-over of one batch from the calling thread to the pool threads.
  std::mutex mutex;
  std::condition_variable work_ready;
  std::condition_variable work_done;
  std::uint64_t batch_id = 0;     // incremented for each batch handed over
  unsigned workers_running = 0;   // pool threads still working on the current batch
  bool stopping = false;
  const std::vector<std::vector<double>>* candidates = nullptr;
  double* costs = nullptr;
  std::atomic<std::size_t> next_index{0};  // Partition::dynamic

  // First failure by candidate index, so which exception is rethrown does not depend on timing.
  std::mutex error_mutex;
  std::size_t error_index = std::numeric_limits<std::size_t>::max();
  std::exception_ptr error;

  std::mutex evaluate_mutex;  // serialises evaluate() calls
  std::vector<std::thread> threads;
};

ThreadPoolEvaluator::ThreadPoolEvaluator(CostFunction cost, unsigned threads, Partition partition)
    : cost_(std::move(cost)), threads_(threads), partition_(partition), pool_(std::make_unique<Pool>()) {
  if (!cost_) throw std::invalid_argument("cost: must be a callable, got an empty function");
  if (threads_ < 1) throw std::invalid_argument("threads: must be >= 1, got 0");
  // The calling thread is the last of the N; N - 1 pool threads wait for batches.
  for (unsigned slot = 0; slot + 1 < threads_; ++slot) {
    pool_->threads.emplace_back([this, slot] {
      Pool& pool = *pool_;
      std::uint64_t seen_batch = 0;
      for (;;) {
        std::unique_lock<std::mutex> lock(pool.mutex);
        pool.work_ready.wait(lock, [&] { return pool.stopping || pool.batch_id != seen_batch; });
        if (pool.stopping) return;
        seen_batch = pool.batch_id;
        const auto& candidates = *pool.candidates;
        double* costs = pool.costs;
        lock.unlock();
        run_share(slot, candidates, costs);
        lock.lock();
        if (--pool.workers_running == 0) pool.work_done.notify_one();
      }
    });
  }
}

ThreadPoolEvaluator::~ThreadPoolEvaluator() {
  {
    std::lock_guard<std::mutex> lock(pool_->mutex);
    pool_->stopping = true;
  }
  pool_->work_ready.notify_all();
  for (auto& thread : pool_->threads) thread.join();
}

void ThreadPoolEvaluator::evaluate_one(std::size_t index, const std::vector<std::vector<double>>& candidates,
                                       double* costs) {
  try {
    costs[index] = finite_or_worst(cost_(candidates[index]));
  } catch (...) {
    costs[index] = kInfinity;
    std::lock_guard<std::mutex> lock(pool_->error_mutex);
    if (index < pool_->error_index) {
      pool_->error_index = index;
      pool_->error = std::current_exception();
    }
  }
}

void ThreadPoolEvaluator::run_share(unsigned slot, const std::vector<std::vector<double>>& candidates,
                                    double* costs) {
  const std::size_t count = candidates.size();
  if (partition_ == Partition::static_blocks) {
    const std::size_t begin = count * slot / threads_;
    const std::size_t end = count * (slot + 1) / threads_;
    for (std::size_t i = begin; i < end; ++i) evaluate_one(i, candidates, costs);
  } else {
    for (std::size_t i = pool_->next_index.fetch_add(1); i < count; i = pool_->next_index.fetch_add(1)) {
      evaluate_one(i, candidates, costs);
    }
  }
}

void ThreadPoolEvaluator::evaluate(const std::vector<std::vector<double>>& candidates,
                                   std::vector<double>& costs) {
  std::lock_guard<std::mutex> serialise(pool_->evaluate_mutex);
  Pool& pool = *pool_;
  costs.assign(candidates.size(), kInfinity);
  pool.error_index = std::numeric_limits<std::size_t>::max();
  pool.error = nullptr;
  if (candidates.empty()) return;

  if (threads_ == 1 || candidates.size() == 1) {
    // Nothing to share: no hand-over cost (pagmo's one-at-a-time calls land here).
    for (std::size_t i = 0; i < candidates.size(); ++i) evaluate_one(i, candidates, costs.data());
  } else {
    {
      std::lock_guard<std::mutex> lock(pool.mutex);
      pool.candidates = &candidates;
      pool.costs = costs.data();
      pool.next_index.store(0);
      pool.workers_running = static_cast<unsigned>(pool.threads.size());
      ++pool.batch_id;
    }
    pool.work_ready.notify_all();
    run_share(threads_ - 1, candidates, costs.data());
    std::unique_lock<std::mutex> lock(pool.mutex);
    pool.work_done.wait(lock, [&] { return pool.workers_running == 0; });
    pool.candidates = nullptr;
    pool.costs = nullptr;
  }
  if (pool.error) std::rethrow_exception(pool.error);
}

// ---------------------------------------------------------------------------
// Parameters

void DeParams::validate() const {
  if (population_size < 4) {
    // r1, r2, r3 and i must be four distinct members, eq. (21).
    throw std::invalid_argument("population_size: must be >= 4, got " + std::to_string(population_size));
  }
  if (dimension < 1) throw std::invalid_argument("dimension: must be >= 1, got " + std::to_string(dimension));
  require_finite("mutation_factor", mutation_factor);
  if (!(mutation_factor > 0.0 && mutation_factor <= 2.0)) {
    throw std::invalid_argument("mutation_factor: must be in (0, 2], got " + format_value(mutation_factor));
  }
  require_in_range("crossover_rate", crossover_rate, 0.0, 1.0);
  require_finite("init_lower", init_lower);
  require_finite("init_upper", init_upper);
  if (!(init_lower < init_upper)) {
    throw std::invalid_argument("init_upper: must be > init_lower (" + format_value(init_lower) + "), got " +
                                format_value(init_upper));
  }
  if (!std::isfinite(init_upper - init_lower)) {
    throw std::invalid_argument("init_upper: init_upper - init_lower must be finite, got " +
                                format_value(init_upper) + " - " + format_value(init_lower));
  }
}

// ---------------------------------------------------------------------------
// DifferentialEvolution

DifferentialEvolution::DifferentialEvolution(const DeParams& params, BatchEvaluator& evaluator)
    : params_(params), evaluator_(&evaluator), rng_(params.seed) {
  params_.validate();
}

void DifferentialEvolution::initialise_population() {
  // x_i,j ~ U[init_lower, init_upper] (Table 1), drawn member by member.
  const double width = params_.init_upper - params_.init_lower;
  std::vector<std::vector<double>> population(params_.population_size, std::vector<double>(params_.dimension));
  for (auto& member : population) {
    for (double& x : member) x = params_.init_lower + width * uniform_unit(rng_);
  }
  std::vector<double> costs;
  evaluate_batch(*evaluator_, population, costs);
  population_ = std::move(population);
  costs_ = std::move(costs);
  evaluations_ += params_.population_size;
  initialised_ = true;
}

OptimiserReport DifferentialEvolution::step() {
  // If the evaluator throws, the optimiser is left as before the call (the
  // RNG is rewound), so a retry continues the same run.
  const std::mt19937_64 rng_before = rng_;
  try {
    if (!initialised_) initialise_population();

    const std::size_t np = params_.population_size;
    const std::size_t dim = params_.dimension;
    const double f_s = params_.mutation_factor;
    const double cr = params_.crossover_rate;

    // 1. All random numbers of the generation, in one thread, in a fixed order:
    //    per member r1, r2, r3, j_rand, then D crossover draws.
    std::vector<std::vector<double>> trials(np, std::vector<double>(dim));
    for (std::size_t i = 0; i < np; ++i) {
      std::size_t r1, r2, r3;  // distinct and != i, by rejection
      do r1 = uniform_index(rng_, np);
      while (r1 == i);
      do r2 = uniform_index(rng_, np);
      while (r2 == i || r2 == r1);
      do r3 = uniform_index(rng_, np);
      while (r3 == i || r3 == r1 || r3 == r2);
      const std::size_t j_rand = uniform_index(rng_, dim);  // this component always comes from the mutant
      const auto& x_i = population_[i];
      const auto& x_r1 = population_[r1];
      const auto& x_r2 = population_[r2];
      const auto& x_r3 = population_[r3];
      for (std::size_t j = 0; j < dim; ++j) {
        const bool from_mutant = uniform_unit(rng_) < cr || j == j_rand;  // (22)
        // (21): v_i = x_r3 + F_s (x_r1 - x_r2). No clipping to the init box: the paper has none.
        trials[i][j] = from_mutant ? x_r3[j] + f_s * (x_r1[j] - x_r2[j]) : x_i[j];
      }
    }

    // 2. The whole generation as one batch.
    std::vector<double> trial_costs;
    evaluate_batch(*evaluator_, trials, trial_costs);
    evaluations_ += np;

    // 3. Greedy selection: the trial replaces its parent if it is no worse.
    //    Costs are finite or +inf, so an infinite trial never replaces a finite parent.
    for (std::size_t i = 0; i < np; ++i) {
      if (trial_costs[i] <= costs_[i]) {
        population_[i] = std::move(trials[i]);
        costs_[i] = trial_costs[i];
      }
    }
    ++generation_;
  } catch (...) {
    rng_ = rng_before;
    throw;
  }
  return report();
}

std::size_t DifferentialEvolution::best_index() const {
  // Lowest cost, first index on ties. Greedy selection is elitist, so this is the best so far.
  return static_cast<std::size_t>(std::min_element(costs_.begin(), costs_.end()) - costs_.begin());
}

OptimiserReport DifferentialEvolution::report() const {
  OptimiserReport out;
  out.generation = generation_;
  out.evaluations = evaluations_;
  out.best_cost = kInfinity;
  out.mean_cost = kInfinity;
  if (!initialised_) return out;
  const std::size_t best = best_index();
  out.best_cost = costs_[best];
  out.best = population_[best];
  double sum = 0;
  std::size_t finite = 0;
  for (double cost : costs_) {
    if (std::isfinite(cost)) {
      sum += cost;
      ++finite;
    }
  }
  if (finite > 0) out.mean_cost = sum / static_cast<double>(finite);
  return out;
}

void DifferentialEvolution::save_checkpoint(const std::string& path) const {
  std::ostringstream out;
  out << kCheckpointTag << ' ' << kCheckpointVersion << '\n'
      << "optimiser " << name() << '\n'
      << "population_size " << params_.population_size << '\n'
      << "dimension " << params_.dimension << '\n'
      << "mutation_factor " << detail::format_exact(params_.mutation_factor) << '\n'
      << "crossover_rate " << detail::format_exact(params_.crossover_rate) << '\n'
      << "init_lower " << detail::format_exact(params_.init_lower) << '\n'
      << "init_upper " << detail::format_exact(params_.init_upper) << '\n'
      << "seed " << params_.seed << '\n'
      << "generation " << generation_ << '\n'
      << "evaluations " << evaluations_ << '\n'
      << "initialised " << (initialised_ ? 1 : 0) << '\n'
      << "rng " << rng_ << '\n';
  if (initialised_) {
    for (std::size_t i = 0; i < population_.size(); ++i) {
      out << "member " << i << ' ' << detail::format_exact(costs_[i]);
      for (double x : population_[i]) out << ' ' << detail::format_exact(x);
      out << '\n';
    }
  }
  out << "end\n";
  detail::write_file_atomically(path, out.str());
}

void DifferentialEvolution::load_checkpoint(const std::string& path) {
  detail::CheckpointReader in(path);
  in.expect_header(name());
  DeParams loaded;
  loaded.population_size = in.matching_count("population_size", params_.population_size);
  loaded.dimension = in.matching_count("dimension", params_.dimension);
  loaded.mutation_factor = in.number("mutation_factor");
  loaded.crossover_rate = in.number("crossover_rate");
  loaded.init_lower = in.number("init_lower");
  loaded.init_upper = in.number("init_upper");
  loaded.seed = in.count("seed");
  try {
    loaded.validate();
  } catch (const std::invalid_argument& e) {
    in.fail(std::string("invalid parameter ") + e.what());
  }
  const std::uint64_t generation = in.count("generation");
  const std::uint64_t evaluations = in.count("evaluations");
  const std::uint64_t initialised = in.count("initialised");
  if (initialised > 1) in.fail("initialised must be 0 or 1");
  const std::uint64_t expected_evaluations =
      initialised == 1 ? loaded.population_size * (generation + 1) : 0;
  if (evaluations != expected_evaluations || (initialised == 0 && generation != 0)) {
    in.fail("generation " + std::to_string(generation) + " and evaluations " + std::to_string(evaluations) +
            " are inconsistent");
  }
  std::mt19937_64 rng;
  {
    std::istringstream state(in.text("rng"));
    state >> rng;
    if (state.fail() || !(state >> std::ws).eof()) in.fail("unreadable RNG state");
  }
  std::vector<std::vector<double>> population;
  std::vector<double> costs;
  if (initialised == 1) {
    for (std::size_t i = 0; i < loaded.population_size; ++i) {
      std::vector<double> member;
      const double cost = in.member(i, loaded.dimension, member);
      if (std::isnan(cost) || cost == -kInfinity) in.fail("member cost must be finite or inf");
      costs.push_back(cost);
      population.push_back(std::move(member));
    }
  }
  in.expect_end();

  // Everything read and checked: commit.
  params_ = loaded;
  rng_ = rng;
  initialised_ = initialised == 1;
  generation_ = generation;
  evaluations_ = evaluations;
  population_ = std::move(population);
  costs_ = std::move(costs);
}

// ---------------------------------------------------------------------------
// Factory

OptimiserKind parse_optimiser_kind(const std::string& text) {
  if (text == "de") return OptimiserKind::de;
  if (text == "jde") return OptimiserKind::jde;
  if (text == "cmaes") return OptimiserKind::cmaes;
  throw std::invalid_argument("optimiser: must be one of de, jde, cmaes, got '" + text + "'");
}

std::unique_ptr<Optimiser> make_optimiser(OptimiserKind kind, const DeParams& common, BatchEvaluator& evaluator) {
  switch (kind) {
    case OptimiserKind::de:
      return std::make_unique<DifferentialEvolution>(common, evaluator);
    case OptimiserKind::jde:
      return std::make_unique<PagmoOptimiser>(PagmoAlgorithm::jde, common, evaluator);
    case OptimiserKind::cmaes:
      return std::make_unique<PagmoOptimiser>(PagmoAlgorithm::cmaes, common, evaluator);
  }
  throw std::invalid_argument("optimiser: unknown kind " + std::to_string(static_cast<int>(kind)));
}

// ---------------------------------------------------------------------------
// Checkpoint plumbing

namespace detail {

void write_file_atomically(const std::string& path, const std::string& contents) {
  const std::string temporary = path + ".tmp";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw_system_error(path, "cannot create '" + temporary + "'");
  const char* data = contents.data();
  std::size_t left = contents.size();
  while (left > 0) {
    const ssize_t written = ::write(fd, data, left);
    if (written < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      ::close(fd);
      ::unlink(temporary.c_str());
      errno = error;
      throw_system_error(path, "cannot write '" + temporary + "'");
    }
    data += written;
    left -= static_cast<std::size_t>(written);
  }
  // fsync before rename: otherwise a crash may leave the new name on empty contents.
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    errno = error;
    throw_system_error(path, "cannot flush '" + temporary + "'");
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    errno = error;
    throw_system_error(path, "cannot rename '" + temporary + "'");
  }
  // Make the rename itself durable (best effort: some file systems refuse to fsync a directory).
  const auto slash = path.find_last_of('/');
  const std::string directory = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  const int dir_fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
}

std::string format_exact(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

CheckpointReader::CheckpointReader(std::string path) : path_(std::move(path)) {
  std::ifstream file(path_, std::ios::binary);
  if (!file) throw_system_error(path_, "cannot open");
  std::ostringstream contents;
  contents << file.rdbuf();
  if (file.bad()) throw_system_error(path_, "cannot read");
  contents_ = contents.str();
}

void CheckpointReader::fail(const std::string& what) const {
  throw std::runtime_error(checkpoint_prefix(path_) + what + " (line " + std::to_string(line_number_) + ")");
}

std::string CheckpointReader::next_line(const std::string& expected) {
  ++line_number_;
  const auto newline = contents_.find('\n', offset_);
  // Every line we write ends in '\n': a missing one means the file was cut short.
  if (newline == std::string::npos) fail("truncated: expected '" + expected + "'");
  std::string line = contents_.substr(offset_, newline - offset_);
  offset_ = newline + 1;
  return line;
}

void CheckpointReader::expect_header(const std::string& optimiser) {
  {
    std::istringstream line(next_line(kCheckpointTag));
    std::string tag, version, extra;
    line >> tag >> version;
    if (tag != kCheckpointTag || line.fail() || (line >> extra)) {
      fail(std::string("not an optimiser checkpoint (first line must be '") + kCheckpointTag + " " +
           std::to_string(kCheckpointVersion) + "')");
    }
    if (version != std::to_string(kCheckpointVersion)) fail("unsupported format version " + version);
  }
  const std::string written_by = text("optimiser");
  if (written_by != optimiser) fail("written by " + written_by + ", not by " + optimiser);
}

std::string CheckpointReader::text(const std::string& key) {
  const std::string line = next_line(key);
  if (line.compare(0, key.size() + 1, key + " ") != 0) {
    fail("corrupt: expected '" + key + "', got '" + line.substr(0, 40) + "'");
  }
  return line.substr(key.size() + 1);
}

std::vector<std::string> CheckpointReader::fields(const std::string& key) {
  std::istringstream line(text(key));
  std::vector<std::string> tokens;
  for (std::string token; line >> token;) tokens.push_back(token);
  return tokens;
}

std::uint64_t CheckpointReader::parse_count(const std::string& token) const {
  if (token.empty() || token.find_first_not_of("0123456789") != std::string::npos) {
    fail("corrupt: '" + token + "' is not an unsigned integer");
  }
  errno = 0;
  const unsigned long long value = std::strtoull(token.c_str(), nullptr, 10);
  if (errno == ERANGE) fail("corrupt: '" + token + "' is out of range");
  return value;
}

double CheckpointReader::parse_number(const std::string& token) const {
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  if (token.empty() || end != token.c_str() + token.size()) fail("corrupt: '" + token + "' is not a number");
  return value;
}

std::uint64_t CheckpointReader::count(const std::string& key) {
  const auto tokens = fields(key);
  if (tokens.size() != 1) fail("corrupt: expected one value after '" + key + "'");
  return parse_count(tokens[0]);
}

std::uint64_t CheckpointReader::matching_count(const std::string& key, std::uint64_t expected) {
  const std::uint64_t value = count(key);
  if (value != expected) {
    fail(key + " " + std::to_string(value) + " does not match the optimiser's " + std::to_string(expected));
  }
  return value;
}

double CheckpointReader::number(const std::string& key) {
  const auto tokens = fields(key);
  if (tokens.size() != 1) fail("corrupt: expected one value after '" + key + "'");
  return parse_number(tokens[0]);
}

double CheckpointReader::member(std::size_t index, std::size_t dimension, std::vector<double>& member) {
  const auto tokens = fields("member");
  if (tokens.size() != dimension + 2) {
    fail("member line has " + std::to_string(tokens.size()) + " fields, expected index, cost and " +
         std::to_string(dimension) + " components");
  }
  if (parse_count(tokens[0]) != index) fail("expected member " + std::to_string(index));
  member.resize(dimension);
  for (std::size_t j = 0; j < dimension; ++j) member[j] = parse_number(tokens[j + 2]);
  return parse_number(tokens[1]);
}

std::vector<double> CheckpointReader::numbers(const std::string& key, std::size_t n) {
  const auto tokens = fields(key);
  if (tokens.size() != n) {
    fail("corrupt: expected " + std::to_string(n) + " values after '" + key + "', got " +
         std::to_string(tokens.size()));
  }
  std::vector<double> values;
  values.reserve(n);
  for (const auto& token : tokens) values.push_back(parse_number(token));
  return values;
}

std::string CheckpointReader::raw(std::size_t n) {
  ++line_number_;
  if (contents_.size() - offset_ < n + 1) fail("truncated inside a block of " + std::to_string(n) + " characters");
  if (contents_[offset_ + n] != '\n') fail("corrupt: block of " + std::to_string(n) + " characters not terminated");
  std::string block = contents_.substr(offset_, n);
  line_number_ += static_cast<std::size_t>(std::count(block.begin(), block.end(), '\n'));
  offset_ += n + 1;
  return block;
}

void CheckpointReader::expect_end() {
  const std::string line = next_line("end");
  if (line != "end") fail("corrupt: expected 'end', got '" + line.substr(0, 40) + "'");
  if (offset_ != contents_.size()) fail("corrupt: data after 'end'");
}

}  // namespace detail
}  // namespace pmlsm
