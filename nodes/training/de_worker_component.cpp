// de_worker: scores weight sets for a de_trainer on any machine of the DDS
// domain. It takes the trainer's TrainingSetup (config texts), answers the
// EvaluationRequests addressed to it with EvaluationResults, and says it is
// alive with a WorkerStatus every 200 ms. Start as many as there are cores to
// spare; kill one at any time: the trainer sends its jobs to the others.
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <mutex>
#include <thread>

#include "cycle_component.hpp"
#include "training_command_lines.hpp"
#include "training_support.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;

using node::WorkerOptions;

class DeWorkerComponent final : public node::CycleComponent {
 public:
  explicit DeWorkerComponent(WorkerOptions options)
      : opt_(std::move(options)),
        participant_(node::named(opt_.dds, "de_worker")),
        setup_reader_(participant_.make_reader(pdds::topics::kTrainingSetup, wakeup_)),
        request_reader_(participant_.make_reader(pdds::topics::kEvaluationRequest, wakeup_)),
        result_writer_(participant_.make_writer(pdds::topics::kEvaluationResult)),
        status_writer_(participant_.make_writer(pdds::topics::kWorkerStatus)) {}
  ~DeWorkerComponent() override { stop_pool(); }

  void activate() override;
  Update update() override;
  /// A worker waits for trainers as long as it runs (--idle-exit-s ends it).
  std::chrono::duration<double> input_timeout() const override { return node::kNoInputTimeout; }
  int inputs_lost() override { return kExitPeerMissing; }
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return wakeup_; }

 private:
  using SteadyClock = std::chrono::steady_clock;

  /// A pool thread: scores the queued requests until stopping_.
  void serve_requests();
  /// One request scored with the setup `cost` of run `cost_run` (nullptr: none yet) into `result`.
  void score(const msg::EvaluationRequest& request, const RnnCost* cost, std::uint64_t cost_run,
             msg::EvaluationResult& result);
  /// Takes the trainer's setups: the cost of the newest one, or why it was refused.
  void take_setups();
  /// Queues the requests addressed to this worker; returns how many wait.
  std::size_t queue_requests();
  void publish_status(SteadyClock::time_point now, std::size_t queued);
  /// Stops and joins the pool threads (none left: nothing).
  void stop_pool();

  WorkerOptions opt_;
  pdds::Wakeup wakeup_;  // outlives the participant, whose listeners signal it
  pdds::Participant participant_;
  pdds::Reader<msg::TrainingSetupPubSubType> setup_reader_;
  pdds::Reader<msg::EvaluationRequestPubSubType> request_reader_;
  pdds::Writer<msg::EvaluationResultPubSubType> result_writer_;
  pdds::Writer<msg::WorkerStatusPubSubType> status_writer_;

  // Shared with the pool threads, guarded by mutex_.
  std::mutex mutex_;
  std::condition_variable work_ready_;
  std::deque<msg::EvaluationRequest> queue_;
  std::shared_ptr<const RnnCost> cost_;  // the pool threads copy the pointer
  std::uint64_t run_id_ = 0;
  std::string setup_error_;
  bool stopping_ = false;
  std::atomic<std::uint64_t> evaluated_{0};
  std::atomic<std::uint32_t> busy_{0};

  // The DDS loop's own.
  msg::TrainingSetup setup_;
  msg::EvaluationRequest request_;
  msg::WorkerStatus status_;
  SteadyClock::time_point next_heartbeat_;
  SteadyClock::time_point last_request_;
  bool have_setup_ = false;
  std::vector<std::thread> pool_;
};

void DeWorkerComponent::serve_requests() {
  msg::EvaluationResult result;
  result.worker_id(opt_.worker_id);
  for (;;) {
    msg::EvaluationRequest request;
    std::shared_ptr<const RnnCost> my_cost;
    std::uint64_t my_run = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      work_ready_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      request = std::move(queue_.front());
      queue_.pop_front();
      my_cost = cost_;
      my_run = run_id_;
      ++busy_;
    }
    score(request, my_cost.get(), my_run, result);
    result_writer_.write(result);
    --busy_;
  }
}

void DeWorkerComponent::score(const msg::EvaluationRequest& request, const RnnCost* cost, std::uint64_t cost_run,
                              msg::EvaluationResult& result) {
  result.run_id(request.run_id());
  result.job_id(request.job_id());
  const auto start = SteadyClock::now();
  if (cost == nullptr || cost_run != request.run_id()) {
    result.status(msg::EvaluationResult_Constants::STATUS_NO_SETUP);
    result.cost(0);
  } else if (request.candidate().size() != cost->dimension()) {
    result.status(msg::EvaluationResult_Constants::STATUS_BAD_CANDIDATE);
    result.cost(0);
  } else {
    result.status(msg::EvaluationResult_Constants::STATUS_OK);
    result.cost((*cost)(request.candidate()));
    ++evaluated_;
  }
  result.eval_time_s(std::chrono::duration<double>(SteadyClock::now() - start).count());
  result.stamp().source_time_ns(wall_time_ns());
}

void DeWorkerComponent::take_setups() {
  const std::string& worker_id = opt_.worker_id;
  while (setup_reader_.take(setup_)) {
    try {
      auto fresh = training::cost_from_setup(setup_);
      std::lock_guard<std::mutex> lock(mutex_);
      cost_ = std::move(fresh);
      run_id_ = setup_.run_id();
      setup_error_.clear();
      last_request_ = SteadyClock::now();
      have_setup_ = true;
      std::printf("de_worker %s: setup of run %llu taken (%zu weights, %zu scenario(s))\n", worker_id.c_str(),
                  static_cast<unsigned long long>(run_id_), cost_->dimension(), setup_.scenarios().size());
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      setup_error_ = std::string(e.what()).substr(0, 128);
      std::fprintf(stderr, "de_worker %s: setup of run %llu refused: %s\n", worker_id.c_str(),
                   static_cast<unsigned long long>(setup_.run_id()), e.what());
    }
    next_heartbeat_ = SteadyClock::now();
  }
}

std::size_t DeWorkerComponent::queue_requests() {
  while (request_reader_.take(request_)) {
    if (request_.worker_id().to_string() != opt_.worker_id) continue;
    last_request_ = SteadyClock::now();
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(request_);
    work_ready_.notify_one();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.size();
}

void DeWorkerComponent::publish_status(SteadyClock::time_point now, std::size_t queued) {
  std::lock_guard<std::mutex> lock(mutex_);
  status_.run_id(setup_error_.empty() ? run_id_ : 0);
  status_.setup_error(setup_error_);
  status_.queued(static_cast<std::uint32_t>(queued + busy_.load()));
  status_.evaluated(evaluated_.load());
  status_.stamp().source_time_ns(wall_time_ns());
  status_writer_.write(status_);
  next_heartbeat_ = now + std::chrono::milliseconds(200);
}

void DeWorkerComponent::stop_pool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  work_ready_.notify_all();
  for (auto& t : pool_) t.join();
  pool_.clear();
}

void DeWorkerComponent::activate() {
  for (unsigned t = 0; t < opt_.threads; ++t) pool_.emplace_back([this] { serve_requests(); });
  status_.worker_id(opt_.worker_id);
  status_.slots(opt_.threads);
  next_heartbeat_ = SteadyClock::now();
  last_request_ = SteadyClock::now();
  std::printf("de_worker %s: %u thread(s), waiting for a trainer\n", opt_.worker_id.c_str(), opt_.threads);
}

// Setups and requests taken and handed to the pool; the heartbeat when due. The pool threads score.
node::CycleComponent::Update DeWorkerComponent::update() {
  take_setups();
  const std::size_t queued = queue_requests();
  const auto now = SteadyClock::now();
  if (now >= next_heartbeat_) publish_status(now, queued);
  if (opt_.idle_exit_s > 0 && have_setup_ && now - last_request_ > std::chrono::duration<double>(opt_.idle_exit_s)) {
    return Update::finished(kExitOk);
  }
  return Update::waiting_until(monotonic_ns() +
                               std::chrono::duration_cast<std::chrono::nanoseconds>(next_heartbeat_ - now).count());
}

int DeWorkerComponent::finish(int exit_code) {
  stop_pool();
  result_writer_.wait_for_acknowledgments(std::chrono::seconds(2));
  std::printf("de_worker %s: %llu evaluations\n", opt_.worker_id.c_str(),
              static_cast<unsigned long long>(evaluated_.load()));
  return exit_code;
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(de_worker, make_de_worker, kRunsAlone);

MadeComponent make_de_worker(const ComponentContext& /*context*/, int argc, char** argv) {
  WorkerOptions opt;
  if (const auto code = parse_de_worker_command_line(argc, argv, opt)) return {nullptr, *code};
  if (opt.worker_id.empty() || opt.worker_id.size() > 64) {
    throw ConfigError("--id: 1 to 64 characters, got '" + opt.worker_id + "'");
  }
  return {std::make_unique<DeWorkerComponent>(std::move(opt))};
}

}  // namespace pmlsm::node
