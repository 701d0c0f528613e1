#include "pmlsm/sim/live_parameters.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

/// A number that is the whole text: "12000", "1.5e-3"; not "12 000", "0x10", "nan".
double whole_number_text(const std::string& key, const std::string& text) {
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(begin, &end);
  const bool hex = text.find_first_of("xX") != std::string::npos;
  if (text.empty() || end != begin + text.size() || errno == ERANGE || !std::isfinite(x) || hex) {
    throw std::invalid_argument(key + ": expected a number, got '" + text + "'");
  }
  return x;
}

/// Finds one entry by its key path and reads (text_ empty: get) or sets it from text.
class EntryAccess {
 public:
  EntryAccess(const std::string& key, const std::string* text) : key_(key), text_(text) {}

  void real(const std::string& path, double& value, const Plausible&) {
    if (path != key_) return;
    found_ = true;
    if (text_ != nullptr) value = whole_number_text(key_, *text_);
    value_ = format_value(value);
  }
  template <typename T>
  void integer(const std::string& path, T& value, const Plausible&) {
    if (path != key_) return;
    found_ = true;
    if (text_ != nullptr) {
      const double x = whole_number_text(key_, *text_);
      if (x != std::trunc(x) || x < static_cast<double>(std::numeric_limits<T>::lowest()) ||
          x > static_cast<double>(std::numeric_limits<T>::max())) {
        throw std::invalid_argument(key_ + ": expected a whole number, got '" + *text_ + "'");
      }
      value = static_cast<T>(x);
    }
    value_ = std::to_string(value);
  }
  void flag(const std::string& path, bool& value) {
    if (path != key_) return;
    found_ = true;
    if (text_ != nullptr) {
      if (*text_ != "true" && *text_ != "false") {
        throw std::invalid_argument(key_ + ": expected true or false, got '" + *text_ + "'");
      }
      value = *text_ == "true";
    }
    value_ = value ? "true" : "false";
  }
  template <typename E, typename F>
  void choice(const std::string& path, E& value, F from_string, const char* /*live_at*/ = nullptr) {
    if (path != key_) return;
    found_ = true;
    if (text_ != nullptr) {
      try {
        value = from_string(*text_);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(key_ + ": " + e.what());
      }
    }
    value_ = to_string(value);
  }
  void vector3(const std::string& path, const Eigen::Vector3d&, const Plausible&) { list(path); }
  void integer_list(const std::string& path, const std::vector<int>&, const Plausible&) { list(path); }

  /// @throws std::invalid_argument when the key was not found or is a list.
  const std::string& value() const {
    if (list_) throw std::invalid_argument(key_ + ": a list: not read or set one value at a time");
    if (!found_) throw std::invalid_argument(key_ + ": no such parameter");
    return value_;
  }

 private:
  void list(const std::string& path) { list_ = list_ || path == key_; }

  std::string key_;
  const std::string* text_;
  bool found_ = false;
  bool list_ = false;
  std::string value_;
};

/// Why the system refused a change: the check's own words, and when the check was of a value
/// derived from the changed one elsewhere (state feedback's model runs on the controller's Kp),
/// the change named too, so both ends are said.
std::string refusal(const std::string& key, const std::string& text, const std::invalid_argument& e) {
  const std::string what = e.what();
  if (what.compare(0, key.size(), key) == 0) return what;
  return key + " = " + text + " refused by a value derived from it: " + what;
}

}  // namespace

std::string parameter_text(const SystemParams& params, const std::string& key_path) {
  SystemParams copy = params;  // the visitor takes the entries by reference; nothing is written
  EntryAccess access(key_path, nullptr);
  visit_parameters(copy, access);
  return access.value();
}

void set_parameter(SystemParams& params, const std::string& key_path, const std::string& text) {
  EntryAccess access(key_path, &text);
  visit_parameters(params, access);
  access.value();  // throws when the key was not found
}

LiveParameters::LiveParameters(const SystemParams& params, std::vector<std::string> live_keys)
    : params_(params), keys_(std::move(live_keys)) {
  for (const std::string& key : keys_) parameter_text(params_, key);  // throws for an unknown one
  history_.reserve(64);
}

bool LiveParameters::is_live(const std::string& key) const {
  return std::find(keys_.begin(), keys_.end(), key) != keys_.end();
}

LiveAnswer LiveParameters::get(const std::string& key) const {
  LiveAnswer answer;
  answer.version = version_;
  if (!is_live(key)) {
    answer.reason = key + ": not a live parameter of this node (" + std::to_string(keys_.size()) + " are)";
    return answer;
  }
  answer.accepted = true;
  answer.value = parameter_text(params_, key);
  return answer;
}

LiveAnswer LiveParameters::set(const std::string& key, const std::string& text) {
  LiveAnswer answer = get(key);
  if (!answer.accepted) return answer;
  answer.accepted = false;
  SystemParams changed = params_;
  try {
    set_parameter(changed, key, text);
  } catch (const std::invalid_argument& e) {
    answer.reason = e.what();
    return answer;
  }
  try {
    changed.validate();  // the file's ranges and the components' checks, with the change in it
  } catch (const std::invalid_argument& e) {
    answer.reason = refusal(key, text, e);
    return answer;
  }
  const std::string new_value = parameter_text(changed, key);
  params_ = std::move(changed);
  pending_ = true;
  ++version_;
  history_.push_back({version_, key, answer.value, new_value});
  answer.accepted = true;
  answer.version = version_;
  answer.value = new_value;
  return answer;
}

LiveAnswer LiveParameters::set_many(const std::vector<std::pair<std::string, std::string>>& changes) {
  LiveAnswer answer;
  answer.version = version_;
  if (changes.empty()) {
    answer.reason = "no changes";
    return answer;
  }
  SystemParams changed = params_;
  std::vector<std::string> old_values;
  old_values.reserve(changes.size());
  for (const auto& change : changes) {
    const std::string& key = change.first;
    const std::string& text = change.second;
    if (std::count_if(changes.begin(), changes.end(), [&key](const auto& c) { return c.first == key; }) > 1) {
      answer.reason = key + ": given more than once";
      return answer;
    }
    const LiveAnswer current = get(key);
    if (!current.accepted) {
      answer.reason = current.reason;
      return answer;
    }
    old_values.push_back(current.value);
    try {
      set_parameter(changed, key, text);
    } catch (const std::invalid_argument& e) {
      answer.reason = e.what();
      return answer;
    }
  }
  try {
    changed.validate();  // once, with every change in it
  } catch (const std::invalid_argument& e) {
    answer.reason = e.what();
    const bool own = std::any_of(changes.begin(), changes.end(),
                                 [&](const auto& c) { return answer.reason.compare(0, c.first.size(), c.first) == 0; });
    if (!own)
      answer.reason =
          "the " + std::to_string(changes.size()) + " changes refused by a value derived from them: " + answer.reason;
    return answer;
  }
  for (std::size_t i = 0; i < changes.size(); ++i) {
    ++version_;
    history_.push_back({version_, changes[i].first, old_values[i], parameter_text(changed, changes[i].first)});
  }
  params_ = std::move(changed);
  pending_ = true;
  answer.accepted = true;
  answer.version = version_;
  return answer;
}

bool LiveParameters::take_pending() {
  const bool pending = pending_;
  pending_ = false;
  return pending;
}

namespace {

// Collects the keys an entry names `node` as taking live.
class LiveKeyCollector {
 public:
  explicit LiveKeyCollector(const std::string& node) : node_(node) {}
  void real(const std::string& path, const double&, const Plausible& range) { add(path, range.live_at); }
  template <typename T>
  void integer(const std::string& path, const T&, const Plausible& range) {
    add(path, range.live_at);
  }
  void flag(const std::string&, const bool&) {}
  template <typename E, typename F>
  void choice(const std::string& path, const E&, F, const char* live_at = nullptr) {
    add(path, live_at);
  }
  void vector3(const std::string&, const Eigen::Vector3d&, const Plausible&) {}
  void integer_list(const std::string&, const std::vector<int>&, const Plausible&) {}

  std::vector<std::string> keys;

 private:
  void add(const std::string& path, const char* live_at) {
    if (live_at != nullptr && node_ == live_at) keys.push_back(path);
  }
  std::string node_;
};

}  // namespace

std::vector<std::string> live_keys(const SystemParams& params, const std::string& node) {
  LiveKeyCollector collector(node);
  visit_parameters(params, collector);
  return collector.keys;
}

FollowedParameters::FollowedParameters(std::string owner, const SystemParams& params)
    : owner_(std::move(owner)), start_(params) {
  pending_.reserve(16);
  values_.reserve(16);
  applied_now_.reserve(16);
}

std::string FollowedParameters::offer(std::uint64_t version,
                                      const std::vector<std::pair<std::string, std::string>>& entries) {
  if (entries.empty()) return "version " + std::to_string(version) + ": no entries";
  if (version < entries.size()) {
    return "version " + std::to_string(version) + " with " + std::to_string(entries.size()) + " entries";
  }
  const std::uint64_t first = version - entries.size() + 1;
  if (version <= offered_version_) return "";  // heard before (a repeated answer)
  if (first != offered_version_ + 1) {
    return "versions " + std::to_string(first) + " to " + std::to_string(version) + " after " +
           std::to_string(offered_version_) + ": a change between them was not heard";
  }
  SystemParams check = start_;
  for (const auto& [key, text] : entries) {
    try {
      set_parameter(check, key, text);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
  }
  std::uint64_t v = first;
  for (const auto& [key, text] : entries) pending_.push_back({v++, key, "", text});
  offered_version_ = version;
  return "";
}

FollowedParameters::Step FollowedParameters::at_tick(std::uint64_t owner_version) {
  Step step;
  applied_now_.clear();
  if (owner_version < applied_version_) {
    // Restarted from its file: what it had changed is gone, and so is what it had announced.
    step.owner_restarted = step.changed = true;
    values_.clear();
    pending_.clear();
    applied_version_ = offered_version_ = 0;
  }
  std::size_t taken = 0;
  for (; taken < pending_.size() && pending_[taken].version <= owner_version; ++taken) {
    LiveChange change = pending_[taken];
    auto value = std::find_if(values_.begin(), values_.end(), [&](const auto& v) { return v.first == change.key; });
    change.old_value = value != values_.end() ? value->second : parameter_text(start_, change.key);
    if (value != values_.end()) {
      value->second = change.new_value;
    } else {
      values_.emplace_back(change.key, change.new_value);
    }
    applied_version_ = change.version;
    applied_now_.push_back(std::move(change));
    step.changed = true;
  }
  pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(taken));
  step.missing = owner_version > applied_version_;
  return step;
}

void FollowedParameters::overlay(SystemParams& params) const {
  for (const auto& [key, text] : values_) set_parameter(params, key, text);
}

}  // namespace pmlsm
