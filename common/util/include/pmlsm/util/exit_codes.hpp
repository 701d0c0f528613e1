// Process exit codes, the same for every node and tool, so that the launcher,
// scripts and a rig's supervisor read one table. Where several apply, a node
// ends with the most specific (a lost controller, 4, also leaves the drive safe).
#pragma once

namespace pmlsm {

enum ExitCode : int {
  kExitOk = 0,             ///< the job did what was asked
  kExitError = 1,          ///< runtime failure (DDS, I/O)
  kExitBadConfig = 2,      ///< config, command line or input rejected
  kExitPeerMissing = 3,    ///< a peer never appeared (discovery timeout)
  kExitPeerLost = 4,       ///< a peer stopped answering mid-run
  kExitSafeState = 5,      ///< the drive spent ticks in its safe state or a fault: the run is not valid
  kExitVerdictFailed = 6,  ///< the job ran to its end and what it judged failed (a sweep run unstable or worse than PI)
};

// What `code` means in the table above, for reports that name an exit (the
// launcher's); "unknown exit code" for anything else, so no code reads as "ok" by accident.
inline const char* exit_code_meaning(int code) noexcept {
  switch (code) {
    case kExitOk: return "ok";
    case kExitError: return "error";
    case kExitBadConfig: return "bad config or input";
    case kExitPeerMissing: return "a peer never appeared";
    case kExitPeerLost: return "a peer was lost";
    case kExitSafeState: return "ended in the safe state or a fault (run not valid)";
    case kExitVerdictFailed: return "ran, and what it judged failed its verdict";
    default: return "unknown exit code";
  }
}

}  // namespace pmlsm
