// Where a program finds its shipped files (pmlsm/util/data_files.hpp): a program of the build tree
// finds them from any folder; $PMLSM_DATA_DIR comes first; a file that is nowhere is named as given.
#include "pmlsm/util/data_files.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace pmlsm {
namespace {

namespace fs = std::filesystem;

/// The current folder moved to `dir` for a scope, and back.
class InFolder {
 public:
  explicit InFolder(const fs::path& dir) : before_(fs::current_path()) { fs::current_path(dir); }
  ~InFolder() { fs::current_path(before_); }
  InFolder(const InFolder&) = delete;
  InFolder& operator=(const InFolder&) = delete;

 private:
  fs::path before_;
};

TEST(DataFiles, AProgramOfTheBuildTreeFindsTheShippedFilesFromAnyFolder) {
  const fs::path elsewhere = fs::temp_directory_path() / ("pmlsm_data_files_" + std::to_string(getpid()));
  fs::create_directories(elsewhere / "configs");
  {
    const InFolder in(elsewhere);
    ASSERT_EQ(::unsetenv(kDataDirEnv), 0);
    const std::string found = data_file("configs/scenarios/identification.yaml");
    EXPECT_TRUE(fs::path(found).is_absolute()) << found;
    EXPECT_TRUE(fs::exists(found)) << found;
    EXPECT_EQ(data_file("configs/no_such_file.yaml"), "configs/no_such_file.yaml");
    // $PMLSM_DATA_DIR first.
    std::ofstream(elsewhere / "configs" / "system.yaml") << "# mine\n";
    ASSERT_EQ(::setenv(kDataDirEnv, elsewhere.c_str(), 1), 0);
    EXPECT_EQ(data_file("configs/system.yaml"), (elsewhere / "configs" / "system.yaml").string());
    EXPECT_NE(data_file("configs/training.yaml"), "configs/training.yaml");  // not there: the tree's
    ASSERT_EQ(::unsetenv(kDataDirEnv), 0);
  }
  fs::remove_all(elsewhere);
}

}  // namespace
}  // namespace pmlsm
