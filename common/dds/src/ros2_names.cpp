#include "pmlsm/dds/ros2_names.hpp"

#include <stdexcept>

namespace pmlsm::dds {
namespace {

bool is_lower(char c) { return c >= 'a' && c <= 'z'; }
bool is_upper(char c) { return c >= 'A' && c <= 'Z'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

[[noreturn]] void refuse(std::string_view name, const std::string& rule) {
  throw std::invalid_argument("type name '" + std::string(name) + "': " + rule);
}

// REP 144: a package name starts with a letter, then lower case letters, digits and single
// underscores, and does not end with one.
void check_package(std::string_view name, const std::string& package) {
  if (package.empty() || !is_lower(package.front()) || package.back() == '_') {
    refuse(name, "the package '" + package + "' must start with a lower case letter and not end with '_'");
  }
  for (std::size_t i = 0; i < package.size(); ++i) {
    const char c = package[i];
    if (!is_lower(c) && !is_digit(c) && c != '_') {
      refuse(name, "the package '" + package + "' may hold lower case letters, digits and '_' only");
    }
    if (c == '_' && package[i - 1] == '_') refuse(name, "the package '" + package + "' has a double '_'");
  }
}

// rosidl: a message name is upper camel case, letters and digits, starting with a capital.
void check_type(std::string_view name, const std::string& type) {
  if (type.empty() || !is_upper(type.front())) {
    refuse(name, "the message '" + type + "' must start with a capital letter");
  }
  for (char c : type) {
    if (!is_lower(c) && !is_upper(c) && !is_digit(c)) {
      refuse(name, "the message '" + type + "' may hold letters and digits only");
    }
  }
}

}  // namespace

InterfaceName interface_name(std::string_view idl_type_name) {
  const auto first = idl_type_name.find("::");
  const auto second = first == std::string_view::npos ? first : idl_type_name.find("::", first + 2);
  if (second == std::string_view::npos || idl_type_name.find("::", second + 2) != std::string_view::npos) {
    refuse(idl_type_name, "expected <package>::msg::<Type>");
  }
  InterfaceName out{std::string(idl_type_name.substr(0, first)),
                    std::string(idl_type_name.substr(first + 2, second - first - 2)),
                    std::string(idl_type_name.substr(second + 2))};
  if (out.kind != "msg") refuse(idl_type_name, "expected the module 'msg', got '" + out.kind + "'");
  check_package(idl_type_name, out.package);
  check_type(idl_type_name, out.type);
  return out;
}

std::string ros2_type_name(std::string_view idl_type_name) {
  const InterfaceName n = interface_name(idl_type_name);
  return n.package + "::" + n.kind + "::dds_::" + n.type + "_";
}

std::string ros2_interface_path(std::string_view idl_type_name) {
  const InterfaceName n = interface_name(idl_type_name);
  return n.package + "/" + n.kind + "/" + n.type;
}

}  // namespace pmlsm::dds
