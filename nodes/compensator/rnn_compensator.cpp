// rnn_compensator: the Jordan RNN of section 3.2 on DDS. Every tick k it takes
// EstimatedState k (a_L, V_load) and VelocityReference k (V_ref), runs the
// network (and, with --online-learning, the extended back-propagation
// (16)-(19)), and publishes CompensatorOutput k. Weights come from --weights
// (a file the trainer wrote) and/or the NetworkWeights topic; a new set is
// checked (layer sizes, input scale and G_n equal to the config's, every value
// finite and within +-100, a version above the one in use: WeightSetGate) and
// swapped in at a tick boundary, or refused with the reason while the current
// set stays in use. Every set taken or refused is logged with its version,
// source and cost.
#include <cstdio>

#include "NetworkWeightsPubSubTypes.h"
#include "compensator_command_lines.hpp"
#include "compensator_node.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/util/validate.hpp"
#include "pmlsm/config/weights_file.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace flags = pmlsm_msgs::msg::CompensatorOutput_Constants;

// NetworkWeights carries no input kind: a set on the topic is the trainer's, which trains for the
// system file it shares with this node (TrainingSetup), so it takes this node's.
RnnWeightsFile from_message(const msg::NetworkWeights& m, const SystemParams& params) {
  RnnWeightsFile w;
  w.on_reference_error = params.compensator.rnn.on_reference_error;
  for (auto size : m.layer_sizes()) w.layer_sizes.push_back(size);
  w.input_scale_s2_per_m = m.input_scale();
  w.gain_n = m.gain_n();
  w.cost = m.cost();
  w.source = m.source().to_string();
  w.weights = m.weights();
  return w;
}

using node::RnnOptions;

class RnnCompensatorComponent final : public node::CycleComponent {
 public:
  RnnCompensatorComponent(const node::ComponentContext& context, RnnOptions options)
      : opt_(std::move(options)),
        rt_("rnn_compensator", opt_.common, context),
        params_(rt_.cfg.params),
        rnn_(params_.rnn_compensator_params(opt_.online_learning)),
        gate_(params_),
        inputs_(rt_.participant, rt_.wakeup, rt_.cfg),
        weights_reader_(rt_.participant.make_reader(pdds::topics::kNetworkWeights, rt_.wakeup)),
        writer_(rt_.participant.make_writer(pdds::topics::kCompensatorOutput)),
        live_(rt_.cfg.params, live_keys(rt_.cfg.params, "rnn_compensator")),
        parameters_(rt_, "rnn_compensator", live_),
        ticks_(scenario_ticks(rt_.cfg.scenario, rt_.period_s)) {
    if (!opt_.weights_path.empty()) {
      const RnnWeightsFile file = load_rnn_weights(opt_.weights_path);
      const std::string why = gate_.offer(file, 0, opt_.weights_path.c_str());
      if (!why.empty()) throw ConfigError(opt_.weights_path + ": " + why);
      rnn_.set_weights(file.weights);
      have_weights_ = true;
      std::printf("rnn_compensator: weights from %s: %s\n", opt_.weights_path.c_str(), gate_.last_log().c_str());
      report_rest_output();
    }
  }

 private:
  void activate() override {
    rt_.status.publish(msg::NodeStatus_Constants::STATE_RUNNING, 0, rt_.period_s,
                       have_weights_ ? "running" : "running, no weights yet");
  }
  Update update() override;
  /// The set's force at rest (its biases' fixed point), which the network would hold a load with.
  void report_rest_output() const {
    std::printf("rnn_compensator: the network's output at rest u* = %.4f (%.1f N), %s\n", rnn_.rest_output(),
                rnn_.rest_force_n(),
                rnn_.params().remove_rest_output
                    ? "taken out once the reference rests (compensator.rnn.remove_rest_output)"
                    : "kept (compensator.rnn.remove_rest_output false)");
  }
  std::chrono::duration<double> input_timeout() const override {
    return std::chrono::duration<double>(opt_.common.peer_timeout_s);
  }
  int inputs_lost() override { return inputs_.end_of_wait("rnn_compensator", answered_, opt_.common.peer_timeout_s); }
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return rt_.wakeup; }

  RnnOptions opt_;
  node::NodeRuntime rt_;
  const SystemParams& params_;
  RnnCompensator rnn_;
  WeightSetGate gate_;
  bool have_weights_ = false;
  node::CompensatorInputs inputs_;
  pdds::Reader<msg::NetworkWeightsPubSubType> weights_reader_;
  pdds::Writer<msg::CompensatorOutputPubSubType> writer_;
  LiveParameters live_;
  node::ParameterService parameters_;
  std::uint64_t ticks_;
  std::uint64_t answered_ = 0;
  CompensatorView view_;
  msg::CompensatorOutput out_;
  msg::NetworkWeights incoming_;
};

RnnCompensatorComponent::Update RnnCompensatorComponent::update() {
  if (answered_ >= ticks_) return Update::finished(kExitOk);
  std::uint64_t tick = 0;
  switch (inputs_.try_next(tick, view_)) {
    case node::CompensatorInputs::Take::kNone: return Update::waiting();
    case node::CompensatorInputs::Take::kEnded:
      return Update::finished(inputs_.end_of_wait("rnn_compensator", answered_, opt_.common.peer_timeout_s));
    case node::CompensatorInputs::Take::kTick: break;
  }
  const bool online_learning = opt_.online_learning;
  // Its online rule's settings (checked by LiveParameters as the file is) and weight swaps
  // happen here, between ticks, never inside a step.
  if (parameters_.serve(tick)) rnn_.set_learning(live_.params().rnn_compensator_params(online_learning));
  while (!opt_.ignore_topic && weights_reader_.take(incoming_)) {
    const RnnWeightsFile candidate = from_message(incoming_, params_);
    if (!gate_.offer(candidate, incoming_.version(), "the NetworkWeights topic").empty()) {
      std::fprintf(stderr, "rnn_compensator: %s\n", gate_.last_log().c_str());
      continue;
    }
    std::printf("rnn_compensator: %s (tick %llu)\n", gate_.last_log().c_str(), static_cast<unsigned long long>(tick));
    rnn_.set_weights(candidate.weights);
    have_weights_ = true;
    report_rest_output();
  }
  CompensatorStep step;  // without weights: no force, the training error alone
  std::uint32_t mode_flags = 0;
  if (have_weights_) {
    step = rnn_.step(rnn_input(view_));
    mode_flags = flags::FLAG_ENABLED | (online_learning ? flags::FLAG_ONLINE_LEARNING : 0u);
  } else {
    step.training_error_mps = view_.v_ref_mps - view_.v_load_mps;
  }
  node::to_msg(step, mode_flags, tick, gate_.version(), out_);
  out_.stamp(node::make_stamp(tick, rt_.period_s, inputs_.run_id()));
  writer_.write(out_);
  answered_ = tick + 1;
  return Update::worked();
}

int RnnCompensatorComponent::finish(int exit_code) {
  const CompensatorCounters& c = rnn_.counters();
  rt_.status.status().rejected(inputs_.rejected() + c.rejected_inputs + gate_.refused());
  rt_.status.publish(msg::NodeStatus_Constants::STATE_STOPPING, answered_, rt_.period_s, "done");
  writer_.wait_for_acknowledgments(node::flush_timeout(exit_code));
  std::printf(
      "rnn_compensator: %llu ticks answered, online learning %s: %llu updates, k_c clamped %llu, dead-band %llu, "
      "reverted %llu; %llu input(s) rejected, %llu skipped; %llu weight set(s) taken, %llu refused\n",
      static_cast<unsigned long long>(answered_), opt_.online_learning ? "on" : "off",
      static_cast<unsigned long long>(c.updates), static_cast<unsigned long long>(c.kc_clamped),
      static_cast<unsigned long long>(c.kc_deadband), static_cast<unsigned long long>(c.reverted_updates),
      static_cast<unsigned long long>(inputs_.rejected() + c.rejected_inputs),
      static_cast<unsigned long long>(inputs_.skipped()),
      static_cast<unsigned long long>(gate_.taken() - (opt_.weights_path.empty() ? 0 : 1)),
      static_cast<unsigned long long>(gate_.refused()));
  return exit_code;
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(rnn_compensator, make_rnn_compensator, 1);

MadeComponent make_rnn_compensator(const ComponentContext& context, int argc, char** argv) {
  RnnOptions opt;
  if (const auto code = parse_rnn_compensator_command_line(argc, argv, opt)) return {nullptr, *code};
  return {std::make_unique<RnnCompensatorComponent>(context, std::move(opt))};
}

}  // namespace pmlsm::node
