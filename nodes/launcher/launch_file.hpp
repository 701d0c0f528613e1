// Launch descriptions: the YAML format read by the launcher, its strict
// validation, $(arg NAME) substitution, host slicing and executable lookup.
// No process handling here, so all of it is unit-testable.
#pragma once

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace pmlsm::launch {

// A launch file that is unreadable, malformed or inconsistent, or a bad
// --host / --arg against it. The message names the file, the key path and the value.
class LaunchFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// An executable that is not where the launch file says it is.
class ExecutableNotFound : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct NodeSpec {
  std::string name;        // unique, [A-Za-z0-9_-]+
  std::string executable;  // as written, after substitution
  std::string host;
  std::vector<std::string> args;                         // after substitution
  std::vector<std::pair<std::string, std::string>> env;  // in file order, after substitution
  bool ends_launch = false;
  bool enabled = true;  // its `if` held (or it had none)
  /// A container: the nodes it runs as components, in file order (empty for a plain node).
  std::vector<std::string> components;
};

struct LaunchDescription {
  std::string source;  // the file, for messages
  std::string name;
  std::vector<std::string> hosts;           // never empty; default {"local"}
  std::vector<NodeSpec> nodes;              // never empty, in file order; the enabled ones
  std::vector<std::string> left_out;        // names of the nodes (and containers) whose `if` was false
  std::map<std::string, std::string> args;  // defaults with the overrides applied
};

using ArgOverrides = std::map<std::string, std::string>;

// Parses and validates a launch description held in `text`; `source` names it in
// messages. Overrides replace declared arg defaults; an undeclared one is an error.
// An enabled entry of `containers:` (name, components, optional host, args, if) replaces its
// components in `nodes` by one node that runs the `container` executable with them, at the
// place of its first component; its args are the container's own options.
// @throws LaunchFileError
LaunchDescription parse_launch(const std::string& text, const std::string& source, const ArgOverrides& overrides = {});

// Reads `path` and parses it as above.
// @throws LaunchFileError
LaunchDescription load_launch_file(const std::string& path, const ArgOverrides& overrides = {});

// Splits "key=value" as given to --arg.
// @throws LaunchFileError when there is no '=' or the key is empty
std::pair<std::string, std::string> parse_arg_override(const std::string& text);

// Replaces every $(arg NAME) in `text` with args[NAME]; `where` names the
// value in messages.
// @throws LaunchFileError for an unknown NAME or a malformed $( ... )
std::string substitute_args(const std::string& text, const std::map<std::string, std::string>& args,
                            const std::string& where);

// The nodes that run on `host` (all of them without a host), in file order.
// @throws LaunchFileError for a host not in the description, listing the known ones
std::vector<NodeSpec> select_nodes(const LaunchDescription& launch, const std::optional<std::string>& host);

// The program to exec for `executable`: a name is looked up in bin_dir, then in
// each PATH entry (path_env is PATH's value); a name containing '/' is used as
// given (relative to the current directory). Only executable regular files count.
// @throws ExecutableNotFound saying where it looked
std::string resolve_executable(const std::string& executable, const std::string& bin_dir, const std::string& path_env);

// A node's `if` after substitution: "true", "false", "A == B" or "A != B" (texts compared
// after trimming blanks). @throws LaunchFileError naming `where` for anything else.
bool evaluate_condition(const std::string& text, const std::string& where);

// A launch description holding only `nodes` (already substituted and selected), all on
// `host`: what a launcher sends to that host's agent. parse_launch() reads it back to the same
// nodes (an arg value holding "$(" would be substituted again there and is refused).
std::string slice_yaml(const std::string& name, const std::string& host, const std::vector<NodeSpec>& nodes);

// Quotes `word` for a POSIX shell when needed, so dry-run output can be pasted.
std::string shell_quote(const std::string& word);

}  // namespace pmlsm::launch
