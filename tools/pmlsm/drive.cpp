// `pmlsm drive status|enable|disable|quick-stop|fault-reset|shutdown|switch-on`: the operator's
// verbs for a drive's CiA 402 power state machine (common/drive/power_state.hpp).
//
// The contract (nodes/plant_sim: serve_drive_control(), publish_drive_state()): requests go out
// on rt/pmlsm/drive_control (DriveControl, reliable volatile) addressed by drive name, each with
// a request_id of ours; the drive answers on rt/pmlsm/drive_state (DriveState, latched) with the
// request_id, whether it carried the request out and why (request_accepted, request_message),
// and publishes its state on every change and every second.
//
// A request is sent only once the drive's state has arrived (latched: at once if the drive runs)
// and our DriveControl writer has matched the drive's reader, so it is not sent into the void.
// `enable` walks the drive like a CiA 402 master (next_command_towards_operation_enabled, one
// request at a time, each answered before the next) but never resets a fault by itself: that is
// the operator's decision (`pmlsm drive fault-reset`).
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/rtps/common/InstanceHandle.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <set>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>

#include "DriveControlPubSubTypes.h"
#include "DriveStatePubSubTypes.h"
#include "commands.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/drive/power_state.hpp"

namespace pmlsm::tools {
namespace {

using Clock = std::chrono::steady_clock;
namespace msg = pmlsm_msgs::msg;
namespace rtps = eprosima::fastrtps::rtps;

// The wire codes are the library's enums in the same order.
static_assert(msg::DriveControl_Constants::COMMAND_SHUTDOWN == static_cast<int>(drive::DriveCommand::kShutdown) &&
                  msg::DriveControl_Constants::COMMAND_SWITCH_ON == static_cast<int>(drive::DriveCommand::kSwitchOn) &&
                  msg::DriveControl_Constants::COMMAND_ENABLE_OPERATION ==
                      static_cast<int>(drive::DriveCommand::kEnableOperation) &&
                  msg::DriveControl_Constants::COMMAND_DISABLE_OPERATION ==
                      static_cast<int>(drive::DriveCommand::kDisableOperation) &&
                  msg::DriveControl_Constants::COMMAND_DISABLE_VOLTAGE ==
                      static_cast<int>(drive::DriveCommand::kDisableVoltage) &&
                  msg::DriveControl_Constants::COMMAND_QUICK_STOP ==
                      static_cast<int>(drive::DriveCommand::kQuickStop) &&
                  msg::DriveControl_Constants::COMMAND_FAULT_RESET ==
                      static_cast<int>(drive::DriveCommand::kFaultReset),
              "DriveControl_Constants::COMMAND_* must follow pmlsm::drive::DriveCommand");
static_assert(msg::DriveState_Constants::POWER_OPERATION_ENABLED ==
                      static_cast<int>(drive::PowerState::kOperationEnabled) &&
                  msg::DriveState_Constants::POWER_FAULT == static_cast<int>(drive::PowerState::kFault) &&
                  msg::DriveState_Constants::POWER_SWITCH_ON_DISABLED ==
                      static_cast<int>(drive::PowerState::kSwitchOnDisabled),
              "DriveState_Constants::POWER_* must follow pmlsm::drive::PowerState");

/// After the first drive answered, how long to wait for the others (several drives, no name).
constexpr auto kMoreDrivesGrace = std::chrono::milliseconds(300);
/// At most this many requests in one `enable` walk (it needs 3 from switch on disabled, 4 from
/// quick stop active): a drive that keeps moving away is reported, not chased forever.
constexpr int kMaxEnableSteps = 12;

struct DriveOptions {
  std::string drive;       // "" or "*": every drive that answers
  double timeout_s = 3.0;  // per wait: for the drive, then for each answer
  std::string requester;   // default user@host
};

bool every_drive(const std::string& name) { return name.empty() || name == "*"; }

std::string hex(std::uint64_t value, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "0x%0*llx", digits, static_cast<unsigned long long>(value));
  return text;
}

std::string seconds_text(double s) {
  std::ostringstream out;
  out << s;
  return out.str();
}

drive::PowerState power_state_of(const msg::DriveState& s) { return static_cast<drive::PowerState>(s.power_state()); }

const char* power_state_name(const msg::DriveState& s) { return drive::to_string(power_state_of(s)); }

std::string error_code_text(std::uint16_t code) { return code == 0 ? "none" : hex(code, 4); }

/// The statusword shows a fault (fault, fault reaction active), not just a past one.
bool faulted(const msg::DriveState& s) { return (s.statusword() & drive::kStatusFault) != 0; }

/// The readable block of `pmlsm drive status`.
void print_state_block(const msg::DriveState& s) {
  const std::string reason = s.fault_reason().to_string();
  std::printf("drive:            %s\n", s.drive_name().c_str());
  std::printf("power state:      %s\n", power_state_name(s));
  std::printf("statusword:       %s\n", hex(s.statusword(), 4).c_str());
  // Like 0x603F, the code of the last fault stays after a fault reset.
  std::printf("error code:       %s%s\n", error_code_text(s.error_code()).c_str(),
              s.error_code() != 0 && !faulted(s) ? " (last fault, reset)" : "");
  std::printf("fault reason:     %s\n", reason.empty() ? "-" : reason.c_str());
  std::printf("refused requests: %llu\n", static_cast<unsigned long long>(s.refused_requests()));
  std::printf("faults:           %llu\n", static_cast<unsigned long long>(s.faults()));
  std::printf("safe ticks:       %llu\n", static_cast<unsigned long long>(s.safe_ticks()));
  std::printf("watchdog armed:   %s\n", s.watchdog_armed() ? "yes" : "no");
  std::printf("run id:           %s\n", hex(s.stamp().run_id(), 16).c_str());
  std::printf("tick:             %llu\n", static_cast<unsigned long long>(s.stamp().tick()));
  if (s.request_id() != 0) {
    std::printf("last request:     %s (%s): %s\n", hex(s.request_id(), 16).c_str(),
                s.request_accepted() ? "accepted" : "refused", s.request_message().c_str());
  }
}

/// One line: the drive, its state and statusword, after a request.
void print_state_line(const msg::DriveState& s) {
  std::printf("%s: %s (statusword %s", s.drive_name().c_str(), power_state_name(s), hex(s.statusword(), 4).c_str());
  if (faulted(s)) std::printf(", error code %s", error_code_text(s.error_code()).c_str());
  std::printf(")\n");
}

/// The participants whose readers our DriveControl writer has matched (Fast DDS 2.9 does not
/// list a writer's matched readers: DataWriter::get_matched_subscriptions is unsupported).
class MatchedReaders : public eprosima::fastdds::dds::DataWriterListener {
 public:
  void on_publication_matched(eprosima::fastdds::dds::DataWriter*,
                              const eprosima::fastdds::dds::PublicationMatchedStatus& info) override {
    std::lock_guard<std::mutex> lock(mutex_);
    const rtps::GUID_t reader = rtps::iHandle2GUID(info.last_subscription_handle);
    if (info.current_count_change > 0) {
      readers_.insert(reader);
    } else if (info.current_count_change < 0) {
      readers_.erase(reader);
    }
  }
  /// Readers known to this listener.
  std::size_t count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return readers_.size();
  }
  bool has_participant(const rtps::GuidPrefix_t& prefix) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::any_of(readers_.begin(), readers_.end(), [&](const rtps::GUID_t& g) { return g.guidPrefix == prefix; });
  }

 private:
  mutable std::mutex mutex_;
  std::set<rtps::GUID_t> readers_;
};

/// Our DDS side of the drives: a DriveControl writer, a DriveState reader, and the latest
/// state of every drive (by name) with the participant it came from.
class DriveLink {
 public:
  DriveLink(const dds::ParticipantOptions& options, const DriveOptions& o, const char* node_name)
      : options_(o),
        domain_(options.domain_id),
        participant_(with_node_name(options, node_name, "pmlsm_drive")),
        state_reader_(participant_.make_reader(dds::topics::kDriveState, wakeup_)),
        control_writer_(participant_.make_writer(dds::topics::kDriveControl)),
        requester_(o.requester.empty() ? user_at_host() : o.requester) {
    // Unique per process and per request, never 0: the pid in the top 16 bits, the wall clock
    // in microseconds below (48 bits: 8.9 years before it repeats).
    const auto wall_us =
        std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    next_request_id_ = (static_cast<std::uint64_t>(getpid() & 0xFFFF) << 48) |
                       (static_cast<std::uint64_t>(wall_us) & 0xFFFFFFFFFFFFULL);
    if (next_request_id_ == 0) next_request_id_ = 1;
    control_writer_.entity()->set_listener(&matched_readers_,
                                           eprosima::fastdds::dds::StatusMask::publication_matched());
  }

  int domain() const { return domain_; }
  double timeout_s() const { return options_.timeout_s; }

  /// "no drive answered on domain N within S s" (naming the drive when one was asked for).
  std::string nobody_answered() const {
    const std::string who = every_drive(options_.drive) ? "no drive" : "drive '" + options_.drive + "' has not";
    return who + " answered on domain " + std::to_string(domain_) + " within " + seconds_text(options_.timeout_s) +
           " s";
  }

  /// Why wait_for_drives() came back empty: nobody answered, or the drive did but our request
  /// could not reach it.
  std::string not_ready() const {
    if (addressed().empty()) return nobody_answered();
    return "drive '" + addressed().front() + "' answered on domain " + std::to_string(domain_) +
           " but its DriveControl reader did not match ours within " + seconds_text(options_.timeout_s) + " s";
  }

  /// Waits (up to the timeout) for the addressed drive's state, or, for every drive, for the
  /// first one's and briefly for the others'. With `for_requests`, also until our DriveControl
  /// writer has matched each such drive's reader. @return the drives' names, sorted; empty on
  /// timeout (or a stop request).
  std::vector<std::string> wait_for_drives(bool for_requests) {
    const auto deadline = Clock::now() + timeout();
    std::optional<Clock::time_point> first_seen;
    while (!dds::stop_requested()) {
      const auto seen = wakeup_.generation();
      take_states();
      std::vector<std::string> names = addressed();
      if (!names.empty() && !first_seen) first_seen = Clock::now();
      const bool all_seen = !every_drive(options_.drive) || names.size() >= state_reader_.matched_writers() ||
                            (first_seen && Clock::now() - *first_seen >= kMoreDrivesGrace);
      const bool reachable =
          !for_requests || std::all_of(names.begin(), names.end(), [&](const std::string& n) { return matched(n); });
      if (!names.empty() && all_seen && reachable) return names;
      const auto now = Clock::now();
      if (now >= deadline) {
        // Every drive was asked for and some answered, but not all could be reached: take those.
        if (every_drive(options_.drive) && for_requests) {
          names.erase(std::remove_if(names.begin(), names.end(), [&](const std::string& n) { return !matched(n); }),
                      names.end());
          return names;
        }
        return every_drive(options_.drive) ? names : std::vector<std::string>{};
      }
      wakeup_.wait_for(seen, std::min<Clock::duration>(deadline - now, std::chrono::milliseconds(50)));
    }
    return {};
  }

  const msg::DriveState& state(const std::string& name) const { return drives_.at(name).state; }

  /// Sends `command` to the drive `name`. @return the request id.
  std::uint64_t send(const std::string& name, drive::DriveCommand command) {
    msg::DriveControl request;
    request.stamp().source_time_ns(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
    request.drive_name(name.substr(0, 64));
    request.command(static_cast<std::uint8_t>(command));
    const std::uint64_t id = next_request_id_++;
    request.request_id(id);
    request.requester(requester_.substr(0, 64));
    if (!control_writer_.write(request)) {
      throw std::runtime_error("DriveControl: the write of request " + std::to_string(id) + " failed");
    }
    return id;
  }

  /// The drive's DriveState that echoes request `id`, or nullopt at the timeout.
  std::optional<msg::DriveState> wait_for_answer(const std::string& name, std::uint64_t id) {
    return wait_for_state(name, [id](const msg::DriveState& s) { return s.request_id() == id; });
  }

  /// The next DriveState of the drive `name` that satisfies `accept`, or nullopt at the timeout.
  template <typename Accept>
  std::optional<msg::DriveState> wait_for_state(const std::string& name, Accept&& accept) {
    const auto deadline = Clock::now() + timeout();
    while (!dds::stop_requested()) {
      const auto seen = wakeup_.generation();
      for (const msg::DriveState& s : take_states()) {
        if (s.drive_name().to_string() == name && accept(s)) return s;
      }
      const auto now = Clock::now();
      if (now >= deadline) return std::nullopt;
      wakeup_.wait_for(seen, std::min<Clock::duration>(deadline - now, std::chrono::milliseconds(50)));
    }
    return std::nullopt;
  }

 private:
  struct Known {
    msg::DriveState state;
    rtps::GuidPrefix_t participant;  // the drive node's, to find its DriveControl reader
  };

  Clock::duration timeout() const {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options_.timeout_s));
  }

  /// Takes every DriveState that arrived, remembers the latest per drive. @return them, in order.
  std::vector<msg::DriveState> take_states() {
    std::vector<msg::DriveState> arrived;
    msg::DriveState sample;
    eprosima::fastdds::dds::SampleInfo info;
    while (state_reader_.take(sample, info)) {
      const std::string name = sample.drive_name().to_string();
      drives_[name] = Known{sample, info.sample_identity.writer_guid().guidPrefix};
      arrived.push_back(sample);
    }
    return arrived;
  }

  /// The names of the drives heard from that the command line addresses.
  std::vector<std::string> addressed() const {
    std::vector<std::string> names;
    for (const auto& [name, known] : drives_) {
      if (every_drive(options_.drive) || name == options_.drive) names.push_back(name);
    }
    return names;
  }

  /// Our DriveControl writer has matched a reader of the drive's participant (not just any
  /// reader: a recorder reads the topic too, and a volatile request written before the drive's
  /// reader matched would never reach it).
  bool matched(const std::string& name) const {
    const std::size_t readers = control_writer_.matched_readers();
    if (readers == 0) return false;
    // A reader matched before the listener was set is not known to it: then any reader counts.
    if (matched_readers_.count() < readers) return true;
    return matched_readers_.has_participant(drives_.at(name).participant);
  }

  DriveOptions options_;
  int domain_;
  dds::Wakeup wakeup_;              // outlives the participant, whose listeners signal it
  MatchedReaders matched_readers_;  // likewise
  dds::Participant participant_;
  dds::Reader<msg::DriveStatePubSubType> state_reader_;
  dds::Writer<msg::DriveControlPubSubType> control_writer_;
  std::string requester_;
  std::uint64_t next_request_id_ = 1;
  std::map<std::string, Known> drives_;
};

int interrupted() {
  std::cerr << "pmlsm drive: interrupted\n";
  return kExitError;
}

int run_status(const dds::ParticipantOptions& dds_options, const DriveOptions& o) {
  DriveLink link(dds_options, o, "pmlsm_drive_status");
  const auto names = link.wait_for_drives(false);
  if (names.empty()) {
    if (dds::stop_requested()) return interrupted();
    std::cerr << "pmlsm drive status: " << link.nobody_answered() << "\n";
    return kExitError;
  }
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) std::printf("\n");
    print_state_block(link.state(names[i]));
  }
  std::fflush(stdout);
  return kExitOk;
}

/// One request to one drive, answered. @return the answer, or nullopt (reported) on timeout.
std::optional<msg::DriveState> request(DriveLink& link, const std::string& name, drive::DriveCommand command) {
  const std::uint64_t id = link.send(name, command);
  auto answer = link.wait_for_answer(name, id);
  if (!answer && !dds::stop_requested()) {
    std::cerr << "pmlsm drive: no answer from drive '" << name << "' to " << drive::to_string(command) << " (request "
              << hex(id, 16) << ") on domain " << link.domain() << " within " << seconds_text(link.timeout_s())
              << " s\n";
  }
  return answer;
}

/// `disable`, `quick-stop`, `fault-reset`, `shutdown`, `switch-on`: one request to each drive.
int run_command(const dds::ParticipantOptions& dds_options, const DriveOptions& o, drive::DriveCommand command) {
  DriveLink link(dds_options, o, "pmlsm_drive");
  const auto names = link.wait_for_drives(true);
  if (names.empty()) {
    if (dds::stop_requested()) return interrupted();
    std::cerr << "pmlsm drive: " << link.not_ready() << "\n";
    return kExitError;
  }
  int exit_code = kExitOk;
  for (const std::string& name : names) {
    const auto answer = request(link, name, command);
    if (!answer) {
      if (dds::stop_requested()) return interrupted();
      exit_code = kExitError;
      continue;
    }
    if (answer->request_accepted()) {
      std::printf("%s: %s\n", drive::to_string(command), answer->request_message().c_str());
    } else {
      std::printf("%s: refused by %s: %s\n", drive::to_string(command), name.c_str(),
                  answer->request_message().c_str());
      exit_code = kExitError;
    }
    print_state_line(*answer);
    std::fflush(stdout);
  }
  return exit_code;
}

/// Walks one drive to operation enabled. @return the exit code.
int enable_one(DriveLink& link, const std::string& name) {
  msg::DriveState state = link.state(name);
  for (int step = 0; step <= kMaxEnableSteps; ++step) {
    const drive::PowerState now = power_state_of(state);
    if (now == drive::PowerState::kOperationEnabled) {
      print_state_line(state);
      return kExitOk;
    }
    if (now == drive::PowerState::kFault) {
      const std::string reason = state.fault_reason().to_string();
      std::printf(
          "enable: drive %s is in fault (error code %s%s%s); `pmlsm drive fault-reset` clears it, then "
          "`pmlsm drive enable`\n",
          name.c_str(), error_code_text(state.error_code()).c_str(), reason.empty() ? "" : ": ", reason.c_str());
      print_state_line(state);
      return kExitError;
    }
    const auto next = drive::next_command_towards_operation_enabled(now);
    if (!next) {
      // Not ready to switch on, fault reaction active: the drive moves on by itself.
      std::printf("enable: %s is in %s; waiting\n", name.c_str(), drive::to_string(now));
      std::fflush(stdout);
      const auto moved =
          link.wait_for_state(name, [now](const msg::DriveState& s) { return power_state_of(s) != now; });
      if (!moved) {
        if (dds::stop_requested()) return interrupted();
        std::cerr << "pmlsm drive enable: drive '" << name << "' stayed in " << drive::to_string(now) << " on domain "
                  << link.domain() << " for " << seconds_text(link.timeout_s()) << " s\n";
        return kExitError;
      }
      state = *moved;
      continue;
    }
    const auto answer = request(link, name, *next);
    if (!answer) return dds::stop_requested() ? interrupted() : kExitError;
    if (!answer->request_accepted()) {
      std::printf("%s: refused by %s: %s\n", drive::to_string(*next), name.c_str(), answer->request_message().c_str());
      print_state_line(*answer);
      return kExitError;
    }
    std::printf("%s: %s\n", drive::to_string(*next), answer->request_message().c_str());
    std::fflush(stdout);
    state = *answer;
    if (power_state_of(state) == now) {
      // A drive on a fieldbus takes the controlword over its next cycles: wait for it to move
      // before the next request, instead of sending this one again.
      const auto moved =
          link.wait_for_state(name, [now](const msg::DriveState& s) { return power_state_of(s) != now; });
      if (!moved) {
        if (dds::stop_requested()) return interrupted();
        std::cerr << "pmlsm drive enable: drive '" << name << "' stayed in " << drive::to_string(now) << " after "
                  << drive::to_string(*next) << " on domain " << link.domain() << " for "
                  << seconds_text(link.timeout_s()) << " s\n";
        return kExitError;
      }
      state = *moved;
    }
  }
  std::printf("enable: %s is not in operation enabled after %d requests\n", name.c_str(), kMaxEnableSteps);
  print_state_line(state);
  return kExitError;
}

int run_enable(const dds::ParticipantOptions& dds_options, const DriveOptions& o) {
  DriveLink link(dds_options, o, "pmlsm_drive");
  const auto names = link.wait_for_drives(true);
  if (names.empty()) {
    if (dds::stop_requested()) return interrupted();
    std::cerr << "pmlsm drive enable: " << link.not_ready() << "\n";
    return kExitError;
  }
  int exit_code = kExitOk;
  for (const std::string& name : names) {
    const int code = enable_one(link, name);
    std::fflush(stdout);
    if (dds::stop_requested()) return code;
    if (code != kExitOk) exit_code = code;
  }
  return exit_code;
}

}  // namespace

void add_drive_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto* drive_app = app.add_subcommand("drive",
                                       "The drive's CiA 402 power state: status, enable, disable, quick-stop, "
                                       "fault-reset, shutdown, switch-on");
  drive_app->require_subcommand(1);
  auto o = std::make_shared<DriveOptions>();

  const auto common = [o](CLI::App* sub) {
    sub->add_option("--drive", o->drive, "Drive node to address (default: every drive that answers)");
    sub->add_option("--timeout-s", o->timeout_s, "How long to wait for the drive, and for each answer")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 3600.0));
    sub->add_option("--requester", o->requester, "Who asks, for the drive's log (default: user@host)");
  };

  auto* status = drive_app->add_subcommand("status", "Prints the drive's power state, statusword, error and counters");
  common(status);
  status->callback([&dds_options, o, &exit_code] { exit_code = run_status(dds_options, *o); });

  auto* enable = drive_app->add_subcommand(
      "enable", "Walks the drive to operation enabled (shutdown, switch on, enable operation); never resets a fault");
  common(enable);
  enable->callback([&dds_options, o, &exit_code] { exit_code = run_enable(dds_options, *o); });

  // One request each; the word is the command's name (parse_drive_command), but for
  // `disable`, which is disable voltage.
  struct Single {
    const char* word;
    const char* help;
  };
  for (const Single& s : {Single{"disable", "Disable voltage: to switch on disabled, force off"},
                          Single{"quick-stop", "Quick stop: the drive brakes to standstill, then switch on disabled"},
                          Single{"fault-reset", "Fault reset: fault -> switch on disabled (then `enable`)"},
                          Single{"shutdown", "Shutdown: to ready to switch on"},
                          Single{"switch-on", "Switch on: ready to switch on -> switched on"}}) {
    const std::string word = s.word;
    const auto command = word == "disable" ? std::optional<drive::DriveCommand>(drive::DriveCommand::kDisableVoltage)
                                           : drive::parse_drive_command(word);
    if (!command) throw std::logic_error("pmlsm drive " + word + ": not a drive command");
    auto* sub = drive_app->add_subcommand(word, s.help);
    common(sub);
    sub->callback([&dds_options, o, &exit_code, c = *command] { exit_code = run_command(dds_options, *o, c); });
  }
}

}  // namespace pmlsm::tools
