#include "fuzz_support.hpp"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace pmlsm::fuzz {

std::string source_path(const std::string& relative_path) {
  return std::string(PMLSM_SOURCE_DIR) + "/" + relative_path;
}

std::string source_file(const std::string& relative_path) {
  const std::string path = source_path(relative_path);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "fuzz: cannot read %s (a fixed input of the target)\n", path.c_str());
    std::abort();
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace pmlsm::fuzz
