// The configuration reference of a system file, generated from the parameter declarations:
// every entry of the parameter table (visit_parameters in pmlsm/sim/system_params.hpp: key path,
// kind, plausible range and its reason; the unit read from the key's name) with the value and
// the source the file gives it. docs/configuration-reference.md is this page for
// configs/system.yaml, written by `pmlsm config reference`; the ctest `config_reference` fails
// when the page drifts from the declarations or the file.
#pragma once

#include <string>

namespace pmlsm {

/// The unit a parameter's key names by its suffix ("force_limit_n" -> "N", "kp_n_s_per_m" ->
/// "N s/m"); "" when the name carries none (ratios, shares, counts, flags, names).
std::string unit_of_key(const std::string& key_path);

/// The reference as Markdown, one table per section. `origin` names the file on the page.
/// @throws ConfigError as parse_system_params when the file is not a valid system file.
std::string system_parameter_reference(const std::string& yaml_text, const std::string& origin);

/// The same for a CANopen rig file (configs/canopen/drive.yaml; pmlsm/config/canopen_config.hpp):
/// docs/canopen-reference.md, checked by the ctest `canopen_reference`.
/// @throws ConfigError as parse_canopen_config.
std::string canopen_parameter_reference(const std::string& yaml_text, const std::string& origin);
/// The same for an EtherCAT rig file (configs/ethercat/drive.yaml; pmlsm/config/ethercat_config.hpp):
/// docs/ethercat-reference.md, checked by the ctest `ethercat_reference`.
/// @throws ConfigError as parse_ethercat_config.
std::string ethercat_parameter_reference(const std::string& yaml_text, const std::string& origin);

}  // namespace pmlsm
