#include "container_spec.hpp"

#include <algorithm>

namespace pmlsm::container {

namespace {

bool valid_name(const std::string& name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

std::string joined(const std::vector<std::string>& words) {
  std::string out;
  for (const auto& w : words) out += (out.empty() ? "" : ", ") + w;
  return out;
}

}  // namespace

ContainerCommandLine split_container_command_line(const std::vector<std::string>& args,
                                                  const std::vector<std::string>& known_types) {
  ContainerCommandLine out;
  std::size_t i = 0;
  for (; i < args.size() && args[i] != kComponentFlag; ++i) out.own_args.push_back(args[i]);
  while (i < args.size()) {
    ++i;  // --component
    if (i + 1 >= args.size() || args[i] == kComponentFlag || args[i + 1] == kComponentFlag) {
      throw ContainerSpecError(std::string(kComponentFlag) + " #" + std::to_string(out.components.size() + 1) +
                               ": needs a NAME and a TYPE");
    }
    ComponentSpec spec;
    spec.name = args[i++];
    spec.type = args[i++];
    for (; i < args.size() && args[i] != kComponentFlag; ++i) spec.args.push_back(args[i]);
    if (!valid_name(spec.name)) {
      throw ContainerSpecError("component name '" + spec.name + "': must be [A-Za-z0-9_-]+");
    }
    for (const auto& other : out.components) {
      if (other.name == spec.name) {
        throw ContainerSpecError("component name '" + spec.name + "' is used twice (" + other.type + " and " +
                                 spec.type + "): every component of a container needs its own");
      }
    }
    if (std::find(known_types.begin(), known_types.end(), spec.type) == known_types.end()) {
      throw ContainerSpecError("component '" + spec.name + "': unknown type '" + spec.type +
                               "' (a container runs: " + joined(known_types) + ")");
    }
    out.components.push_back(std::move(spec));
  }
  if (out.components.empty()) {
    throw ContainerSpecError(std::string("no component: give at least one ") + kComponentFlag + " NAME TYPE [ARGS...]");
  }
  return out;
}

std::vector<std::string> container_command_line(const std::vector<std::string>& own_args,
                                                const std::vector<ComponentSpec>& components) {
  std::vector<std::string> out = own_args;
  for (const auto& c : components) {
    out.push_back(kComponentFlag);
    out.push_back(c.name);
    out.push_back(c.type);
    out.insert(out.end(), c.args.begin(), c.args.end());
  }
  return out;
}

}  // namespace pmlsm::container
