// The local BatchEvaluator: a CostFunction run on a pool of threads.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "pmlsm/optim/optimiser.hpp"

namespace pmlsm {

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

}  // namespace pmlsm
