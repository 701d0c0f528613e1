// ros2_package: the ROS 2 interface package of our messages, made from idl/ by the build, so a
// ROS 2 user installs (colcon build) the very definitions the wire carries:
//
//   ros2_package --idl-dir DIR --names Stamp,DriveState,... --version V --out DIR
//
// writes DIR/package.xml, DIR/CMakeLists.txt (rosidl_generate_interfaces) and DIR/msg/<Name>.msg,
// one per struct of the IDL files (pmlsm/introspect/ros2_msg.hpp), replacing what was there.
// Exit 0 written, 1 an IDL a .msg cannot express or a file not written, 2 bad command line.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "pmlsm/introspect/ros2_msg.hpp"

namespace {

namespace fs = std::filesystem;

constexpr const char* kPackage = "pmlsm_msgs";

struct Options {
  std::string idl_dir;
  std::vector<std::string> names;  ///< Stamp first: every message includes it
  std::string version;
  std::string out_dir;
};

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// The IDL without its preprocessor lines: the files include Stamp.idl, which is read first.
std::string without_includes(const std::string& idl) {
  std::istringstream lines(idl);
  std::string out;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind('#', 0) != 0) out += line + "\n";
  }
  return out;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out.flush()) throw std::runtime_error(path.string() + ": cannot write");
}

std::string package_xml(const std::string& version) {
  return std::string(R"(<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" schematypens="http://www.w3.org/2001/XMLSchema"?>
<!-- Generated from idl/ by the pmlsm build (tools/ros2_package); edit the IDL, not this file. -->
<package format="3">
  <name>)") +
         kPackage + R"(</name>
  <version>)" +
         version + R"(</version>
  <description>The messages of the PMLSM vibration control system (drive feedback, force commands,
    estimates, compensation, power states, training), as its DDS topics carry them.</description>
  <maintainer email="pmlsm@localhost">PMLSM vibration control</maintainer>
  <license>Proprietary</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
)";
}

std::string cmake_lists(const std::vector<std::string>& messages) {
  std::string text = std::string(
                         "# Generated from idl/ by the pmlsm build (tools/ros2_package); edit the IDL, not this "
                         "file.\ncmake_minimum_required(VERSION 3.8)\nproject(") +
                     kPackage +
                     ")\n\nfind_package(ament_cmake REQUIRED)\nfind_package(rosidl_default_generators REQUIRED)\n\n"
                     "rosidl_generate_interfaces(${PROJECT_NAME}\n";
  for (const std::string& name : messages) text += "  \"msg/" + name + ".msg\"\n";
  text += ")\n\nament_export_dependencies(rosidl_default_runtime)\nament_package()\n";
  return text;
}

// Every struct once, each with the IDL file that defines it.
void write_package(const Options& opt) {
  const std::string stamp = without_includes(read_text(fs::path(opt.idl_dir) / (opt.names.front() + ".idl")));
  std::map<std::string, std::string> origin_of;  // message -> IDL file
  std::vector<pmlsm::introspect::Ros2MessageFile> files;
  for (const std::string& name : opt.names) {
    const std::string file = name + ".idl";
    const std::string own = without_includes(read_text(fs::path(opt.idl_dir) / file));
    const std::string idl = name == opt.names.front() ? own : stamp + own;
    for (auto& message : pmlsm::introspect::ros2_message_files(idl, kPackage)) {
      if (origin_of.emplace(message.name, file).second) files.push_back(std::move(message));
    }
  }
  const fs::path out(opt.out_dir);
  fs::remove_all(out / "msg");
  fs::create_directories(out / "msg");
  std::vector<std::string> messages;
  for (const auto& message : files) {
    write_text(out / "msg" / (message.name + ".msg"),
               "# " + std::string(kPackage) + "/msg/" + message.name + ", generated from idl/" +
                   origin_of.at(message.name) + " (the meaning and unit of each field are there).\n" + message.text);
    messages.push_back(message.name);
  }
  write_text(out / "package.xml", package_xml(opt.version));
  write_text(out / "CMakeLists.txt", cmake_lists(messages));
  std::printf("ros2_package: %s %s, %zu messages in %s\n", kPackage, opt.version.c_str(), messages.size(),
              out.string().c_str());
}

std::vector<std::string> split_names(const std::string& text) {
  std::vector<std::string> names;
  std::istringstream parts(text);
  for (std::string name; std::getline(parts, name, ',');) {
    if (!name.empty()) names.push_back(name);
  }
  return names;
}

// An error message, or "" when the command line is complete.
std::string parse(int argc, char** argv, Options& opt) {
  for (int i = 1; i < argc; i += 2) {
    const std::string arg = argv[i];
    if (i + 1 >= argc) return arg + " needs a value";
    const std::string value = argv[i + 1];
    if (arg == "--idl-dir") {
      opt.idl_dir = value;
    } else if (arg == "--names") {
      opt.names = split_names(value);
    } else if (arg == "--version") {
      opt.version = value;
    } else if (arg == "--out") {
      opt.out_dir = value;
    } else {
      return "unknown option '" + arg + "'";
    }
  }
  if (opt.idl_dir.empty() || opt.names.empty() || opt.version.empty() || opt.out_dir.empty()) {
    return "usage: ros2_package --idl-dir DIR --names Stamp,... --version V --out DIR";
  }
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  if (const std::string error = parse(argc, argv, opt); !error.empty()) {
    std::fprintf(stderr, "ros2_package: %s\n", error.c_str());
    return 2;
  }
  try {
    write_package(opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ros2_package: %s\n", e.what());
    return 1;
  }
  return 0;
}
