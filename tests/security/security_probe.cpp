// A participant for the security tests, open or with any identity:
//   --intrude: answers every MotorFeedback it sees with a ForceCommand for that tick and run (what
//              a controller does: on an open domain it takes the drive over) and reports what it
//              saw and whether any drive matched its commands;
//   --say TEXT: publishes NodeStatus with message TEXT every 10 ms;
//   --listen TEXT: counts NodeStatus samples whose message is TEXT.
// Prints one line "probe: feedback N, force matched M, sent S, heard H" and exits 0.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <optional>
#include <thread>

#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "NodeStatusPubSubTypes.h"
#include "node_support.hpp"

namespace pmlsm {
namespace {

namespace msg = pmlsm_msgs::msg;

int run(int argc, char** argv) {
  CLI::App app{"security test probe"};
  dds::ParticipantOptions options;
  options.node_name = "security_probe";
  node::add_dds_options(app, options);
  double seconds = 3.0;
  bool intrude = false;
  std::string say, listen;
  app.add_option("--seconds", seconds, "How long to run");
  app.add_flag("--intrude", intrude, "Answer MotorFeedback with ForceCommand");
  app.add_option("--say", say, "Publish NodeStatus with this message");
  app.add_option("--listen", listen, "Count NodeStatus samples with this message");
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;

  dds::Wakeup wakeup;
  dds::Participant participant(options);
  std::optional<dds::Reader<msg::MotorFeedbackPubSubType>> feedback;
  std::optional<dds::Writer<msg::ForceCommandPubSubType>> force;
  std::optional<dds::Writer<msg::NodeStatusPubSubType>> status_writer;
  std::optional<dds::Reader<msg::NodeStatusPubSubType>> status_reader;
  if (intrude) {
    feedback.emplace(participant.make_reader(dds::topics::kMotorFeedback, wakeup));
    force.emplace(participant.make_writer(dds::topics::kForceCommand));
  }
  if (!say.empty()) status_writer.emplace(participant.make_writer(dds::topics::kNodeStatus));
  if (!listen.empty()) {
    status_reader.emplace(participant.make_reader(dds::topics::kNodeStatus, wakeup));
  }

  std::uint64_t feedback_seen = 0, sent = 0, heard = 0;
  std::size_t force_matched = 0;
  msg::MotorFeedback fb;
  msg::NodeStatus status;
  status.node_name("security_probe");
  status.message(say);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                          std::chrono::duration<double>(seconds));
  auto next_say = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < end && !dds::stop_requested()) {
    const auto seen = wakeup.generation();
    if (feedback) {
      force_matched = std::max(force_matched, force->matched_readers());
      while (feedback->take(fb)) {
        ++feedback_seen;
        msg::ForceCommand cmd;
        cmd.stamp(fb.stamp());
        cmd.feedback_tick(fb.stamp().tick());
        cmd.force_n(0.0);
        if (force->write(cmd)) ++sent;
      }
    }
    if (status_reader) {
      msg::NodeStatus in;
      while (status_reader->take(in)) heard += in.message() == listen ? 1 : 0;
    }
    if (status_writer && std::chrono::steady_clock::now() >= next_say) {
      next_say += std::chrono::milliseconds(10);
      if (status_writer->write(status)) ++sent;
    }
    wakeup.wait_for(seen, std::chrono::milliseconds(5));
  }
  std::printf("probe: feedback %llu, force matched %zu, sent %llu, heard %llu\n",
              static_cast<unsigned long long>(feedback_seen), force_matched, static_cast<unsigned long long>(sent),
              static_cast<unsigned long long>(heard));
  return kExitOk;
}

}  // namespace
}  // namespace pmlsm

int main(int argc, char** argv) {
  return pmlsm::node::run_node("security_probe", [&] { return pmlsm::run(argc, argv); });
}
