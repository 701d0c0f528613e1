// The subcommands of `pmlsm` and what they share. Each run_* returns the process exit code:
// 0 done, 1 runtime failure (DDS, I/O), 2 bad command line or input (unknown topic, bad file).
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"
#include "pmlsm/mcap/mcap.hpp"
#include "pmlsm/dds/participant.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace pmlsm::tools {

/// A bad command line or input: the message is printed and the exit code is 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The catalog entries for topic names as users write them ("/pmlsm/x", "rt/pmlsm/x",
/// "pmlsm/x"); all of them when `names` is empty. @throws UsageError naming an unknown topic
/// and listing the known ones.
std::vector<const dds::CatalogEntry*> select_topics(const std::vector<std::string>& names);

/// The project topic a recorded channel carries, or nullptr with `why`: a channel in cdr whose
/// schema is ours for its topic, in either profile (dds::recorded_entry). With `decoder`, also
/// how to decode it: an omgidl schema as recorded (a recording of an older build still decodes),
/// a ros2msg one by this build's IDL, which its definition was checked to equal.
const dds::CatalogEntry* recorded_channel(const mcap::Channel& channel, const mcap::Schema* schema,
                                          std::optional<introspect::MessageSchema>* decoder, std::string& why);

/// A printable key of a DDS writer (its GUID), for per-writer accounting.
std::string writer_key(const eprosima::fastdds::dds::SampleInfo& info);

/// Time_t -> ns since the epoch.
std::int64_t to_ns(const eprosima::fastrtps::rtps::Time_t& t);

/// `options` with node_name set to `name` and the security identity to `identity` (one per
/// command group: pmlsm_topic, pmlsm_record, pmlsm_play, pmlsm_drive, pmlsm_setpoint), unless the user gave them.
dds::ParticipantOptions with_node_name(dds::ParticipantOptions options, const std::string& name,
                                       const std::string& identity);

/// "user@host" of who runs the command (requests name their requester), else "pmlsm".
std::string user_at_host();

/// Checked before a measurement or a long run: the folder that will hold `file` (given by
/// `option`) exists. @throws UsageError "<option> <file>: no folder <folder> to write it in".
void require_output_folder(const std::string& option, const std::string& file);
/// Made before a long run: the folder `option` names (and its parents).
/// @throws UsageError "<option> <folder>: cannot be made: <why>".
void make_output_folder(const std::string& option, const std::string& folder);

// Each registers its subcommand(s); the callback runs the command and stores its exit code.
// Option storage lives in the callbacks (shared), so it outlives parsing.
void add_topic_commands(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);
void add_record_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);
void add_play_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);
void add_plot_command(CLI::App& app, int& exit_code);
/// `pmlsm drive status|enable|disable|quick-stop|fault-reset|shutdown|switch-on` (drive.cpp).
void add_drive_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);
/// `pmlsm setpoint VALUE [--ramp-mps2 A] [--hold-s S]`: a live velocity setpoint (setpoint.cpp).
void add_setpoint_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);
/// `pmlsm security create|create-identity|update-permissions|check|list` (security.cpp).
void add_security_command(CLI::App& app, int& exit_code);
/// `pmlsm sweep FILE`: the robustness sweep, in process (sweep.cpp).
void add_sweep_command(CLI::App& app, int& exit_code);

/// `pmlsm identify [RECORDING] | --simulate`: the commissioning identification (identify.cpp).
void add_identify_command(CLI::App& app, int& exit_code);
/// `pmlsm param list|get|set NODE ...`: a running node's live parameters (param.cpp).
void add_param_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);
/// `pmlsm commission --simulate`: frequency response, two-mass fit, Bode plot (commission.cpp).
void add_commission_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code);

/// `pmlsm config reference|check`: the generated configuration reference, the file's checks (config_command.cpp).
void add_config_command(CLI::App& app, int& exit_code);
/// `pmlsm ethercat scan|state|sdo|serve` (ethercat.cpp).
void add_ethercat_command(CLI::App& app, int& exit_code);

}  // namespace pmlsm::tools
