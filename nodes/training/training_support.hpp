// What de_trainer and de_worker share: the TrainingSetup message that lets a
// worker on any machine score weight sets exactly as the trainer would, and
// the trainer's evaluator that farms a generation out to live workers.
//
// Protocol (topics in pmlsm/dds/topics.hpp):
//   trainer -> TrainingSetup (latched): config texts + run_id
//   worker  -> WorkerStatus every 200 ms: id, run_id it holds, slots
//   trainer -> EvaluationRequest addressed to one worker (at most 2 x slots in flight)
//   worker  -> EvaluationResult (job_id echoed)
// A worker silent for longer than the timeout is dead: its jobs go back to the
// queue with new job ids (a late answer to an old id is ignored). With no live
// worker the trainer evaluates in its own threads. Costs are pure functions of
// the weights, so who evaluates never changes the search.
// A worker is known by the DDS participant its status comes from, not only by the
// id it gives itself: a second process with the same id (another run on the
// domain) would otherwise keep a dead worker alive with its own heartbeats, turn
// its run id back and forth, and answer its requests. An id two live
// participants claim gets no jobs, and an answer counts only from the participant
// the job went to.
#pragma once

#include <fastdds/rtps/common/GuidPrefix_t.hpp>

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "EvaluationRequestPubSubTypes.h"
#include "EvaluationResultPubSubTypes.h"
#include "TrainingSetupPubSubTypes.h"
#include "WorkerStatusPubSubTypes.h"
#include "pmlsm/config/config.hpp"
#include "pmlsm/dds/participant.hpp"
#include "pmlsm/optim/optimiser.hpp"
#include "pmlsm/optim/thread_pool_evaluator.hpp"
#include "pmlsm/analysis/rnn_training.hpp"

namespace pmlsm::training {

/// Reads a whole file; @throws ConfigError naming it.
std::string read_text(const std::string& path);

/// The setup message for this run. @throws ConfigError if a text exceeds its bound.
pmlsm_msgs::msg::TrainingSetup make_setup(std::uint64_t run_id, const std::string& system_path,
                                          const std::vector<std::string>& system_overrides,
                                          const TrainingParams& training);

/// The cost a setup describes. @throws ConfigError (bad texts) naming the trainer's file.
std::shared_ptr<const RnnCost> cost_from_setup(const pmlsm_msgs::msg::TrainingSetup& setup);

struct DispatchCounters {
  std::uint64_t remote_evaluations = 0;
  std::uint64_t local_evaluations = 0;
  std::uint64_t requeued = 0;       ///< jobs sent again (worker lost or refused)
  std::uint64_t workers_lost = 0;   ///< workers of this run that went silent
  std::uint64_t stale_results = 0;  ///< answers to jobs already re-queued, of another run or by another process
};

class DdsEvaluator final : public BatchEvaluator {
 public:
  DdsEvaluator(dds::Participant& participant, dds::Wakeup& wakeup, CostFunction local_cost, unsigned local_threads,
               std::uint64_t run_id, std::chrono::milliseconds worker_timeout);
  void evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) override;
  /// Live workers holding this run's setup.
  std::size_t live_workers();
  /// Waits up to `timeout` for `count` live workers; returns how many there are.
  std::size_t wait_for_workers(std::size_t count, std::chrono::milliseconds timeout);
  const DispatchCounters& counters() const { return counters_; }

 private:
  /// The DDS participant a worker's status and results come from.
  using Origin = eprosima::fastrtps::rtps::GuidPrefix_t;
  struct Worker {
    std::string id;
    std::chrono::steady_clock::time_point last_seen;
    std::uint32_t slots = 1;
    std::uint64_t run_id = 0;
    std::size_t in_flight = 0;
    std::string setup_error;
    bool held_this_run = false;  ///< it took this run's setup once: missed when it goes silent
  };
  struct Job {
    std::size_t index;
    Origin worker;
  };
  void poll_workers();
  /// Holds this run's setup, and no other live participant claims its id.
  bool usable(const Worker& w) const;
  /// Evaluates candidates[i] for i in `indices` in the local threads, into costs[i].
  void evaluate_locally(const std::vector<std::vector<double>>& candidates, const std::deque<std::size_t>& indices,
                        std::vector<double>& costs);
  /// Jobs of workers that vanished (or are no longer usable) go back to the front of `pending`.
  void requeue_lost_jobs(std::deque<std::size_t>& pending);
  /// Sends jobs from `pending` until every usable worker has 2 x slots in flight.
  void send_requests(const std::vector<std::vector<double>>& candidates, std::deque<std::size_t>& pending,
                     pmlsm_msgs::msg::EvaluationRequest& request);
  /// Takes the workers' answers: a cost into costs[index] (`done` counts them), a refusal back to
  /// `pending`; answers of other runs, re-queued jobs or other processes are stale. True when one counted.
  bool take_results(pmlsm_msgs::msg::EvaluationResult& result, std::vector<double>& costs,
                    std::deque<std::size_t>& pending, std::size_t& done);

  dds::Wakeup& wakeup_;
  ThreadPoolEvaluator local_;
  std::uint64_t run_id_;
  std::chrono::milliseconds worker_timeout_;
  dds::Writer<pmlsm_msgs::msg::EvaluationRequestPubSubType> request_writer_;
  dds::Reader<pmlsm_msgs::msg::EvaluationResultPubSubType> result_reader_;
  dds::Reader<pmlsm_msgs::msg::WorkerStatusPubSubType> status_reader_;
  std::map<Origin, Worker> workers_;
  std::map<std::uint64_t, Job> in_flight_;
  std::uint64_t next_job_id_ = 1;
  DispatchCounters counters_;
};

}  // namespace pmlsm::training
