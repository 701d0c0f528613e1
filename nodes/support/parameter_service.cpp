#include "parameter_service.hpp"

#include <cstdio>
#include <utility>
#include <vector>

namespace pmlsm::node {

namespace msg = pmlsm_msgs::msg;
namespace ops = pmlsm_msgs::msg::ParameterRequest_Constants;

namespace {

// A SET_MANY answer lists each change as "key: old -> new" (ParameterEvent.entries); the service
// writes them and a follower reads them back, both here.
constexpr const char* kKeySeparator = ": ";
constexpr const char* kChangeArrow = " -> ";

std::string change_entry(const LiveChange& change) {
  return change.key + kKeySeparator + change.old_value + kChangeArrow + change.new_value;
}

/// The key and the new value of an entry change_entry wrote; false for any other text.
bool parse_change_entry(const std::string& text, std::string& key, std::string& new_value) {
  const auto colon = text.find(kKeySeparator);
  const auto arrow = text.rfind(kChangeArrow);
  if (colon == std::string::npos || arrow == std::string::npos || arrow < colon) return false;
  key = text.substr(0, colon);
  new_value = text.substr(arrow + std::char_traits<char>::length(kChangeArrow));
  return true;
}

}  // namespace

ParameterService::ParameterService(NodeRuntime& rt, std::string node_name, LiveParameters& live)
    : rt_(rt),
      node_name_(std::move(node_name)),
      live_(live),
      reader_(rt.participant.make_reader(dds::topics::kParameterRequest, rt.wakeup)),
      writer_(rt.participant.make_writer(dds::topics::kParameterEvent)) {}

bool ParameterService::serve(std::uint64_t tick) {
  applied_ = false;
  while (reader_.take(request_)) {
    const std::string node = request_.node().to_string();
    if (!node.empty() && node != "*" && node != node_name_) continue;
    ++requests_;
    answer(tick);
  }
  return applied_ && live_.take_pending();
}

void ParameterService::list_into(msg::ParameterEvent& event) const {
  event.entries().clear();
  for (const std::string& key : live_.keys())
    event.entries().push_back((key + " = " + live_.get(key).value).substr(0, 192));
}

LiveAnswer ParameterService::set_many(std::uint64_t tick, const std::string& requester) {
  std::vector<std::pair<std::string, std::string>> changes;
  for (const auto& entry : request_.entries()) {
    const std::string text = entry.to_string();
    const auto equals = text.find(" = ");
    if (equals == std::string::npos || equals == 0) {
      LiveAnswer refused;
      refused.version = live_.version();
      refused.reason = "entry '" + text + "': expected 'key = value'";
      return refused;
    }
    changes.emplace_back(text.substr(0, equals), text.substr(equals + 3));
  }
  const LiveAnswer a = live_.set_many(changes);
  if (!a.accepted) {
    std::fprintf(stderr, "%s: tick %llu: %zu parameters refused together (by %s): %s\n", node_name_.c_str(),
                 static_cast<unsigned long long>(tick), changes.size(), requester.c_str(), a.reason.c_str());
    return a;
  }
  event_.effective_tick(tick);
  applied_ = true;
  const auto& history = live_.history();
  for (auto change = history.end() - static_cast<std::ptrdiff_t>(changes.size()); change != history.end(); ++change) {
    event_.entries().push_back(change_entry(*change).substr(0, 192));
    std::printf("%s: tick %llu: parameter %s %s -> %s (version %llu, by %s, together with %zu)\n", node_name_.c_str(),
                static_cast<unsigned long long>(tick), change->key.c_str(), change->old_value.c_str(),
                change->new_value.c_str(), static_cast<unsigned long long>(change->version), requester.c_str(),
                changes.size());
  }
  return a;
}

void ParameterService::answer(std::uint64_t tick) {
  for (const msg::ParameterEvent& earlier : answered_) {
    if (earlier.request_id() != 0 && earlier.request_id() == request_.request_id()) {
      writer_.write(earlier);  // a repeat: the same answer, nothing applied again
      return;
    }
  }
  event_ = msg::ParameterEvent{};
  event_.stamp(make_stamp(tick, rt_.period_s));
  event_.node(node_name_.substr(0, 64));
  event_.request_id(request_.request_id());
  event_.operation(request_.operation());
  const std::string key = request_.key().to_string();
  const std::string requester = request_.requester().to_string();
  LiveAnswer a;
  if (request_.operation() == ops::OPERATION_LIST) {
    a.accepted = true;
    a.version = live_.version();
    list_into(event_);
  } else if (request_.operation() == ops::OPERATION_GET) {
    a = live_.get(key);
  } else if (request_.operation() == ops::OPERATION_SET) {
    a = live_.set(key, request_.value().to_string());
    if (a.accepted) {
      const std::string& old_value = live_.history().back().old_value;
      event_.old_value(old_value.substr(0, 64));
      event_.effective_tick(tick);
      applied_ = true;
      std::printf("%s: tick %llu: parameter %s %s -> %s (version %llu, by %s)\n", node_name_.c_str(),
                  static_cast<unsigned long long>(tick), key.c_str(), old_value.c_str(), a.value.c_str(),
                  static_cast<unsigned long long>(a.version), requester.c_str());
    } else {
      std::fprintf(stderr, "%s: tick %llu: parameter %s = '%s' refused (by %s): %s\n", node_name_.c_str(),
                   static_cast<unsigned long long>(tick), key.c_str(), request_.value().c_str(), requester.c_str(),
                   a.reason.c_str());
    }
  } else if (request_.operation() == ops::OPERATION_SET_MANY) {
    a = set_many(tick, requester);
  } else {
    a.version = live_.version();
    a.reason = "unknown operation " + std::to_string(request_.operation());
  }
  refused_ += a.accepted ? 0 : 1;
  event_.accepted(a.accepted);
  event_.key(key.substr(0, 128));
  event_.value(a.value.substr(0, 64));
  event_.version(a.version);
  event_.reason(a.reason.substr(0, 256));
  writer_.write(event_);
  answered_[next_answered_] = event_;
  next_answered_ = (next_answered_ + 1) % answered_.size();
}

ParameterFollower::ParameterFollower(NodeRuntime& rt, std::string node_name, std::string owner,
                                     const SystemParams& params)
    : rt_(rt),
      node_name_(std::move(node_name)),
      followed_(std::move(owner), params),
      reader_(rt.participant.make_reader(dds::topics::kParameterEvent, rt.wakeup)) {
  entries_.reserve(64);
}

void ParameterFollower::take() {
  while (reader_.take(event_)) {
    const bool change = event_.operation() == ops::OPERATION_SET || event_.operation() == ops::OPERATION_SET_MANY;
    if (!event_.accepted() || !change || event_.node().to_string() != followed_.owner()) continue;
    entries_.clear();
    if (event_.operation() == ops::OPERATION_SET) {
      entries_.emplace_back(event_.key().to_string(), event_.value().to_string());
    } else {
      std::string key, value;
      for (const auto& entry : event_.entries()) {
        if (parse_change_entry(entry.to_string(), key, value)) entries_.emplace_back(key, value);
      }
    }
    const std::string refused = followed_.offer(event_.version(), entries_);
    if (!refused.empty()) {
      std::fprintf(stderr, "%s: %s's parameter change (version %llu) not followed: %s\n", node_name_.c_str(),
                   followed_.owner().c_str(), static_cast<unsigned long long>(event_.version()), refused.c_str());
    }
  }
}

void ParameterFollower::report_not_heard(std::uint64_t tick, std::uint64_t owner_version, double timeout_s) const {
  std::fprintf(stderr,
               "%s: tick %llu: %s computed it with parameter version %llu; the change was not heard within %.1f s\n",
               node_name_.c_str(), static_cast<unsigned long long>(tick), followed_.owner().c_str(),
               static_cast<unsigned long long>(owner_version), timeout_s);
}

ParameterFollower::Result ParameterFollower::at_tick(std::uint64_t tick, std::uint64_t owner_version) {
  // The owner's version says when there is something to take: a tick at the version applied
  // costs nothing (the reader keeps the newest 8192 events meanwhile, the owner's among them).
  if (owner_version == followed_.applied_version()) return Result::kSame;
  take();
  // Lockstep: written before the tick's data, it is on its way.
  if (rt_.cfg.clock == Clock::kLockstep && owner_version > followed_.offered_version()) return Result::kNotYet;
  const FollowedParameters::Step step = followed_.at_tick(owner_version);
  if (step.missing && !behind_) {
    behind_ = true;
    behind_since_tick_ = tick;
  }
  const char* late = "";
  char late_text[64] = "";
  if (step.changed && behind_) {
    std::snprintf(late_text, sizeof late_text, ", %llu tick(s) after %s",
                  static_cast<unsigned long long>(tick - behind_since_tick_), followed_.owner().c_str());
    late = late_text;
  }
  if (!step.missing) behind_ = false;
  if (step.owner_restarted) {
    std::printf("%s: tick %llu: %s restarted: its values as loaded from here\n", node_name_.c_str(),
                static_cast<unsigned long long>(tick), followed_.owner().c_str());
  }
  for (const LiveChange& c : followed_.applied_now()) {
    std::printf("%s: tick %llu: follows %s's parameter %s %s -> %s (version %llu%s)\n", node_name_.c_str(),
                static_cast<unsigned long long>(tick), followed_.owner().c_str(), c.key.c_str(), c.old_value.c_str(),
                c.new_value.c_str(), static_cast<unsigned long long>(c.version), late);
  }
  return step.changed ? Result::kChanged : Result::kSame;
}

}  // namespace pmlsm::node
