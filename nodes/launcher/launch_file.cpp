#include "launch_file.hpp"

#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

namespace pmlsm::launch {

namespace {

const std::vector<std::string> kTopKeys = {"name", "hosts", "nodes", "args", "common_args", "containers"};
const std::vector<std::string> kNodeKeys = {"name", "executable", "host",        "common_args",
                                            "args", "env",        "ends_launch", "if"};
const std::vector<std::string> kContainerKeys = {"name", "components", "host", "args", "if"};
/// The program that runs components in one process (nodes/container).
constexpr const char* kContainerExecutable = "container";

std::string join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : sep) + item;
  return out;
}

template <typename Map>
std::string join_keys(const Map& map) {
  std::vector<std::string> keys;
  for (const auto& kv : map) keys.push_back(kv.first);
  return keys.empty() ? std::string("none") : join(keys);
}

bool matches(const std::string& text, bool (*allowed)(char)) {
  if (text.empty()) return false;
  for (char c : text) {
    if (!allowed(c)) return false;
  }
  return true;
}

bool is_alnum(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'); }
bool node_name_char(char c) { return is_alnum(c) || c == '_' || c == '-'; }
bool host_name_char(char c) { return node_name_char(c) || c == '.'; }
bool identifier_char(char c) { return is_alnum(c) || c == '_'; }
bool is_identifier(const std::string& s) { return matches(s, identifier_char) && !(s[0] >= '0' && s[0] <= '9'); }

// Describes a YAML value for messages, quoting scalars.
std::string describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null: return "null";
    case YAML::NodeType::Scalar: return "'" + node.Scalar() + "'";
    case YAML::NodeType::Sequence: return "a list";
    case YAML::NodeType::Map: return "a map";
    default: return "nothing";
  }
}

// Where a value sits: "file:line:col: key.path", the prefix of every message.
class Location {
 public:
  explicit Location(const std::string& source) : source_(source) {}

  std::string at(const YAML::Node& node, const std::string& path) const {
    std::string out = source_;
    const YAML::Mark mark = node.Mark();
    if (!mark.is_null()) {
      out += ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
    }
    return path.empty() ? out : out + ": " + path;
  }

  [[noreturn]] void fail(const YAML::Node& node, const std::string& path, const std::string& what) const {
    throw LaunchFileError(at(node, path) + ": " + what);
  }

 private:
  const std::string& source_;
};

// The keys of a map in file order, each checked against `allowed` and for duplicates.
std::vector<std::pair<std::string, YAML::Node>> checked_fields(const Location& loc, const YAML::Node& map,
                                                               const std::string& path,
                                                               const std::vector<std::string>& allowed) {
  std::vector<std::pair<std::string, YAML::Node>> fields;
  std::set<std::string> seen;
  const std::string prefix = path.empty() ? "" : path + ".";
  for (const auto& kv : map) {
    if (!kv.first.IsScalar()) loc.fail(kv.first, path, "keys must be strings, got " + describe(kv.first));
    const std::string key = kv.first.Scalar();
    if (!allowed.empty()) {
      bool known = false;
      for (const auto& a : allowed) known = known || a == key;
      if (!known) loc.fail(kv.first, prefix + key, "unknown key (allowed: " + join(allowed) + ")");
    }
    if (!seen.insert(key).second) loc.fail(kv.first, prefix + key, "duplicate key");
    fields.emplace_back(key, kv.second);
  }
  return fields;
}

const YAML::Node* find(const std::vector<std::pair<std::string, YAML::Node>>& fields, const std::string& key) {
  for (const auto& kv : fields) {
    if (kv.first == key) return &kv.second;
  }
  return nullptr;
}

const YAML::Node& require(const Location& loc, const YAML::Node& map,
                          const std::vector<std::pair<std::string, YAML::Node>>& fields, const std::string& path,
                          const std::string& key) {
  const YAML::Node* node = find(fields, key);
  if (node == nullptr) {
    loc.fail(map, path, "missing required key '" + key + "'");
  }
  return *node;
}

std::string string_value(const Location& loc, const YAML::Node& node, const std::string& path) {
  if (!node.IsScalar()) loc.fail(node, path, "must be a string, got " + describe(node));
  return node.Scalar();
}

std::string non_empty_string(const Location& loc, const YAML::Node& node, const std::string& path) {
  std::string value = string_value(loc, node, path);
  if (value.empty()) loc.fail(node, path, "must not be empty");
  return value;
}

bool bool_value(const Location& loc, const YAML::Node& node, const std::string& path) {
  if (node.IsScalar()) {
    const std::string& v = node.Scalar();
    if (v == "true" || v == "True" || v == "TRUE") return true;
    if (v == "false" || v == "False" || v == "FALSE") return false;
  }
  loc.fail(node, path, "must be true or false, got " + describe(node));
}

std::vector<std::string> parse_hosts(const Location& loc, const YAML::Node& node) {
  if (!node.IsSequence()) loc.fail(node, "hosts", "must be a list of host names, got " + describe(node));
  if (node.size() == 0) loc.fail(node, "hosts", "must not be empty (leave it out for one host 'local')");
  std::vector<std::string> hosts;
  for (std::size_t i = 0; i < node.size(); ++i) {
    const std::string path = "hosts[" + std::to_string(i) + "]";
    std::string host = string_value(loc, node[i], path);
    if (!matches(host, host_name_char)) {
      loc.fail(node[i], path, "'" + host + "' is not a host name ([A-Za-z0-9_.-]+)");
    }
    for (const auto& h : hosts) {
      if (h == host) loc.fail(node[i], path, "'" + host + "' is listed twice");
    }
    hosts.push_back(std::move(host));
  }
  return hosts;
}

/// An arg's default with a leading $(dirname) made the launch file's own folder: a path in the file
/// resolves against it, wherever the launcher runs (an override is the user's: from the current folder).
std::string default_value(const std::string& text, const std::string& source) {
  constexpr std::string_view kDirname = "$(dirname)";
  if (text.compare(0, kDirname.size(), kDirname) != 0) return text;
  const std::string folder = std::filesystem::absolute(source).parent_path().string();
  return std::filesystem::path(folder + text.substr(kDirname.size())).lexically_normal().string();
}

std::map<std::string, std::string> parse_args(const Location& loc, const YAML::Node& node, const std::string& source) {
  if (!node.IsMap()) loc.fail(node, "args", "must be a map of arg names to default values, got " + describe(node));
  std::map<std::string, std::string> args;
  for (const auto& [key, value] : checked_fields(loc, node, "args", {})) {
    const std::string path = "args." + key;
    if (!is_identifier(key)) loc.fail(value, path, "'" + key + "' is not an arg name ([A-Za-z_][A-Za-z0-9_]*)");
    args[key] = default_value(string_value(loc, value, path), source);
  }
  return args;
}

}  // namespace

namespace {

std::string trimmed(const std::string& t) {
  const auto first = t.find_first_not_of(" \t");
  if (first == std::string::npos) return std::string();
  return t.substr(first, t.find_last_not_of(" \t") - first + 1);
}

/// `text` split at every `separator`.
std::vector<std::string> split_at(const std::string& text, const std::string& separator) {
  std::vector<std::string> parts;
  std::size_t from = 0;
  for (std::size_t at = text.find(separator); at != std::string::npos; at = text.find(separator, from)) {
    parts.push_back(text.substr(from, at - from));
    from = at + separator.size();
  }
  parts.push_back(text.substr(from));
  return parts;
}

/// true, false, A == B or A != B; nullopt when it is none of them.
std::optional<bool> evaluate_comparison(const std::string& text) {
  const std::string condition = trimmed(text);
  if (condition == "true") return true;
  if (condition == "false") return false;
  for (const char* op : {"==", "!="}) {
    const auto at = condition.find(op);
    if (at == std::string::npos) continue;
    const std::string left = trimmed(condition.substr(0, at));
    const std::string right = trimmed(condition.substr(at + 2));
    if (left.empty() || right.empty() || right.find("==") != std::string::npos ||
        right.find("!=") != std::string::npos) {
      return std::nullopt;
    }
    return (left == right) == (op[0] == '=');
  }
  return std::nullopt;
}

}  // namespace

bool evaluate_condition(const std::string& text, const std::string& where) {
  // Alternatives (||) of conjunctions (&&) of comparisons; every part is checked, none skipped.
  bool any = false;
  bool well_formed = true;
  for (const std::string& alternative : split_at(text, "||")) {
    bool all = true;
    for (const std::string& part : split_at(alternative, "&&")) {
      const std::optional<bool> value = evaluate_comparison(part);
      if (!value) well_formed = false;
      all = all && value.value_or(false);
    }
    any = any || all;
  }
  if (!well_formed) {
    throw LaunchFileError(where + ": '" + text +
                          "': a condition is true, false, A == B or A != B, joined by && and || (&& binds first)");
  }
  return any;
}

namespace {

NodeSpec parse_node(const Location& loc, const YAML::Node& node, const std::string& path,
                    const std::vector<std::string>& hosts, const std::map<std::string, std::string>& args,
                    const std::vector<std::string>& common_args) {
  if (!node.IsMap()) loc.fail(node, path, "must be a map with at least name and executable, got " + describe(node));
  const auto fields = checked_fields(loc, node, path, kNodeKeys);
  NodeSpec spec;

  const YAML::Node& name = require(loc, node, fields, path, "name");
  spec.name = string_value(loc, name, path + ".name");
  if (!matches(spec.name, node_name_char)) {
    loc.fail(name, path + ".name", "'" + spec.name + "' is not a node name ([A-Za-z0-9_-]+)");
  }
  if (spec.name == "launcher") {
    loc.fail(name, path + ".name", "'launcher' is reserved for the launcher's own messages");
  }

  const YAML::Node& exe = require(loc, node, fields, path, "executable");
  const std::string exe_path = path + ".executable";
  spec.executable = substitute_args(non_empty_string(loc, exe, exe_path), args, loc.at(exe, exe_path));
  if (spec.executable.empty()) loc.fail(exe, exe_path, "is empty after substitution");

  spec.host = hosts.front();
  if (const YAML::Node* host = find(fields, "host")) {
    spec.host = string_value(loc, *host, path + ".host");
    bool known = false;
    for (const auto& h : hosts) known = known || h == spec.host;
    if (!known) {
      loc.fail(*host, path + ".host", "'" + spec.host + "' is not among hosts [" + join(hosts) + "]");
    }
  }

  // The file's common_args first (the options every node of it shares), unless the node says
  // `common_args: false`; then its own.
  const YAML::Node* takes_common = find(fields, "common_args");
  if (takes_common == nullptr || bool_value(loc, *takes_common, path + ".common_args")) spec.args = common_args;
  if (const YAML::Node* list = find(fields, "args")) {
    if (!list->IsSequence()) {
      loc.fail(*list, path + ".args", "must be a list of strings, got " + describe(*list));
    }
    for (std::size_t i = 0; i < list->size(); ++i) {
      const std::string item_path = path + ".args[" + std::to_string(i) + "]";
      const YAML::Node item = (*list)[i];
      spec.args.push_back(substitute_args(string_value(loc, item, item_path), args, loc.at(item, item_path)));
    }
  }

  if (const YAML::Node* env = find(fields, "env")) {
    if (!env->IsMap()) {
      loc.fail(*env, path + ".env", "must be a map of variable names to strings, got " + describe(*env));
    }
    for (const auto& [key, value] : checked_fields(loc, *env, path + ".env", {})) {
      const std::string var_path = path + ".env." + key;
      if (!is_identifier(key)) {
        loc.fail(value, var_path, "'" + key + "' is not an environment variable name ([A-Za-z_][A-Za-z0-9_]*)");
      }
      spec.env.emplace_back(key, substitute_args(string_value(loc, value, var_path), args, loc.at(value, var_path)));
    }
  }

  if (const YAML::Node* ends = find(fields, "ends_launch")) {
    spec.ends_launch = bool_value(loc, *ends, path + ".ends_launch");
  }
  if (const YAML::Node* condition = find(fields, "if")) {
    const std::string where = loc.at(*condition, path + ".if");
    spec.enabled = evaluate_condition(substitute_args(string_value(loc, *condition, path + ".if"), args, where), where);
  }
  return spec;
}

std::vector<std::string> string_list(const Location& loc, const YAML::Node& node, const std::string& path,
                                     const std::map<std::string, std::string>& args) {
  if (!node.IsSequence()) loc.fail(node, path, "must be a list of strings, got " + describe(node));
  std::vector<std::string> out;
  for (std::size_t i = 0; i < node.size(); ++i) {
    const std::string item_path = path + "[" + std::to_string(i) + "]";
    out.push_back(substitute_args(string_value(loc, node[i], item_path), args, loc.at(node[i], item_path)));
  }
  return out;
}

using Fields = std::vector<std::pair<std::string, YAML::Node>>;

/// A container's `name`: a valid name that is neither a node's nor the launcher's.
std::string checked_container_name(const Location& loc, const YAML::Node& node, const Fields& fields,
                                   const std::string& path, const std::vector<NodeSpec>& all_nodes) {
  const YAML::Node& name_node = require(loc, node, fields, path, "name");
  const std::string name = string_value(loc, name_node, path + ".name");
  if (!matches(name, node_name_char)) {
    loc.fail(name_node, path + ".name", "'" + name + "' is not a container name ([A-Za-z0-9_-]+)");
  }
  for (const auto& n : all_nodes) {
    if (n.name == name) loc.fail(name_node, path + ".name", "'" + name + "' is already the name of a node");
  }
  if (name == "launcher") loc.fail(name_node, path + ".name", "'launcher' is reserved for the launcher's own messages");
  return name;
}

/// The entry's `if` after substitution; true without one.
bool entry_condition_holds(const Location& loc, const Fields& fields, const std::string& path,
                           const std::map<std::string, std::string>& args) {
  const YAML::Node* condition = find(fields, "if");
  if (condition == nullptr) return true;
  const std::string where = loc.at(*condition, path + ".if");
  return evaluate_condition(substitute_args(string_value(loc, *condition, path + ".if"), args, where), where);
}

/// A left-out container's components are checked all the same: a typo shows whatever the args.
void check_left_out_components(const Location& loc, const YAML::Node& list, const std::string& path,
                               const std::vector<std::string>& names, const std::vector<NodeSpec>& all_nodes) {
  for (std::size_t i = 0; i < names.size(); ++i) {
    const bool known =
        std::any_of(all_nodes.begin(), all_nodes.end(), [&](const NodeSpec& n) { return n.name == names[i]; });
    if (!known) {
      loc.fail(list[i], path + ".components[" + std::to_string(i) + "]",
               "'" + names[i] + "' is not a node of this file");
    }
  }
}

/// The node a container's component names, checked: in the file and in no other container
/// (`taken`); when its own `if` holds, without env and named, not a path. nullptr when its own
/// `if` left it out.
const NodeSpec* checked_component(const Location& loc, const YAML::Node& item, const std::string& item_path,
                                  const std::string& name, const std::vector<NodeSpec>& all_nodes,
                                  std::set<std::string>& taken) {
  const auto in_file =
      std::find_if(all_nodes.begin(), all_nodes.end(), [&](const NodeSpec& n) { return n.name == name; });
  if (in_file == all_nodes.end()) {
    std::vector<std::string> known;
    for (const auto& n : all_nodes) known.push_back(n.name);
    loc.fail(item, item_path, "'" + name + "' is not a node of this file (nodes: " + join(known) + ")");
  }
  if (!taken.insert(name).second) loc.fail(item, item_path, "'" + name + "' is already in a container");
  if (!in_file->enabled) return nullptr;
  if (!in_file->env.empty()) {
    loc.fail(item, item_path,
             "'" + name +
                 "' sets env: the components of a container share one process's "
                 "environment; run it alone or move the variables to the launch");
  }
  if (in_file->executable.find('/') != std::string::npos) {
    loc.fail(item, item_path,
             "'" + name + "' runs '" + in_file->executable +
                 "': a container makes components by node name (plant_sim, controller, ...), not paths");
  }
  return &*in_file;
}

/// Puts `container` in `launch.nodes` at `first_index` in place of its components, with each
/// component's command line as its args.
void replace_components_by_container(LaunchDescription& launch, NodeSpec container, std::size_t first_index) {
  const auto is_component = [&](const NodeSpec& n) {
    return std::find(container.components.begin(), container.components.end(), n.name) != container.components.end();
  };
  // Each component's command line, in the order of `nodes` (the container sorts the chain itself).
  for (const auto& n : launch.nodes) {
    if (!is_component(n)) continue;
    container.args.push_back("--component");
    container.args.push_back(n.name);
    container.args.push_back(n.executable);
    container.args.insert(container.args.end(), n.args.begin(), n.args.end());
  }
  std::vector<NodeSpec> rest;
  for (std::size_t i = 0; i < launch.nodes.size(); ++i) {
    if (i == first_index) rest.push_back(container);
    const auto& n = launch.nodes[i];
    if (!is_component(n)) rest.push_back(n);
  }
  launch.nodes = std::move(rest);
}

// One `containers:` entry against the nodes already parsed: replaces its components in
// `launch.nodes` (when its `if` holds). `taken` collects the nodes already in a container.
void apply_container(const Location& loc, const YAML::Node& node, const std::string& path,
                     const std::vector<NodeSpec>& all_nodes, std::set<std::string>& taken, LaunchDescription& launch) {
  if (!node.IsMap()) loc.fail(node, path, "must be a map with name and components, got " + describe(node));
  const auto fields = checked_fields(loc, node, path, kContainerKeys);
  const std::string name = checked_container_name(loc, node, fields, path, all_nodes);
  const bool enabled = entry_condition_holds(loc, fields, path, launch.args);
  const YAML::Node& list = require(loc, node, fields, path, "components");
  const std::vector<std::string> names = string_list(loc, list, path + ".components", launch.args);
  if (names.empty()) loc.fail(list, path + ".components", "must list at least one node");
  if (!enabled) {
    check_left_out_components(loc, list, path, names, all_nodes);
    launch.left_out.push_back(name);
    return;
  }

  NodeSpec spec;
  spec.name = name;
  spec.executable = kContainerExecutable;
  spec.args = {"--name", name};
  if (const YAML::Node* own = find(fields, "args")) {
    const auto more = string_list(loc, *own, path + ".args", launch.args);
    spec.args.insert(spec.args.end(), more.begin(), more.end());
  }
  const YAML::Node* own_host = find(fields, "host");
  std::optional<std::string> host;
  if (own_host != nullptr) host = string_value(loc, *own_host, path + ".host");
  std::size_t first_index = launch.nodes.size();
  for (std::size_t i = 0; i < names.size(); ++i) {
    const std::string item_path = path + ".components[" + std::to_string(i) + "]";
    const NodeSpec* component = checked_component(loc, list[i], item_path, names[i], all_nodes, taken);
    if (component == nullptr) continue;  // left out by its own `if`
    // With its own `host` the container takes its components there; without, they share one.
    if (!host) host = component->host;
    if (own_host == nullptr && component->host != *host) {
      loc.fail(list[i], item_path,
               "'" + names[i] + "' is on host " + component->host + ", the container on " + *host +
                   ": a container is one process on one host");
    }
    const auto at =
        std::find_if(launch.nodes.begin(), launch.nodes.end(), [&](const NodeSpec& n) { return n.name == names[i]; });
    first_index = std::min(first_index, static_cast<std::size_t>(at - launch.nodes.begin()));
    spec.components.push_back(names[i]);
    spec.ends_launch = spec.ends_launch || component->ends_launch;
  }
  if (spec.components.empty()) {
    launch.left_out.push_back(name);  // every component left out by its own `if`
    return;
  }
  bool known_host = false;
  for (const auto& h : launch.hosts) known_host = known_host || h == *host;
  if (!known_host) loc.fail(node, path + ".host", "'" + *host + "' is not among hosts [" + join(launch.hosts) + "]");
  spec.host = *host;
  replace_components_by_container(launch, std::move(spec), first_index);
}

}  // namespace

LaunchDescription parse_launch(const std::string& text, const std::string& source, const ArgOverrides& overrides) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw LaunchFileError(source + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) +
                          ": invalid YAML: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw LaunchFileError(source + ": invalid YAML: " + e.what());
  }
  const Location loc(source);
  if (!root.IsMap()) {
    loc.fail(root, "", "the top level must be a map with name and nodes, got " + describe(root));
  }
  const auto fields = checked_fields(loc, root, "", kTopKeys);

  LaunchDescription launch;
  launch.source = source;
  launch.name = non_empty_string(loc, require(loc, root, fields, "", "name"), "name");

  if (const YAML::Node* args = find(fields, "args")) launch.args = parse_args(loc, *args, source);
  for (const auto& [key, value] : overrides) {
    auto it = launch.args.find(key);
    if (it == launch.args.end()) {
      throw LaunchFileError(source + ": --arg " + key + "=" + value + ": no arg '" + key +
                            "' is declared (declared: " + join_keys(launch.args) + ")");
    }
    it->second = value;
  }

  launch.hosts = {"local"};
  if (const YAML::Node* hosts = find(fields, "hosts")) launch.hosts = parse_hosts(loc, *hosts);
  std::vector<std::string> common_args;
  if (const YAML::Node* common = find(fields, "common_args")) {
    common_args = string_list(loc, *common, "common_args", launch.args);
  }

  const YAML::Node& nodes = require(loc, root, fields, "", "nodes");
  if (!nodes.IsSequence()) loc.fail(nodes, "nodes", "must be a list of nodes, got " + describe(nodes));
  if (nodes.size() == 0) loc.fail(nodes, "nodes", "must list at least one node");
  std::map<std::string, std::size_t> index_of;
  std::vector<NodeSpec> all_nodes;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const std::string path = "nodes[" + std::to_string(i) + "]";
    NodeSpec spec = parse_node(loc, nodes[i], path, launch.hosts, launch.args, common_args);
    all_nodes.push_back(spec);
    const auto [it, inserted] = index_of.emplace(spec.name, i);
    if (!inserted) {
      loc.fail(nodes[i]["name"], path + ".name",
               "'" + spec.name + "' is already the name of nodes[" + std::to_string(it->second) + "]");
    }
    if (spec.enabled) {
      launch.nodes.push_back(std::move(spec));
    } else {
      launch.left_out.push_back(spec.name);
    }
  }
  if (launch.nodes.empty()) {
    loc.fail(nodes, "nodes", "every node is left out by its 'if' (left out: " + join(launch.left_out) + ")");
  }
  if (const YAML::Node* containers = find(fields, "containers")) {
    if (!containers->IsSequence()) {
      loc.fail(*containers, "containers", "must be a list of containers, got " + describe(*containers));
    }
    std::set<std::string> taken;
    std::set<std::string> container_names;
    for (std::size_t i = 0; i < containers->size(); ++i) {
      const std::string path = "containers[" + std::to_string(i) + "]";
      const YAML::Node entry = (*containers)[i];
      if (entry.IsMap() && entry["name"] && entry["name"].IsScalar() &&
          !container_names.insert(entry["name"].Scalar()).second) {
        loc.fail(entry["name"], path + ".name", "'" + entry["name"].Scalar() + "' is already the name of a container");
      }
      apply_container(loc, entry, path, all_nodes, taken, launch);
    }
  }
  return launch;
}

LaunchDescription load_launch_file(const std::string& path, const ArgOverrides& overrides) {
  std::ifstream in(path);
  if (!in) throw LaunchFileError(path + ": cannot open launch file: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return parse_launch(text.str(), path, overrides);
}

std::pair<std::string, std::string> parse_arg_override(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw LaunchFileError("--arg '" + text + "': expected NAME=VALUE");
  }
  return {text.substr(0, eq), text.substr(eq + 1)};
}

std::string substitute_args(const std::string& text, const std::map<std::string, std::string>& args,
                            const std::string& where) {
  std::string out;
  std::size_t pos = 0;
  for (;;) {
    const std::size_t open = text.find("$(", pos);
    if (open == std::string::npos) break;
    out.append(text, pos, open - pos);
    const std::size_t close = text.find(')', open);
    if (close == std::string::npos) {
      throw LaunchFileError(where + ": '" + text + "': '$(' without a closing ')'");
    }
    std::istringstream inner(text.substr(open + 2, close - open - 2));
    std::string kind, name, extra;
    inner >> kind >> name >> extra;
    if (kind != "arg" || name.empty() || !extra.empty()) {
      throw LaunchFileError(where + ": '" + text + "': unknown substitution '" + text.substr(open, close - open + 1) +
                            "' (only $(arg NAME) exists, and $(dirname) at the start of an arg's default)");
    }
    const auto it = args.find(name);
    if (it == args.end()) {
      throw LaunchFileError(where + ": '" + text + "': unknown arg '" + name + "' (declared: " + join_keys(args) + ")");
    }
    out += it->second;
    pos = close + 1;
  }
  out.append(text, pos, std::string::npos);
  return out;
}

std::vector<NodeSpec> select_nodes(const LaunchDescription& launch, const std::optional<std::string>& host) {
  if (!host) return launch.nodes;
  bool known = false;
  for (const auto& h : launch.hosts) known = known || h == *host;
  if (!known) {
    throw LaunchFileError(launch.source + ": --host '" + *host + "': unknown host (known: " + join(launch.hosts) + ")");
  }
  std::vector<NodeSpec> selected;
  for (const auto& node : launch.nodes) {
    if (node.host == *host) selected.push_back(node);
  }
  return selected;
}

std::string resolve_executable(const std::string& executable, const std::string& bin_dir, const std::string& path_env) {
  const auto usable = [](const std::string& path) {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
  };
  if (executable.find('/') != std::string::npos) {
    if (usable(executable)) return executable;
    std::error_code ec;
    const std::string cwd = std::filesystem::current_path(ec).string();
    struct stat st {};
    const bool exists = ::stat(executable.c_str(), &st) == 0;
    throw ExecutableNotFound("executable '" + executable + "' " + (exists ? "is not an executable file" : "not found") +
                             (executable[0] == '/' ? std::string() : " (relative to " + cwd + ")"));
  }
  std::vector<std::string> dirs;
  if (!bin_dir.empty()) dirs.push_back(bin_dir);
  std::size_t start = 0;
  while (!path_env.empty()) {
    const std::size_t colon = path_env.find(':', start);
    const std::string dir = path_env.substr(start, colon == std::string::npos ? colon : colon - start);
    // POSIX: an empty PATH entry means the current directory.
    const std::string entry = dir.empty() ? "." : dir;
    if (std::find(dirs.begin(), dirs.end(), entry) == dirs.end()) dirs.push_back(entry);
    if (colon == std::string::npos) break;
    start = colon + 1;
  }
  for (const auto& dir : dirs) {
    const std::string candidate = dir + "/" + executable;
    if (usable(candidate)) return candidate;
  }
  throw ExecutableNotFound("executable '" + executable + "' not found (looked in " + join(dirs) + ")");
}

std::string slice_yaml(const std::string& name, const std::string& host, const std::vector<NodeSpec>& nodes) {
  YAML::Emitter out;
  out << YAML::DoubleQuoted << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << name;
  out << YAML::Key << "hosts" << YAML::Value << YAML::Flow << YAML::BeginSeq << host << YAML::EndSeq;
  out << YAML::Key << "nodes" << YAML::Value << YAML::BeginSeq;
  for (const auto& node : nodes) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << node.name;
    out << YAML::Key << "executable" << YAML::Value << node.executable;
    out << YAML::Key << "host" << YAML::Value << host;
    out << YAML::Key << "args" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const auto& a : node.args) out << a;
    out << YAML::EndSeq;
    if (!node.env.empty()) {
      out << YAML::Key << "env" << YAML::Value << YAML::BeginMap;
      for (const auto& [key, value] : node.env) out << YAML::Key << key << YAML::Value << value;
      out << YAML::EndMap;
    }
    if (node.ends_launch) out << YAML::Key << "ends_launch" << YAML::Value << YAML::Auto << true;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

std::string shell_quote(const std::string& word) {
  static const std::string kPlain = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_@%+=:,./-";
  if (!word.empty() && word.find_first_not_of(kPlain) == std::string::npos) return word;
  std::string out = "'";
  for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace pmlsm::launch
