// The meanings the launcher prints for exit codes: one per code of the shared
// table, and never "ok" for a code outside it.
#include "pmlsm/util/exit_codes.hpp"

#include <gtest/gtest.h>

#include <string>

namespace {

TEST(ExitCodeMeaning, NamesEveryCodeOfTheTable) {
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitOk), "ok");
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitError), "error");
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitBadConfig), "bad config or input");
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitPeerMissing), "a peer never appeared");
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitPeerLost), "a peer was lost");
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitSafeState), "ended in the safe state or a fault (run not valid)");
  EXPECT_STREQ(pmlsm::exit_code_meaning(pmlsm::kExitVerdictFailed), "ran, and what it judged failed its verdict");
}

TEST(ExitCodeMeaning, CodesOutsideTheTableAreUnknown) {
  for (int code : {-1, 7, 99, 127, 130, 255}) EXPECT_STREQ(pmlsm::exit_code_meaning(code), "unknown exit code") << code;
}

}  // namespace
