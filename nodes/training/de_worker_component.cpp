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

#include "node_support.hpp"
#include "training_command_lines.hpp"
#include "training_support.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;

using node::WorkerOptions;

class DeWorkerComponent final : public node::Component {
 public:
  explicit DeWorkerComponent(WorkerOptions options)
      : opt_(std::move(options)),
        participant_(node::named(opt_.dds, "de_worker")),
        setup_reader_(participant_.make_reader(pdds::topics::kTrainingSetup, wakeup_)),
        request_reader_(participant_.make_reader(pdds::topics::kEvaluationRequest, wakeup_)),
        result_writer_(participant_.make_writer(pdds::topics::kEvaluationResult)),
        status_writer_(participant_.make_writer(pdds::topics::kWorkerStatus)) {}

  int run() override;

 private:
  WorkerOptions opt_;
  pdds::Wakeup wakeup_;  // outlives the participant, whose listeners signal it
  pdds::Participant participant_;
  pdds::Reader<msg::TrainingSetupPubSubType> setup_reader_;
  pdds::Reader<msg::EvaluationRequestPubSubType> request_reader_;
  pdds::Writer<msg::EvaluationResultPubSubType> result_writer_;
  pdds::Writer<msg::WorkerStatusPubSubType> status_writer_;
};

int DeWorkerComponent::run() {
  const std::string& worker_id = opt_.worker_id;
  std::mutex mutex;
  std::condition_variable work_ready;
  std::deque<msg::EvaluationRequest> queue;
  std::shared_ptr<const RnnCost> cost;  // guarded by mutex; workers copy the pointer
  std::uint64_t run_id = 0;
  std::string setup_error;
  std::atomic<std::uint64_t> evaluated{0};
  std::atomic<std::uint32_t> busy{0};
  bool stopping = false;

  std::vector<std::thread> pool;
  for (unsigned t = 0; t < opt_.threads; ++t) {
    pool.emplace_back([&] {
      msg::EvaluationResult result;
      result.worker_id(worker_id);
      for (;;) {
        msg::EvaluationRequest request;
        std::shared_ptr<const RnnCost> my_cost;
        std::uint64_t my_run = 0;
        {
          std::unique_lock<std::mutex> lock(mutex);
          work_ready.wait(lock, [&] { return stopping || !queue.empty(); });
          if (stopping) return;
          request = std::move(queue.front());
          queue.pop_front();
          my_cost = cost;
          my_run = run_id;
          ++busy;
        }
        result.run_id(request.run_id());
        result.job_id(request.job_id());
        const auto start = std::chrono::steady_clock::now();
        if (!my_cost || my_run != request.run_id()) {
          result.status(msg::EvaluationResult_Constants::STATUS_NO_SETUP);
          result.cost(0);
        } else if (request.candidate().size() != my_cost->dimension()) {
          result.status(msg::EvaluationResult_Constants::STATUS_BAD_CANDIDATE);
          result.cost(0);
        } else {
          result.status(msg::EvaluationResult_Constants::STATUS_OK);
          result.cost((*my_cost)(request.candidate()));
          ++evaluated;
        }
        result.eval_time_s(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        result.stamp().source_time_ns(wall_time_ns());
        result_writer_.write(result);
        --busy;
      }
    });
  }

  msg::TrainingSetup setup;
  msg::EvaluationRequest request;
  msg::WorkerStatus status;
  status.worker_id(worker_id);
  status.slots(opt_.threads);
  auto next_heartbeat = std::chrono::steady_clock::now();
  auto last_request = std::chrono::steady_clock::now();
  bool have_setup = false;
  std::printf("de_worker %s: %u thread(s), waiting for a trainer\n", worker_id.c_str(), opt_.threads);
  while (!pdds::stop_requested()) {
    const std::uint64_t seen = wakeup_.generation();
    while (setup_reader_.take(setup)) {
      try {
        auto fresh = training::cost_from_setup(setup);
        std::lock_guard<std::mutex> lock(mutex);
        cost = std::move(fresh);
        run_id = setup.run_id();
        setup_error.clear();
        last_request = std::chrono::steady_clock::now();
        have_setup = true;
        std::printf("de_worker %s: setup of run %llu taken (%zu weights, %zu scenario(s))\n", worker_id.c_str(),
                    static_cast<unsigned long long>(run_id), cost->dimension(), setup.scenarios().size());
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(mutex);
        setup_error = std::string(e.what()).substr(0, 128);
        std::fprintf(stderr, "de_worker %s: setup of run %llu refused: %s\n", worker_id.c_str(),
                     static_cast<unsigned long long>(setup.run_id()), e.what());
      }
      next_heartbeat = std::chrono::steady_clock::now();
    }
    std::size_t queued = 0;
    while (request_reader_.take(request)) {
      if (request.worker_id().to_string() != worker_id) continue;
      last_request = std::chrono::steady_clock::now();
      std::lock_guard<std::mutex> lock(mutex);
      queue.push_back(request);
      work_ready.notify_one();
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      queued = queue.size();
    }
    const auto now = std::chrono::steady_clock::now();
    if (now >= next_heartbeat) {
      std::lock_guard<std::mutex> lock(mutex);
      status.run_id(setup_error.empty() ? run_id : 0);
      status.setup_error(setup_error);
      status.queued(static_cast<std::uint32_t>(queued + busy.load()));
      status.evaluated(evaluated.load());
      status.stamp().source_time_ns(wall_time_ns());
      status_writer_.write(status);
      next_heartbeat = now + std::chrono::milliseconds(200);
    }
    if (opt_.idle_exit_s > 0 && have_setup && now - last_request > std::chrono::duration<double>(opt_.idle_exit_s))
      break;
    wakeup_.wait_for(seen, std::chrono::milliseconds(50));
  }
  {
    std::lock_guard<std::mutex> lock(mutex);
    stopping = true;
  }
  work_ready.notify_all();
  for (auto& t : pool) t.join();
  result_writer_.wait_for_acknowledgments(std::chrono::seconds(2));
  std::printf("de_worker %s: %llu evaluations\n", worker_id.c_str(), static_cast<unsigned long long>(evaluated.load()));
  return kExitOk;
}

}  // namespace

namespace pmlsm::node {

MadeComponent make_de_worker(const ComponentContext& /*context*/, int argc, char** argv) {
  WorkerOptions opt;
  if (const auto code = parse_de_worker_command_line(argc, argv, opt)) return {nullptr, *code};
  if (opt.worker_id.empty() || opt.worker_id.size() > 64) {
    throw ConfigError("--id: 1 to 64 characters, got '" + opt.worker_id + "'");
  }
  return {std::make_unique<DeWorkerComponent>(std::move(opt))};
}

}  // namespace pmlsm::node
