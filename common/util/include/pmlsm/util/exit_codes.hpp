// Process exit codes, the same for every node and tool, so that the launcher,
// scripts and a rig's supervisor read one table.
#pragma once

namespace pmlsm {

enum ExitCode : int {
  kExitOk = 0,           ///< the job did what was asked
  kExitError = 1,        ///< runtime failure (DDS, I/O)
  kExitBadConfig = 2,    ///< config, command line or input rejected
  kExitPeerMissing = 3,  ///< a peer never appeared (discovery timeout)
  kExitPeerLost = 4,     ///< a peer stopped answering mid-run
};

}  // namespace pmlsm
