// Where programs find their shipped files (configs/, launch/) when no option names them, so an
// installed program runs anywhere and a built one from the source tree:
//   1. an explicit option (the caller's: this is only the default)
//   2. $PMLSM_DATA_DIR/<relative>
//   3. <the program's folder>/../share/pmlsm/<relative> (cmake --install, the .deb: /usr/bin -> /usr/share/pmlsm)
//   4. <the source tree the program was built from>/<relative> (a program run from its build tree,
//      from any folder)
//   5. <relative> itself, from the current folder
// The first that exists wins; when none does, <relative> (the error then names it).
#pragma once

#include <string>

namespace pmlsm {

/// The environment variable of step 2.
inline constexpr const char* kDataDirEnv = "PMLSM_DATA_DIR";

/// The folder of the running program ("" when /proc/self/exe cannot be read): the launcher
/// and the agent find the nodes beside themselves.
std::string program_dir();

/// The installed data folder of this program (<its folder>/../share/pmlsm), or "" when there is none.
std::string installed_data_dir();

/// `relative` (e.g. "configs/system.yaml") found by the order above.
std::string data_file(const std::string& relative);

}  // namespace pmlsm
