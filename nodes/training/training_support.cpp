#include "training_support.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <limits>
#include <sstream>

#include "pmlsm/dds/shutdown.hpp"

namespace pmlsm::training {

namespace msg = pmlsm_msgs::msg;

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

namespace {
/// `text` into a bounded string of TrainingSetup: the bound is the field's type (the IDL's), and
/// fastddsgen's fixed_string truncates past it without a word, so a longer text is refused here.
template <std::size_t kBound>
void put_text(const std::string& what, const std::string& text, eprosima::fastrtps::fixed_string<kBound>& field) {
  if (text.size() > kBound) {
    throw ConfigError(what + ": " + std::to_string(text.size()) + " characters, TrainingSetup carries at most " +
                      std::to_string(kBound));
  }
  field = text;
}

using Assignments = std::vector<std::pair<std::string, double>>;
using AssignmentTexts = std::vector<eprosima::fastrtps::fixed_string<256>>;

/// "key.path=value" items, the value as %.17g (round-trips the double exactly); at most 16.
void put_assignments(const Assignments& assignments, const std::string& what, AssignmentTexts& out) {
  if (assignments.size() > 16) throw ConfigError(what + ": at most 16 values reach remote workers");
  for (const auto& [key, value] : assignments) {
    char number[32];
    std::snprintf(number, sizeof number, "%.17g", value);
    put_text(what + " " + key, key + "=" + number, out.emplace_back());
  }
}

/// The items put_assignments wrote. @throws ConfigError naming `what` and an item that is no number.
Assignments take_assignments(const AssignmentTexts& items, const std::string& what) {
  Assignments out;
  for (const auto& item : items) {
    const ConfigOverride o = ConfigOverride::parse(item.to_string());
    char* end = nullptr;
    const double value = std::strtod(o.value.c_str(), &end);
    if (end == o.value.c_str() || *end != '\0') throw ConfigError(what + ": '" + item.to_string() + "' is no number");
    out.emplace_back(o.key_path, value);
  }
  return out;
}

}  // namespace

msg::TrainingSetup make_setup(std::uint64_t run_id, const std::string& system_path,
                              const std::vector<std::string>& system_overrides, const TrainingParams& training) {
  msg::TrainingSetup setup;
  setup.run_id(run_id);
  put_text(system_path, read_text(system_path), setup.system_yaml());
  put_text(system_path + " (name)", system_path, setup.system_origin());
  if (system_overrides.size() > 64) throw ConfigError("--set: at most 64 overrides reach remote workers");
  for (const auto& o : system_overrides) {
    put_text("--set " + o, o, setup.system_overrides().emplace_back());
  }
  if (training.scenarios.size() > 8) throw ConfigError("scenarios: at most 8 reach remote workers");
  for (const TrainingScenario& s : training.scenarios) {
    msg::TrainingScenarioText text;
    put_text(s.file, read_text(s.file), text.yaml());
    put_text(s.file + " (name)", s.file, text.origin());
    text.weight(s.weight);
    setup.scenarios().push_back(text);
  }
  setup.cost_velocity(to_string(training.cost_velocity));
  if (training.plants.size() > 32) throw ConfigError("plants: at most 32 reach remote workers");
  for (const PlantVariant& plant : training.plants) {
    msg::TrainingPlantText text;
    put_text("plants " + plant.name + " (name)", plant.name, text.name());
    put_assignments(plant.values, "plants " + plant.name, text.moves());
    text.weight(plant.weight);
    put_assignments(plant.models, "plants " + plant.name + " models", text.models());
    setup.plants().push_back(text);
  }
  setup.plant_objective(to_string(training.plant_objective));
  msg::TrainingVerdict& verdict = setup.verdict();
  verdict.judge_runs(training.judge_runs);
  verdict.tail_s(training.verdict.tail_s);
  verdict.tail_windows(training.verdict.tail_windows);
  verdict.limit_cycle_amplitude_m(training.verdict.limit_cycle_amplitude_m);
  verdict.min_decay_rate_per_s(training.verdict.min_decay_rate_per_s);
  verdict.max_saturated_tail_share(training.verdict.max_saturated_tail_share);
  verdict.max_free_vibration_settling_s(training.verdict.max_free_vibration_settling_s);
  verdict.rest_command_band_mps(training.verdict.rest_command_band_mps);
  verdict.min_rest_s(training.verdict.min_rest_s);
  verdict.max_rest_stretch_peak_m(training.verdict.max_rest_stretch_peak_m);
  verdict.max_rest_compensation_rms_n(training.verdict.max_rest_compensation_rms_n);
  verdict.max_forced_ratio_to_pi(training.verdict.max_forced_ratio_to_pi);
  return setup;
}

std::shared_ptr<const RnnCost> cost_from_setup(const msg::TrainingSetup& setup) {
  std::vector<ConfigOverride> overrides;
  for (const auto& o : setup.system_overrides()) overrides.push_back(ConfigOverride::parse(o.to_string()));
  const std::string origin = "trainer:" + setup.system_origin().to_string();
  const SystemParams params = parse_system_params(setup.system_yaml().to_string(), origin, overrides);
  std::vector<TrainingScenario> scenarios;
  for (const auto& s : setup.scenarios()) {
    TrainingScenario ts;
    ts.file = s.origin().to_string();
    ts.weight = s.weight();
    ts.scenario =
        parse_scenario(s.yaml().to_string(), "trainer:" + s.origin().to_string(), params.timing.control_period_s);
    scenarios.push_back(ts);
  }
  std::vector<PlantVariant> plants;
  for (const auto& p : setup.plants()) {
    PlantVariant variant{p.name().to_string(), {}, p.weight()};
    variant.values = take_assignments(p.moves(), origin + ": plants " + variant.name);
    variant.models = take_assignments(p.models(), origin + ": plants " + variant.name + " models");
    plants.push_back(variant);
  }
  CostVelocity which = CostVelocity::truth;
  try {
    which = cost_velocity_from_string(setup.cost_velocity().to_string());
    const PlantObjective objective = plant_objective_from_string(setup.plant_objective().to_string());
    const msg::TrainingVerdict& v = setup.verdict();
    if (!v.judge_runs()) return std::make_shared<const RnnCost>(params, std::move(scenarios), which, plants, objective);
    VerdictParams verdict;
    verdict.tail_s = v.tail_s();
    verdict.tail_windows = v.tail_windows();
    verdict.limit_cycle_amplitude_m = v.limit_cycle_amplitude_m();
    verdict.min_decay_rate_per_s = v.min_decay_rate_per_s();
    verdict.max_saturated_tail_share = v.max_saturated_tail_share();
    verdict.max_free_vibration_settling_s = v.max_free_vibration_settling_s();
    verdict.rest_command_band_mps = v.rest_command_band_mps();
    verdict.min_rest_s = v.min_rest_s();
    verdict.max_rest_stretch_peak_m = v.max_rest_stretch_peak_m();
    verdict.max_rest_compensation_rms_n = v.max_rest_compensation_rms_n();
    verdict.max_forced_ratio_to_pi = v.max_forced_ratio_to_pi();
    return std::make_shared<const RnnCost>(params, std::move(scenarios), which, plants, objective, verdict);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(origin + ": " + e.what());
  }
}

DdsEvaluator::DdsEvaluator(dds::Participant& participant, dds::Wakeup& wakeup, CostFunction local_cost,
                           unsigned local_threads, std::uint64_t run_id, std::chrono::milliseconds worker_timeout)
    : wakeup_(wakeup),
      local_(std::move(local_cost), local_threads),
      run_id_(run_id),
      worker_timeout_(worker_timeout),
      request_writer_(participant.make_writer(dds::topics::kEvaluationRequest)),
      result_reader_(participant.make_reader(dds::topics::kEvaluationResult, wakeup)),
      status_reader_(participant.make_reader(dds::topics::kWorkerStatus, wakeup, dds::kObserverProfile)) {}

void DdsEvaluator::poll_workers() {
  msg::WorkerStatus status;
  eprosima::fastdds::dds::SampleInfo info;
  const auto now = std::chrono::steady_clock::now();
  while (status_reader_.take(status, info)) {
    const std::string id = status.worker_id().to_string();
    const std::string setup_error = status.setup_error().to_string();
    const Origin origin = info.sample_identity.writer_guid().guidPrefix;
    const auto [it, fresh] = workers_.try_emplace(origin);
    Worker& w = it->second;
    if (fresh) {
      w.id = id;
      for (const auto& [other_origin, other] : workers_) {
        if (other_origin != origin && other.id == id) {
          std::fprintf(stderr,
                       "de_trainer: two processes call themselves worker %s: neither gets jobs while both live "
                       "(give each its own --id)\n",
                       id.c_str());
          break;
        }
      }
    }
    w.last_seen = now;
    w.slots = std::max<std::uint32_t>(1, status.slots());
    w.run_id = status.run_id();
    w.held_this_run = w.held_this_run || w.run_id == run_id_;
    if (setup_error != w.setup_error && !setup_error.empty()) {
      std::fprintf(stderr, "de_trainer: worker %s refused the setup: %s\n", id.c_str(), setup_error.c_str());
    }
    w.setup_error = setup_error;
  }
  for (auto it = workers_.begin(); it != workers_.end();) {
    if (now - it->second.last_seen > worker_timeout_) {
      if (it->second.in_flight > 0) {
        std::fprintf(stderr, "de_trainer: worker %s silent for %lld ms: its %zu jobs go to others\n",
                     it->second.id.c_str(), static_cast<long long>(worker_timeout_.count()), it->second.in_flight);
      }
      if (it->second.held_this_run) ++counters_.workers_lost;
      it = workers_.erase(it);
    } else {
      ++it;
    }
  }
}

bool DdsEvaluator::usable(const Worker& w) const {
  if (w.run_id != run_id_ || !w.setup_error.empty()) return false;
  const auto same_id =
      std::count_if(workers_.begin(), workers_.end(), [&](const auto& kv) { return kv.second.id == w.id; });
  return same_id == 1;
}

std::size_t DdsEvaluator::live_workers() {
  poll_workers();
  return static_cast<std::size_t>(
      std::count_if(workers_.begin(), workers_.end(), [&](const auto& kv) { return usable(kv.second); }));
}

std::size_t DdsEvaluator::wait_for_workers(std::size_t count, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::size_t live = live_workers();
  while (live < count && std::chrono::steady_clock::now() < deadline && !dds::stop_requested()) {
    const auto seen = wakeup_.generation();
    wakeup_.wait_for(seen, std::chrono::milliseconds(50));
    live = live_workers();
  }
  return live;
}

void DdsEvaluator::evaluate_locally(const std::vector<std::vector<double>>& candidates,
                                    const std::deque<std::size_t>& indices, std::vector<double>& costs) {
  std::vector<std::vector<double>> batch;
  for (std::size_t i : indices) batch.push_back(candidates[i]);
  std::vector<double> batch_costs;
  local_.evaluate(batch, batch_costs);
  std::size_t k = 0;
  for (std::size_t i : indices) costs[i] = batch_costs[k++];
  counters_.local_evaluations += batch.size();
}

void DdsEvaluator::requeue_lost_jobs(std::deque<std::size_t>& pending) {
  for (auto it = in_flight_.begin(); it != in_flight_.end();) {
    const auto w = workers_.find(it->second.worker);
    if (w == workers_.end() || !usable(w->second)) {
      pending.push_front(it->second.index);
      ++counters_.requeued;
      if (w != workers_.end() && w->second.in_flight > 0) --w->second.in_flight;
      it = in_flight_.erase(it);
    } else {
      ++it;
    }
  }
}

void DdsEvaluator::send_requests(const std::vector<std::vector<double>>& candidates, std::deque<std::size_t>& pending,
                                 msg::EvaluationRequest& request) {
  // Keep every live worker busy with up to 2 x slots jobs in flight.
  for (auto& [origin, w] : workers_) {
    if (!usable(w)) continue;
    while (!pending.empty() && w.in_flight < 2 * static_cast<std::size_t>(w.slots)) {
      const std::size_t index = pending.front();
      pending.pop_front();
      const std::uint64_t job = next_job_id_++;
      request.job_id(job);
      request.worker_id(w.id);
      request.candidate(candidates[index]);
      request_writer_.write(request);
      in_flight_[job] = Job{index, origin};
      ++w.in_flight;
    }
  }
}

bool DdsEvaluator::take_results(msg::EvaluationResult& result, std::vector<double>& costs,
                                std::deque<std::size_t>& pending, std::size_t& done) {
  bool progressed = false;
  eprosima::fastdds::dds::SampleInfo info;
  while (result_reader_.take(result, info)) {
    const auto it = in_flight_.find(result.job_id());
    if (result.run_id() != run_id_ || it == in_flight_.end() ||
        info.sample_identity.writer_guid().guidPrefix != it->second.worker) {
      ++counters_.stale_results;
      continue;
    }
    auto w = workers_.find(it->second.worker);
    if (w != workers_.end() && w->second.in_flight > 0) --w->second.in_flight;
    if (result.status() == msg::EvaluationResult_Constants::STATUS_OK) {
      costs[it->second.index] = result.cost();
      ++done;
      ++counters_.remote_evaluations;
    } else {
      pending.push_front(it->second.index);
      ++counters_.requeued;
    }
    in_flight_.erase(it);
    progressed = true;
  }
  return progressed;
}

void DdsEvaluator::evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) {
  costs.assign(candidates.size(), std::numeric_limits<double>::infinity());
  if (live_workers() == 0) {
    local_.evaluate(candidates, costs);
    counters_.local_evaluations += candidates.size();
    return;
  }
  std::deque<std::size_t> pending;
  for (std::size_t i = 0; i < candidates.size(); ++i) pending.push_back(i);
  std::size_t done = 0;
  msg::EvaluationRequest request;
  msg::EvaluationResult result;
  request.run_id(run_id_);
  in_flight_.clear();

  while (done < candidates.size()) {
    poll_workers();
    requeue_lost_jobs(pending);
    if (live_workers() == 0) {
      // Nobody left: the rest is evaluated here, in one batch.
      evaluate_locally(candidates, pending, costs);
      break;
    }
    send_requests(candidates, pending, request);
    const std::uint64_t seen = wakeup_.generation();
    const bool progressed = take_results(result, costs, pending, done);
    if (!progressed && done < candidates.size()) wakeup_.wait_for(seen, std::chrono::milliseconds(20));
    if (dds::stop_requested()) {
      // Finish the generation locally so the population stays consistent for the checkpoint.
      for (const auto& [job, j] : in_flight_) pending.push_back(j.index);
      in_flight_.clear();
      evaluate_locally(candidates, pending, costs);
      break;
    }
  }
}

}  // namespace pmlsm::training
