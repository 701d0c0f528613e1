#include "pmlsm/optim/thread_pool_evaluator.hpp"

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "pmlsm/optim/batch_evaluation.hpp"

namespace pmlsm {
namespace {

using detail::finite_or_worst;
using detail::kInfinity;

}  // namespace

struct ThreadPoolEvaluator::Pool {
  // Hand-over of one batch from the calling thread to the pool threads.
  std::mutex mutex;
  std::condition_variable work_ready;
  std::condition_variable work_done;
  std::uint64_t batch_id = 0;    // incremented for each batch handed over
  unsigned workers_running = 0;  // pool threads still working on the current batch
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

void ThreadPoolEvaluator::run_share(unsigned slot, const std::vector<std::vector<double>>& candidates, double* costs) {
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

void ThreadPoolEvaluator::evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) {
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

}  // namespace pmlsm
