// Launch files (parse_launch) with --arg overrides: lines "#arg key=value" (YAML comments, so the
// file stays a launch file) are passed as overrides through parse_arg_override. A valid
// description is then sliced per host and its arguments shell-quoted, as `launcher --dry-run` does.
#include "fuzz_support.hpp"
#include "launch_file.hpp"

namespace pmlsm::fuzz::launch_file {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  const std::string text = as_text(data, size);
  launch::ArgOverrides overrides;
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    if (text.compare(begin, 5, "#arg ") == 0) {
      try {
        overrides.insert(launch::parse_arg_override(text.substr(begin + 5, end - begin - 5)));
      } catch (const launch::LaunchFileError&) {
      }
    }
    begin = end + 1;
  }
  try {
    const launch::LaunchDescription description = launch::parse_launch(text, "fuzz/launch.yaml", overrides);
    for (const launch::NodeSpec& node : launch::select_nodes(description, std::nullopt)) {
      for (const std::string& arg : node.args) launch::shell_quote(arg);
    }
    for (const std::string& host : description.hosts) launch::select_nodes(description, host);
    launch::select_nodes(description, std::string("no-such-host"));
  } catch (const launch::LaunchFileError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::launch_file
