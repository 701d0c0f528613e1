// The launcher over launch agents (`launcher FILE --agents`): each host's slice goes to the
// agent that announces that host (`pmlsm agent`); their output comes back prefixed with host and
// node. Decisions in pmlsm_agent's LaunchCoordinator (common/agent); DDS here.
#pragma once

#include <chrono>
#include <string>
#include <vector>

#include "launch_file.hpp"
#include "pmlsm/dds/participant.hpp"

namespace pmlsm::launch {

struct RemoteOptions {
  dds::ParticipantOptions dds;
  std::chrono::milliseconds agent_wait{10000};  // every host's agent found within this, or nothing starts
  std::chrono::milliseconds lease{2000};        // an agent (or this launcher) silent this long is gone
  int start_grace_ms = 1000;
  int stop_timeout_ms = 5000;
};

// Runs `nodes` (the enabled nodes of `launch`, every host) through the hosts' agents until every
// slice ended; the launch's exit code (see LaunchCoordinator::exit_code). Handles SIGINT/SIGTERM.
int run_over_agents(const LaunchDescription& launch, const std::vector<NodeSpec>& nodes, const RemoteOptions& options);

}  // namespace pmlsm::launch
