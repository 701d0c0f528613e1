// fuzz_regressions TARGET PATH...: feeds every file under each PATH (a directory, walked
// recursively in name order, or a file) to TARGET's fuzz_one, as libFuzzer would, so that the
// seed corpora and the inputs of every crash found (fuzz/regressions/<target>/) run in the normal
// build too. A crash or sanitizer report fails it; so does finding no input at all.
// `fuzz_regressions --list` prints the targets.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace pmlsm::fuzz {
#define PMLSM_FUZZ_TARGET(name)                             \
  namespace name {                                          \
  int fuzz_one(const std::uint8_t* data, std::size_t size); \
  }
#include "fuzz_targets.inc"
#undef PMLSM_FUZZ_TARGET
}  // namespace pmlsm::fuzz

namespace {

struct Target {
  const char* name;
  int (*fuzz_one)(const std::uint8_t*, std::size_t);
};

const Target kTargets[] = {
#define PMLSM_FUZZ_TARGET(name) {#name, &pmlsm::fuzz::name::fuzz_one},
#include "fuzz_targets.inc"
#undef PMLSM_FUZZ_TARGET
};

std::vector<std::filesystem::path> inputs_under(const std::filesystem::path& path) {
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_regular_file(path)) {
    files.push_back(path);
  } else if (std::filesystem::is_directory(path)) {
    for (const auto& entry : std::filesystem::recursive_directory_iterator(path)) {
      if (entry.is_regular_file()) files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 2 && std::strcmp(argv[1], "--list") == 0) {
    for (const Target& target : kTargets) std::printf("%s\n", target.name);
    return 0;
  }
  if (argc < 3) {
    std::fprintf(stderr, "usage: fuzz_regressions TARGET PATH... | --list\n");
    return 2;
  }
  const Target* target = nullptr;
  for (const Target& t : kTargets) {
    if (std::strcmp(t.name, argv[1]) == 0) target = &t;
  }
  if (target == nullptr) {
    std::fprintf(stderr, "fuzz_regressions: unknown target '%s' (--list names them)\n", argv[1]);
    return 2;
  }
  std::size_t count = 0;
  for (int i = 2; i < argc; ++i) {
    for (const std::filesystem::path& file : inputs_under(argv[i])) {
      std::ifstream in(file, std::ios::binary);
      const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (!in.good() && !in.eof()) {
        std::fprintf(stderr, "fuzz_regressions: cannot read %s\n", file.c_str());
        return 1;
      }
      std::printf("%s: %s (%zu bytes)\n", target->name, file.c_str(), bytes.size());
      std::fflush(stdout);  // the last line names the input when one crashes
      const int result = target->fuzz_one(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
      if (result != 0) {
        std::fprintf(stderr, "fuzz_regressions: %s returned %d for %s\n", target->name, result, file.c_str());
        return 1;
      }
      ++count;
    }
  }
  if (count == 0) {
    std::fprintf(stderr, "fuzz_regressions: no input found for %s\n", target->name);
    return 1;
  }
  std::printf("%s: %zu inputs, no crash\n", target->name, count);
  return 0;
}
