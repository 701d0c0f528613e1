#include "canopen_config.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

namespace pmlsm::virtual_drive {
namespace {

[[noreturn]] void fail(const std::string& origin, const std::string& key, const std::string& what) {
  throw ConfigError(origin + ": " + key + ": " + what);
}

// Checks that `node` is a map holding exactly `keys` (no unknown, duplicate or missing key).
void check_keys(const YAML::Node& node, const std::string& origin, const std::string& prefix,
                const std::vector<std::string>& keys) {
  const std::string where = prefix.empty() ? "(top level)" : prefix;
  if (!node.IsMap()) fail(origin, where, "must be a map");
  std::set<std::string> seen;
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    bool known = false;
    for (const auto& k : keys) known = known || k == key;
    if (!known) {
      std::string list;
      for (const auto& k : keys) list += (list.empty() ? "" : ", ") + k;
      fail(origin, path, "unknown key (expected " + list + ")");
    }
    if (!seen.insert(key).second) fail(origin, path, "duplicate key");
  }
  for (const auto& k : keys) {
    if (seen.count(k) == 0) fail(origin, prefix.empty() ? k : prefix + "." + k, "missing key");
  }
}

// A sourced leaf {value: ..., source: "..."}: its value text.
std::string leaf_text(const YAML::Node& node, const std::string& origin, const std::string& path) {
  check_keys(node, origin, path, {"value", "source"});
  const YAML::Node value = node["value"];
  const YAML::Node source = node["source"];
  if (!source.IsScalar() || source.Scalar().empty()) fail(origin, path + ".source", "must be a non-empty text");
  if (!value.IsScalar()) fail(origin, path + ".value", "must be a scalar");
  return value.Scalar();
}

double number(const YAML::Node& node, const std::string& origin, const std::string& path) {
  const std::string text = leaf_text(node, origin, path);
  std::istringstream in(text);
  double x = 0;
  in >> x;
  if (in.fail() || !(in >> std::ws).eof()) fail(origin, path, "must be a number, got \"" + text + "\"");
  if (!std::isfinite(x)) fail(origin, path, "must be finite, got " + text);
  return x;
}

long long integer(const YAML::Node& node, const std::string& origin, const std::string& path, long long lo,
                  long long hi) {
  const std::string text = leaf_text(node, origin, path);
  std::istringstream in(text);
  long long x = 0;
  in >> x;
  if (in.fail() || !(in >> std::ws).eof()) fail(origin, path, "must be an integer, got \"" + text + "\"");
  if (x < lo || x > hi) {
    fail(origin, path, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + text);
  }
  return x;
}

}  // namespace

CanopenConfig parse_canopen_config(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin + ": YAML parse error: " + e.what());
  }
  CanopenConfig c;
  try {
    check_keys(root, origin, "",
               {"node_id", "rated_force_n", "increments_per_metre", "heartbeat_producer_ms", "heartbeat_consumer",
                "sync_timeout_ms"});
    c.node_id = static_cast<int>(integer(root["node_id"], origin, "node_id", 1, 127));
    c.rated_force_n = number(root["rated_force_n"], origin, "rated_force_n");
    if (!(c.rated_force_n > 0.0) || std::llround(c.rated_force_n * 1000.0) < 1 ||
        c.rated_force_n * 1000.0 > 4294967295.0) {
      fail(origin, "rated_force_n",
           "must be > 0 and at most 4294967.295 (0x6076 in mN), got " + leaf_text(root["rated_force_n"], origin, "rated_force_n"));
    }
    c.increments_per_metre = number(root["increments_per_metre"], origin, "increments_per_metre");
    if (!(c.increments_per_metre > 0.0)) {
      fail(origin, "increments_per_metre",
           "must be > 0, got " + leaf_text(root["increments_per_metre"], origin, "increments_per_metre"));
    }
    c.heartbeat_producer_ms = static_cast<std::uint16_t>(
        integer(root["heartbeat_producer_ms"], origin, "heartbeat_producer_ms", 0, 65535));
    const YAML::Node consumer = root["heartbeat_consumer"];
    check_keys(consumer, origin, "heartbeat_consumer", {"master_node_id", "time_ms"});
    c.master_node_id =
        static_cast<int>(integer(consumer["master_node_id"], origin, "heartbeat_consumer.master_node_id", 1, 127));
    c.consumer_time_ms =
        static_cast<std::uint16_t>(integer(consumer["time_ms"], origin, "heartbeat_consumer.time_ms", 0, 65535));
    c.sync_timeout_ms = static_cast<std::uint16_t>(integer(root["sync_timeout_ms"], origin, "sync_timeout_ms", 1, 65535));
    if (c.master_node_id == c.node_id) {
      fail(origin, "heartbeat_consumer.master_node_id",
           "must differ from node_id (" + std::to_string(c.node_id) + "), got " + std::to_string(c.master_node_id));
    }
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin + ": " + e.what());
  }
  return c;
}

CanopenConfig load_canopen_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot be read");
  std::stringstream text;
  text << in.rdbuf();
  return parse_canopen_config(text.str(), path);
}

}  // namespace pmlsm::virtual_drive
