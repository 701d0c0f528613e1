// cyclone_subscriber: a Cyclone DDS participant, with type support that Cyclone's own idlc made
// from our IDL, that subscribes to the Fast DDS nodes' topics and writes every sample it gets to
// a CSV file. It proves that what our nodes put on the wire is plain DDS-RTPS + XCDR1 that
// another vendor's implementation discovers, matches and decodes to the same values.
//
// With --answer-force-n it also stands in for the controller in the other direction: it answers
// every MotorFeedback tick k with a ForceCommand (feedback_tick k, force (-1)^k * F), so a Fast
// DDS plant_sim in lockstep runs on commands that Cyclone serialised. With --bad-answers it
// also sends, before the answer to every tick k with k % 7 == 3, two malformed commands: one
// for a future tick (k + 1000, 999 N) and one for tick k with a NaN force. A plant must reject
// and count both and apply only the genuine answer.
//
// Exit codes (as the nodes'): 0 every topic got --count samples (a --lossy topic: its last tick),
// 1 timeout or DDS error (the message says which topic got how many), 2 bad command line.
#include <dds/dds.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <string>
#include <vector>

#include "CompensatorOutput.h"
#include "CurrentFeedback.h"
#include "EstimatedState.h"
#include "ForceCommand.h"
#include "MotorFeedback.h"
#include "NodeStatus.h"
#include "PlantTruth.h"
#include "VelocityReference.h"
#include "VoltageCommand.h"

namespace {

constexpr int kOk = 0;
constexpr int kFailed = 1;
constexpr int kBadOptions = 2;

// One CSV row: "topic,tick,sim_time_ns,<the type's fields>". Doubles with 17 significant digits,
// so that strtod gives back the exact value the publisher wrote.
class CsvRow {
 public:
  CsvRow(std::FILE* out, const char* topic) : out_(out) { std::fputs(topic, out_); }
  ~CsvRow() { std::fputc('\n', out_); }
  CsvRow(const CsvRow&) = delete;
  CsvRow& operator=(const CsvRow&) = delete;

  CsvRow& num(double v) {
    std::fprintf(out_, ",%.17g", v);
    return *this;
  }
  CsvRow& num(std::uint64_t v) {
    std::fprintf(out_, ",%" PRIu64, v);
    return *this;
  }
  CsvRow& num(std::int64_t v) {
    std::fprintf(out_, ",%" PRId64, v);
    return *this;
  }
  CsvRow& num(std::uint32_t v) {
    std::fprintf(out_, ",%" PRIu32, v);
    return *this;
  }
  CsvRow& num(bool v) {
    std::fputs(v ? ",1" : ",0", out_);
    return *this;
  }
  // Text fields of ours carry no commas or newlines (node and host names, status messages),
  // but a stray one must not shift the columns.
  CsvRow& text(const char* s) {
    std::fputc(',', out_);
    for (; *s != '\0'; ++s) std::fputc(*s == ',' || *s == '\n' ? ' ' : *s, out_);
    return *this;
  }
  CsvRow& stamp(const pmlsm_msgs_msg_Stamp& s) { return num(s.tick).num(s.sim_time_ns); }

 private:
  std::FILE* out_;
};

// What the program knows about one of our topics: its names, Cyclone's type descriptor made by
// idlc, the CSV columns and the function that writes them.
struct TopicKind {
  const char* short_name;  // as given to --topic
  const char* dds_name;    // as in common/dds/include/pmlsm/dds/topics.hpp
  const dds_topic_descriptor_t* descriptor;
  const char* columns;  // after "topic,tick,sim_time_ns"
  // Writes the row and returns the sample's tick.
  std::uint64_t (*write_row)(std::FILE* out, const char* topic, const void* sample);
};

std::uint64_t motor_feedback_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_MotorFeedback*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .num(m.position_m)
      .num(m.velocity_mps)
      .num(m.i_d_a)
      .num(m.i_q_a)
      .num(m.thrust_force_n)
      .num(m.applied_force_n)
      .num(m.applied_command_tick)
      .num(m.status);
  return m.stamp.tick;
}

std::uint64_t force_command_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_ForceCommand*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .num(m.feedback_tick)
      .num(m.force_n)
      .num(m.pi_force_n)
      .num(m.compensation_force_n)
      .num(m.velocity_error_mps)
      .num(m.saturated);
  return m.stamp.tick;
}

std::uint64_t plant_truth_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_PlantTruth*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .num(m.motor_position_m)
      .num(m.motor_velocity_mps)
      .num(m.motor_acceleration_mps2)
      .num(m.load_position_m)
      .num(m.load_velocity_mps)
      .num(m.load_acceleration_mps2)
      .num(m.spring_force_n)
      .num(m.thrust_force_n)
      .num(m.ripple_force_n)
      .num(m.friction_force_n)
      .num(m.command_force_n)
      .num(m.i_d_a)
      .num(m.i_q_a)
      .num(m.u_d_v)
      .num(m.u_q_v);
  return m.stamp.tick;
}

std::uint64_t velocity_reference_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_VelocityReference*>(sample);
  CsvRow(out, topic).stamp(m.stamp).num(m.velocity_command_mps).num(m.v_ref_mps).num(m.a_ref_mps2);
  return m.stamp.tick;
}

std::uint64_t estimated_state_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_EstimatedState*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .num(m.feedback_tick)
      .num(m.v_motor_mps)
      .num(m.v_load_mps)
      .num(m.spring_force_n)
      .num(m.a_load_mps2)
      .num(m.input_force_n)
      .num(m.innovation_mps);
  return m.stamp.tick;
}

std::uint64_t compensator_output_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_CompensatorOutput*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .num(m.estimate_tick)
      .num(m.weights_version)
      .num(m.force_n)
      .num(m.u_n)
      .num(m.training_error_mps)
      .num(m.k_c_mps)
      .num(m.flags);
  return m.stamp.tick;
}

std::uint64_t current_feedback_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_CurrentFeedback*>(sample);
  CsvRow(out, topic).stamp(m.stamp).num(m.substep).num(m.i_d_a).num(m.i_q_a).num(m.velocity_mps).num(m.position_m);
  return m.stamp.tick;
}

std::uint64_t voltage_command_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_VoltageCommand*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .num(m.substep)
      .num(m.u_d_v)
      .num(m.u_q_v)
      .num(m.i_d_ref_a)
      .num(m.i_q_ref_a)
      .num(m.saturated);
  return m.stamp.tick;
}

std::uint64_t node_status_row(std::FILE* out, const char* topic, const void* sample) {
  const auto& m = *static_cast<const pmlsm_msgs_msg_NodeStatus*>(sample);
  CsvRow(out, topic)
      .stamp(m.stamp)
      .text(m.node_name)
      .num(m.pid)
      .num(static_cast<std::uint32_t>(m.state))
      .num(m.ticks)
      .num(m.late)
      .num(m.rejected)
      .text(m.message);
  return m.stamp.tick;
}

const TopicKind kTopicKinds[] = {
    {"motor_feedback", "rt/pmlsm/motor_feedback", &pmlsm_msgs_msg_MotorFeedback_desc,
     "position_m,velocity_mps,i_d_a,i_q_a,thrust_force_n,applied_force_n,applied_command_tick,status",
     motor_feedback_row},
    {"force_command", "rt/pmlsm/force_command", &pmlsm_msgs_msg_ForceCommand_desc,
     "feedback_tick,force_n,pi_force_n,compensation_force_n,velocity_error_mps,saturated", force_command_row},
    {"plant_truth", "rt/pmlsm/plant_truth", &pmlsm_msgs_msg_PlantTruth_desc,
     "motor_position_m,motor_velocity_mps,motor_acceleration_mps2,load_position_m,load_velocity_mps,"
     "load_acceleration_mps2,spring_force_n,thrust_force_n,ripple_force_n,friction_force_n,command_force_n,"
     "i_d_a,i_q_a,u_d_v,u_q_v",
     plant_truth_row},
    {"velocity_reference", "rt/pmlsm/velocity_reference", &pmlsm_msgs_msg_VelocityReference_desc,
     "velocity_command_mps,v_ref_mps,a_ref_mps2", velocity_reference_row},
    {"estimated_state", "rt/pmlsm/estimated_state", &pmlsm_msgs_msg_EstimatedState_desc,
     "feedback_tick,v_motor_mps,v_load_mps,spring_force_n,a_load_mps2,input_force_n,innovation_mps",
     estimated_state_row},
    {"compensator_output", "rt/pmlsm/compensator_output", &pmlsm_msgs_msg_CompensatorOutput_desc,
     "estimate_tick,weights_version,force_n,u_n,training_error_mps,k_c_mps,flags", compensator_output_row},
    {"current_feedback", "rt/pmlsm/current_feedback", &pmlsm_msgs_msg_CurrentFeedback_desc,
     "substep,i_d_a,i_q_a,velocity_mps,position_m", current_feedback_row},
    {"voltage_command", "rt/pmlsm/voltage_command", &pmlsm_msgs_msg_VoltageCommand_desc,
     "substep,u_d_v,u_q_v,i_d_ref_a,i_q_ref_a,saturated", voltage_command_row},
    {"node_status", "rt/pmlsm/node_status", &pmlsm_msgs_msg_NodeStatus_desc,
     "node_name,pid,state,ticks,late,rejected,message", node_status_row},
};

const TopicKind* find_topic_kind(const std::string& name) {
  for (const TopicKind& kind : kTopicKinds) {
    if (name == kind.short_name || name == kind.dds_name) return &kind;
  }
  return nullptr;
}

struct Options {
  dds_domainid_t domain = 0;
  std::vector<const TopicKind*> topics;
  std::vector<const TopicKind*> lossy;  // complete once their tick count - 1 has come
  std::uint64_t count = 0;
  double timeout_s = 30.0;
  double linger_s = 0.0;  // after the last sample needed, wait this long for the writers to go
  std::string out_path;
  std::string cyclone_config;  // empty: Cyclone's defaults, or CYCLONEDDS_URI if set
  bool answer = false;         // answer MotorFeedback with ForceCommand
  double answer_force_n = 0.0;
  bool bad_answers = false;       // malformed commands before some answers (see the top)
  bool ros2_default_qos = false;  // read as a ROS 2 subscriber with default QoS does
};

void print_usage(std::FILE* to) {
  std::fprintf(to,
               "usage: cyclone_subscriber --topic NAME [--topic NAME ...] --count K --out FILE.csv\n"
               "                          [--domain N] [--timeout-s T] [--linger-s T]\n"
               "                          [--cyclone-config XML] [--answer-force-n F [--bad-answers]]\n"
               "                          [--ros2-default-qos [--lossy NAME ...]]\n"
               "  --topic NAME         one of our topics, short (motor_feedback) or DDS name\n"
               "                       (rt/pmlsm/motor_feedback); repeatable\n"
               "  --count K            exit 0 once every topic got K samples\n"
               "  --timeout-s T        exit 1 if that has not happened after T s (default 30)\n"
               "  --linger-s T         then stay up to T s more until every matched writer has gone,\n"
               "                       answering its heartbeats (default 0): a Fast DDS 2.9 writer\n"
               "                       otherwise waits for the acknowledgment of its last samples until\n"
               "                       this participant's lease (Cyclone's default 10 s) expires\n"
               "  --out FILE.csv       one row per sample: topic,tick,sim_time_ns,fields...; a '#' line\n"
               "                       per topic names its columns\n"
               "  --domain N           DDS domain id, 0..232 (default 0)\n"
               "  --cyclone-config XML Cyclone DDS configuration (as in CYCLONEDDS_URI) for this domain\n"
               "  --answer-force-n F   act as the controller: answer MotorFeedback tick k with a\n"
               "                       ForceCommand of force (-1)^k * F (needs --topic motor_feedback)\n"
               "  --bad-answers        before the answer to every tick k with k %% 7 == 3, send a command\n"
               "                       for tick k + 1000 (999 N) and one for tick k with a NaN force\n"
               "  --ros2-default-qos   read with ROS 2's default subscriber QoS (reliable, volatile,\n"
               "                       keep last 10), as `ros2 topic echo` does\n"
               "  --lossy NAME         a --topic that is complete once its tick K-1 has come, however\n"
               "                       many came before it: a keep-last-10 reader keeps only the newest\n"
               "                       10 of a burst (a reliable repair delivers one); repeatable\n"
               "topics:");
  for (const TopicKind& kind : kTopicKinds) std::fprintf(to, " %s", kind.short_name);
  std::fputc('\n', to);
}

// Strict number parsing: the whole argument must be the number.
bool parse_double(const char* text, double& value) {
  char* end = nullptr;
  value = std::strtod(text, &end);
  return end != text && *end == '\0';
}

bool parse_u64(const char* text, std::uint64_t& value) {
  if (*text == '-' || *text == '\0') return false;
  char* end = nullptr;
  errno = 0;
  value = std::strtoull(text, &end, 10);
  return *end == '\0' && errno == 0;
}

bool is_option(const std::string& arg) {
  for (const char* known : {"--domain", "--topic", "--count", "--timeout-s", "--linger-s", "--out", "--cyclone-config",
                            "--answer-force-n", "--lossy"}) {
    if (arg == known) return true;
  }
  return false;
}

// Returns an error message, or an empty string when the command line is fine.
std::string parse_options(int argc, char** argv, Options& opt, bool& help) {
  bool have_count = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      help = true;
      return {};
    }
    if (arg == "--bad-answers") {  // a flag: no value
      opt.bad_answers = true;
      continue;
    }
    if (arg == "--ros2-default-qos") {
      opt.ros2_default_qos = true;
      continue;
    }
    if (!is_option(arg)) return (arg.rfind("-", 0) == 0 ? "unknown option '" : "unexpected argument '") + arg + "'";
    if (i + 1 >= argc) return arg + " needs a value";
    const char* value = argv[++i];
    if (arg == "--domain") {
      std::uint64_t domain = 0;
      if (!parse_u64(value, domain) || domain > 232)
        return "--domain: '" + std::string(value) + "' is not a domain id 0..232";
      opt.domain = static_cast<dds_domainid_t>(domain);
    } else if (arg == "--topic") {
      const TopicKind* kind = find_topic_kind(value);
      if (kind == nullptr) return "--topic: unknown topic '" + std::string(value) + "' (see --help for the list)";
      for (const TopicKind* t : opt.topics) {
        if (t == kind) return "--topic: '" + std::string(value) + "' given twice";
      }
      opt.topics.push_back(kind);
    } else if (arg == "--lossy") {
      const TopicKind* kind = find_topic_kind(value);
      if (kind == nullptr) return "--lossy: unknown topic '" + std::string(value) + "' (see --help for the list)";
      opt.lossy.push_back(kind);
    } else if (arg == "--count") {
      if (!parse_u64(value, opt.count) || opt.count == 0)
        return "--count: '" + std::string(value) + "' is not a positive integer";
      have_count = true;
    } else if (arg == "--timeout-s") {
      if (!parse_double(value, opt.timeout_s) || !(opt.timeout_s > 0.0) || opt.timeout_s > 86400.0) {
        return "--timeout-s: '" + std::string(value) + "' is not a number of seconds in (0, 86400]";
      }
    } else if (arg == "--linger-s") {
      if (!parse_double(value, opt.linger_s) || !(opt.linger_s >= 0.0) || opt.linger_s > 86400.0) {
        return "--linger-s: '" + std::string(value) + "' is not a number of seconds in [0, 86400]";
      }
    } else if (arg == "--out") {
      opt.out_path = value;
      if (opt.out_path.empty()) return "--out: empty file name";
    } else if (arg == "--cyclone-config") {
      opt.cyclone_config = value;
    } else if (arg == "--answer-force-n") {
      if (!parse_double(value, opt.answer_force_n) || !(std::abs(opt.answer_force_n) < 1e6)) {
        return "--answer-force-n: '" + std::string(value) + "' is not a force in N";
      }
      opt.answer = true;
    }
  }
  if (opt.topics.empty()) return "no --topic given";
  if (!have_count) return "no --count given";
  if (opt.out_path.empty()) return "no --out given";
  if (opt.answer) {
    const TopicKind* motor_feedback = find_topic_kind("motor_feedback");
    bool subscribed = false;
    for (const TopicKind* t : opt.topics) subscribed = subscribed || t == motor_feedback;
    if (!subscribed) return "--answer-force-n answers MotorFeedback: add --topic motor_feedback";
  }
  if (opt.bad_answers && !opt.answer) return "--bad-answers needs --answer-force-n";
  for (const TopicKind* lossy : opt.lossy) {
    bool subscribed = false;
    for (const TopicKind* t : opt.topics) subscribed = subscribed || t == lossy;
    if (!subscribed) return "--lossy " + std::string(lossy->short_name) + ": not a --topic";
  }
  if (!opt.lossy.empty() && !opt.ros2_default_qos) {
    return "--lossy needs --ros2-default-qos: the default readers keep every sample";
  }
  return {};
}

// QoS that matches our writers (configs/dds/profiles.xml, pmlsm_control and pmlsm_observe):
// reliable, and transient-local so that what was written before this reader was discovered is
// still delivered. KEEP_ALL: a Cyclone reader with KEEP_LAST drops the oldest unread samples
// when its history is full, and this program must see every tick however fast the loop runs.
// XCDR1 only: it is what Fast DDS 2.9 writes and reads (its SEDP announces no representation,
// which means XCDR1). Cyclone 0.10 offers XCDR1 for our @final types by default as well, but the
// choice is pinned here rather than left to a default: in XCDR2 a double is aligned to 4 bytes,
// not 8, so every message would decode differently.
//
// With ros2_default: the reader QoS of a ROS 2 subscriber that asks for nothing (rmw's default
// profile: reliable, volatile, keep last 10), which our writers must serve as they are.
dds_qos_t* make_qos(bool writer, bool ros2_default = false) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  if (ros2_default) {
    dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
    const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(qos, 1, &xcdr1);
    return qos;
  }
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  if (writer) {
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 4096);  // as pmlsm_control's writers
  } else {
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  }
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  return qos;
}

struct Subscription {
  const TopicKind* kind = nullptr;
  bool answered = false;  // its samples are MotorFeedback that --answer-force-n answers
  bool lossy = false;     // complete at its last tick (--lossy)
  bool last_tick_seen = false;
  dds_entity_t reader = 0;
  std::uint64_t received = 0;
  std::uint32_t matched_writers = 0;
};

std::string dds_error(const char* what, dds_return_t rc) { return std::string(what) + ": " + dds_strretcode(rc); }

class Program {
 public:
  explicit Program(const Options& opt) : opt_(opt) {}
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;
  ~Program() {
    // Deleting the participant deletes its readers, writer, topics and the waitset's
    // attachments; the domain created from --cyclone-config goes with it.
    if (participant_ > 0) dds_delete(participant_);
    if (domain_ > 0) dds_delete(domain_);
    if (out_ != nullptr) std::fclose(out_);
  }

  int run() {
    out_ = std::fopen(opt_.out_path.c_str(), "w");
    if (out_ == nullptr) {
      std::fprintf(stderr, "cyclone_subscriber: cannot open %s for writing: %s\n", opt_.out_path.c_str(),
                   std::strerror(errno));
      return kFailed;
    }
    for (const TopicKind* kind : opt_.topics) {
      std::fprintf(out_, "# %s: topic,tick,sim_time_ns,%s\n", kind->short_name, kind->columns);
    }
    if (const std::string error = create_entities(); !error.empty()) {
      std::fprintf(stderr, "cyclone_subscriber: %s\n", error.c_str());
      return kFailed;
    }
    std::printf("cyclone_subscriber: readers ready on domain %d:", static_cast<int>(opt_.domain));
    for (const Subscription& s : subscriptions_) std::printf(" %s", s.kind->dds_name);
    std::printf("%s\n", opt_.answer ? " (answering MotorFeedback with ForceCommand)" : "");
    std::fflush(stdout);

    const dds_time_t deadline = dds_time() + seconds(opt_.timeout_s);
    if (const std::string error = serve_until(deadline, [&] { return all_received(); }); !error.empty()) {
      std::fprintf(stderr, "cyclone_subscriber: %s\n", error.c_str());
      return kFailed;
    }
    std::fflush(out_);
    if (!all_received()) {
      std::fprintf(stderr, "cyclone_subscriber: timeout after %.1f s, samples received of %" PRIu64 " per topic:",
                   opt_.timeout_s, opt_.count);
      for (const Subscription& s : subscriptions_) {
        std::fprintf(stderr, " %s %" PRIu64 " (%u matched writers)", s.kind->short_name, s.received, s.matched_writers);
      }
      std::fputc('\n', stderr);
      return kFailed;
    }
    if (answer_writer_ > 0) {
      // The last answers must reach the plant before this participant goes away.
      const dds_return_t rc = dds_wait_for_acks(answer_writer_, DDS_SECS(5));
      if (rc < 0)
        std::fprintf(stderr, "cyclone_subscriber: %s\n", dds_error("last ForceCommands not acknowledged", rc).c_str());
    }
    if (opt_.linger_s > 0.0) {
      // Samples that still come are taken and written, but not waited for.
      const std::string error =
          serve_until(dds_time() + seconds(opt_.linger_s), [&] { return matched_writers() == 0; });
      if (!error.empty()) {
        std::fprintf(stderr, "cyclone_subscriber: %s\n", error.c_str());
        return kFailed;
      }
      if (matched_writers() > 0) {
        std::printf("cyclone_subscriber: %u writers still matched after --linger-s %.1f\n", matched_writers(),
                    opt_.linger_s);
      }
      std::fflush(out_);
    }
    std::printf("cyclone_subscriber: done:");
    for (const Subscription& s : subscriptions_) std::printf(" %s %" PRIu64, s.kind->short_name, s.received);
    std::printf("%s", opt_.answer ? (", answered " + std::to_string(answered_) + " ticks").c_str() : "");
    std::printf("%s\n",
                opt_.bad_answers ? (", " + std::to_string(bad_answers_) + " malformed commands sent").c_str() : "");
    return kOk;
  }

 private:
  std::string create_entities() {
    if (!opt_.cyclone_config.empty()) {
      domain_ = dds_create_domain(opt_.domain, opt_.cyclone_config.c_str());
      if (domain_ < 0) return dds_error("cannot create the domain from --cyclone-config", domain_);
    }
    participant_ = dds_create_participant(opt_.domain, nullptr, nullptr);
    if (participant_ < 0) return dds_error("cannot create the participant", participant_);
    waitset_ = dds_create_waitset(participant_);
    if (waitset_ < 0) return dds_error("cannot create the waitset", waitset_);
    dds_qos_t* reader_qos = make_qos(false, opt_.ros2_default_qos);
    for (const TopicKind* kind : opt_.topics) {
      const dds_entity_t topic =
          dds_create_topic(participant_, ros2_named(kind->descriptor), kind->dds_name, nullptr, nullptr);
      if (topic < 0) {
        dds_delete_qos(reader_qos);
        return dds_error((std::string("cannot create topic ") + kind->dds_name).c_str(), topic);
      }
      Subscription s;
      s.kind = kind;
      s.answered = opt_.answer && kind == find_topic_kind("motor_feedback");
      s.lossy = std::find(opt_.lossy.begin(), opt_.lossy.end(), kind) != opt_.lossy.end();
      s.reader = dds_create_reader(participant_, topic, reader_qos, nullptr);
      if (s.reader < 0) {
        dds_delete_qos(reader_qos);
        return dds_error((std::string("cannot create a reader of ") + kind->dds_name).c_str(), s.reader);
      }
      // The waitset wakes on new data, and on matches so that they can be logged as they come.
      dds_set_status_mask(s.reader, DDS_DATA_AVAILABLE_STATUS | DDS_SUBSCRIPTION_MATCHED_STATUS);
      const dds_return_t rc = dds_waitset_attach(waitset_, s.reader, s.reader);
      if (rc < 0) {
        dds_delete_qos(reader_qos);
        return dds_error("cannot attach a reader to the waitset", rc);
      }
      subscriptions_.push_back(s);
    }
    dds_delete_qos(reader_qos);
    if (opt_.answer) {
      const dds_entity_t topic = dds_create_topic(participant_, ros2_named(&pmlsm_msgs_msg_ForceCommand_desc),
                                                  "rt/pmlsm/force_command", nullptr, nullptr);
      if (topic < 0) return dds_error("cannot create topic rt/pmlsm/force_command", topic);
      dds_qos_t* writer_qos = make_qos(true);
      answer_writer_ = dds_create_writer(participant_, topic, writer_qos, nullptr);
      dds_delete_qos(writer_qos);
      if (answer_writer_ < 0) return dds_error("cannot create the ForceCommand writer", answer_writer_);
    }
    return {};
  }

  static dds_duration_t seconds(double s) { return static_cast<dds_duration_t>(s * 1e9); }

  // Waits on the waitset, taking whatever arrives and noting (un)matches, until `done` holds or
  // the deadline passes. Returns an error message, or an empty string.
  template <typename Done>
  std::string serve_until(dds_time_t deadline, Done&& done) {
    while (!done() && dds_time() < deadline) {
      const dds_return_t rc = dds_waitset_wait_until(waitset_, nullptr, 0, deadline);
      if (rc < 0) return dds_error("waitset", rc);
      // One batch per reader in turn until none holds anything. Draining one reader until it is
      // empty would starve the others while the lockstep plant, fed by the answers, keeps it
      // busy; a reader with ROS 2's keep-last-10 then loses the oldest of what waits.
      for (std::size_t taken = 1; taken > 0;) {
        taken = 0;
        for (Subscription& s : subscriptions_) {
          if (std::string error = take_batch(s, taken); !error.empty()) return error;
        }
      }
    }
    return {};
  }

  std::uint32_t matched_writers() const {
    std::uint32_t n = 0;
    for (const Subscription& s : subscriptions_) n += s.matched_writers;
    return n;
  }

  bool all_received() const {
    for (const Subscription& s : subscriptions_) {
      if (s.lossy ? !s.last_tick_seen : s.received < opt_.count) return false;
    }
    return true;
  }

  // Takes up to a batch of what the reader holds, writes it to the CSV (and answers
  // MotorFeedback), and adds the number taken to `taken`.
  std::string take_batch(Subscription& s, std::size_t& taken) {
    dds_subscription_matched_status_t matched{};
    if (dds_get_subscription_matched_status(s.reader, &matched) == DDS_RETCODE_OK &&
        matched.current_count != s.matched_writers) {
      s.matched_writers = matched.current_count;
      std::printf("cyclone_subscriber: %s: %u matched writers\n", s.kind->dds_name, s.matched_writers);
      std::fflush(stdout);
    }
    constexpr std::size_t kBatch = 64;
    void* samples[kBatch] = {};  // null: Cyclone lends its own buffers
    dds_sample_info_t infos[kBatch];
    const dds_return_t n = dds_take(s.reader, samples, infos, kBatch, kBatch);
    if (n < 0) return dds_error((std::string("take on ") + s.kind->dds_name).c_str(), n);
    if (n == 0) return {};
    taken += static_cast<std::size_t>(n);
    std::string error;
    for (dds_return_t i = 0; i < n && error.empty(); ++i) {
      if (!infos[i].valid_data) continue;  // a writer went away: no sample
      const std::uint64_t tick = s.kind->write_row(out_, s.kind->short_name, samples[i]);
      ++s.received;
      s.last_tick_seen = s.last_tick_seen || tick + 1 == opt_.count;
      if (s.answered) {
        error = answer(*static_cast<const pmlsm_msgs_msg_MotorFeedback*>(samples[i]));
      }
    }
    dds_return_loan(s.reader, samples, n);
    return error;
  }

  std::string answer(const pmlsm_msgs_msg_MotorFeedback& feedback) {
    const std::uint64_t k = feedback.stamp.tick;
    if (opt_.bad_answers && k % 7 == 3) {
      pmlsm_msgs_msg_ForceCommand bad{};
      bad.stamp = feedback.stamp;
      bad.stamp.source_time_ns = dds_time();
      bad.feedback_tick = k + 1000;  // a tick not yet published
      bad.force_n = 999.0;
      dds_return_t rc = dds_write(answer_writer_, &bad);
      if (rc < 0) return dds_error("write ForceCommand (future tick)", rc);
      bad.feedback_tick = k;
      bad.force_n = std::nan("");
      rc = dds_write(answer_writer_, &bad);
      if (rc < 0) return dds_error("write ForceCommand (NaN)", rc);
      bad_answers_ += 2;
    }
    pmlsm_msgs_msg_ForceCommand command{};
    command.stamp = feedback.stamp;
    command.stamp.source_time_ns = dds_time();
    command.feedback_tick = k;
    command.force_n = (k % 2 == 0 ? 1.0 : -1.0) * opt_.answer_force_n;
    command.pi_force_n = command.force_n;
    command.compensation_force_n = 0.0;
    command.velocity_error_mps = 0.0;
    command.saturated = false;
    const dds_return_t rc = dds_write(answer_writer_, &command);
    if (rc < 0) return dds_error("write ForceCommand", rc);
    ++answered_;
    return {};
  }

  const Options& opt_;
  std::FILE* out_ = nullptr;
  // idlc names a type as its IDL does ("pmlsm_msgs::msg::MotorFeedback"); on the wire our types
  // carry ROS 2's name for it ("pmlsm_msgs::msg::dds_::MotorFeedback_", ros2/design "Topic and
  // Service name mapping to DDS"), so this reader uses a copy of idlc's descriptor renamed so.
  // The copies and their names live as long as the program (deque: stable addresses).
  const dds_topic_descriptor_t* ros2_named(const dds_topic_descriptor_t* idlc) {
    const std::string idl_name = idlc->m_typename;
    const auto last = idl_name.rfind("::");
    ros2_names_.push_back(idl_name.substr(0, last) + "::dds_::" + idl_name.substr(last + 2) + "_");
    ros2_descriptors_.push_back(*idlc);
    ros2_descriptors_.back().m_typename = ros2_names_.back().c_str();
    return &ros2_descriptors_.back();
  }

  std::deque<std::string> ros2_names_;
  std::deque<dds_topic_descriptor_t> ros2_descriptors_;
  dds_entity_t domain_ = 0;
  dds_entity_t participant_ = 0;
  dds_entity_t waitset_ = 0;
  dds_entity_t answer_writer_ = 0;
  std::vector<Subscription> subscriptions_;
  std::uint64_t answered_ = 0;
  std::uint64_t bad_answers_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  bool help = false;
  if (const std::string error = parse_options(argc, argv, opt, help); !error.empty()) {
    std::fprintf(stderr, "cyclone_subscriber: %s (--help lists the options)\n", error.c_str());
    return kBadOptions;
  }
  if (help) {
    print_usage(stdout);
    return kOk;
  }
  Program program(opt);
  return program.run();
}
