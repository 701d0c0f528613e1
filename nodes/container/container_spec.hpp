// A container's command line, split into the container's own options and its components:
//   container [container options] --component NAME TYPE [ARGS...] [--component NAME TYPE [ARGS...]]...
// Each component's ARGS are its node's command line, as its executable takes them. No DDS here.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace pmlsm::container {

/// A malformed container command line; the message names the component and what is wrong.
class ContainerSpecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr const char* kComponentFlag = "--component";

struct ComponentSpec {
  std::string name;  ///< unique in the container, [A-Za-z0-9_-]+ (a launch file's node name)
  std::string type;  ///< the node it runs (plant_sim, controller, ...)
  std::vector<std::string> args;
};

struct ContainerCommandLine {
  std::vector<std::string> own_args;  ///< before the first --component
  std::vector<ComponentSpec> components;
};

/// Splits `args` (argv without the program name). `known_types` lists the component types the
/// container can make. @throws ContainerSpecError for no component, a missing name or type, a
/// name used twice or not [A-Za-z0-9_-]+, or an unknown type (the known ones listed).
ContainerCommandLine split_container_command_line(const std::vector<std::string>& args,
                                                  const std::vector<std::string>& known_types);

/// The command line that runs `components` in one container with `own_args`, inverse of
/// split_container_command_line (the launcher builds it).
std::vector<std::string> container_command_line(const std::vector<std::string>& own_args,
                                                const std::vector<ComponentSpec>& components);

}  // namespace pmlsm::container
