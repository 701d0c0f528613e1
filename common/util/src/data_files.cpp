#include "pmlsm/util/data_files.hpp"

#include <cstdlib>
#include <filesystem>

namespace pmlsm {

namespace fs = std::filesystem;

std::string program_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}

std::string installed_data_dir() {
  const std::string bin = program_dir();
  if (bin.empty()) return "";
  std::error_code ec;
  const fs::path dir = fs::path(bin).parent_path() / "share" / "pmlsm";
  return fs::is_directory(dir, ec) ? dir.string() : "";
}

std::string data_file(const std::string& relative) {
  std::error_code ec;
  if (const char* env = std::getenv(kDataDirEnv); env != nullptr && *env != '\0') {
    const fs::path p = fs::path(env) / relative;
    if (fs::exists(p, ec)) return p.string();
  }
  if (const std::string dir = installed_data_dir(); !dir.empty()) {
    const fs::path p = fs::path(dir) / relative;
    if (fs::exists(p, ec)) return p.string();
  }
#ifdef PMLSM_SOURCE_TREE
  if (const fs::path p = fs::path(PMLSM_SOURCE_TREE) / relative; fs::exists(p, ec)) return p.string();
#endif
  return relative;
}

}  // namespace pmlsm
