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
  w.on_reference_error = params.compensator.rnn_on_reference_error;
  for (auto size : m.layer_sizes()) w.layer_sizes.push_back(size);
  w.input_scale_s2_per_m = m.input_scale();
  w.gain_n = m.gain_n();
  w.cost = m.cost();
  w.source = m.source().to_string();
  w.weights = m.weights();
  return w;
}

int run(int argc, char** argv) {
  CLI::App app{"Jordan RNN vibration compensator on DDS"};
  node::CommonOptions common;
  node::add_common_options(app, common);
  std::string weights_path;
  bool online_learning = false;
  bool ignore_topic = false;
  app.add_option("-w,--weights", weights_path, "Weights file (from de_trainer)")->check(CLI::ExistingFile);
  app.add_flag("--online-learning", online_learning, "Refine the weights online, eqs. (16)-(19)");
  app.add_flag("--no-weights-topic", ignore_topic, "Do not take weight sets from the NetworkWeights topic");
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("rnn_compensator", common);
  const SystemParams& params = rt.cfg.params;
  RnnCompensator rnn(params.rnn_compensator_params(online_learning));
  WeightSetGate gate(params);
  bool have_weights = false;
  if (!weights_path.empty()) {
    const RnnWeightsFile file = load_rnn_weights(weights_path);
    const std::string why = gate.offer(file, 0, weights_path.c_str());
    if (!why.empty()) throw ConfigError(weights_path + ": " + why);
    rnn.set_weights(file.weights);
    have_weights = true;
    std::printf("rnn_compensator: weights from %s: %s\n", weights_path.c_str(), gate.last_log().c_str());
  }
  node::CompensatorInputs inputs(rt.participant, rt.wakeup);
  auto weights_reader = rt.participant.make_reader<msg::NetworkWeightsPubSubType>(pdds::topics::kNetworkWeights, rt.wakeup);
  auto writer = rt.participant.make_writer<msg::CompensatorOutputPubSubType>(pdds::topics::kCompensatorOutput);
  const std::uint64_t ticks = scenario_ticks(rt.cfg.scenario, rt.period_s);
  rt.status.publish(msg::NodeStatus_Constants::STATE_RUNNING, 0, rt.period_s, have_weights ? "running" : "running, no weights yet");

  msg::CompensatorOutput out;
  msg::NetworkWeights incoming;
  std::uint64_t tick = 0, answered = 0;
  CompensatorView view;
  int exit_code = kExitOk;
  while (answered < ticks && !pdds::stop_requested()) {
    if (!inputs.next(std::chrono::duration<double>(common.peer_timeout_s), tick, view)) {
      exit_code = node::end_of_failed_wait("rnn_compensator", "EstimatedState and VelocityReference", "estimator or controller",
                                           answered, common.peer_timeout_s);
      break;
    }
    // Weight swaps happen here, between ticks, never inside a step.
    while (!ignore_topic && weights_reader.take(incoming)) {
      const RnnWeightsFile candidate = from_message(incoming, params);
      if (!gate.offer(candidate, incoming.version(), "the NetworkWeights topic").empty()) {
        std::fprintf(stderr, "rnn_compensator: %s\n", gate.last_log().c_str());
        continue;
      }
      std::printf("rnn_compensator: %s (tick %llu)\n", gate.last_log().c_str(), static_cast<unsigned long long>(tick));
      rnn.set_weights(candidate.weights);
      have_weights = true;
    }
    std::uint32_t out_flags = 0;
    if (have_weights) {
      const CompensatorStep step = rnn.step(rnn_input(view));
      out.force_n(step.force_n);
      out.u_n(step.u_n);
      out.training_error_mps(step.training_error_mps);
      out.k_c_mps(step.k_c_mps);
      out_flags |= flags::FLAG_ENABLED;
      if (online_learning) out_flags |= flags::FLAG_ONLINE_LEARNING;
      if (step.weights_updated) out_flags |= flags::FLAG_WEIGHTS_UPDATED;
      if (step.kc_guarded) out_flags |= flags::FLAG_KC_CLAMPED;
      if (step.input_rejected) out_flags |= flags::FLAG_INPUT_STALE;
    } else {
      out.force_n(0.0);
      out.u_n(0.0);
      out.training_error_mps(view.v_ref_mps - view.v_load_mps);
      out.k_c_mps(0.0);
    }
    out.flags(out_flags);
    out.stamp(node::make_stamp(tick, rt.period_s, inputs.run_id()));
    out.estimate_tick(tick);
    out.weights_version(gate.version());
    writer.write(out);
    answered = tick + 1;
  }
  const CompensatorCounters& c = rnn.counters();
  rt.status.status().rejected(inputs.rejected() + c.rejected_inputs + gate.refused());
  rt.status.publish(msg::NodeStatus_Constants::STATE_STOPPING, answered, rt.period_s, "done");
  writer.wait_for_acknowledgments(node::kFlushTimeout);
  std::printf("rnn_compensator: %llu ticks answered, online learning %s: %llu updates, k_c clamped %llu, dead-band %llu, "
              "reverted %llu; %llu input(s) rejected, %llu skipped; %llu weight set(s) taken, %llu refused\n",
              static_cast<unsigned long long>(answered), online_learning ? "on" : "off",
              static_cast<unsigned long long>(c.updates), static_cast<unsigned long long>(c.kc_clamped),
              static_cast<unsigned long long>(c.kc_deadband), static_cast<unsigned long long>(c.reverted_updates),
              static_cast<unsigned long long>(inputs.rejected() + c.rejected_inputs),
              static_cast<unsigned long long>(inputs.skipped()),
              static_cast<unsigned long long>(gate.taken() - (weights_path.empty() ? 0 : 1)),
              static_cast<unsigned long long>(gate.refused()));
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("rnn_compensator", [&] { return run(argc, argv); });
}
