// The training programs' command lines (de_trainer, de_worker), apart from the components so that
// only the parsers include CLI11 (see nodes/support/CMakeLists.txt: the nodes' parsers are
// compiled together in pmlsm_node_support). Each parses into options whose values are the
// defaults shown, and returns an exit code to end with (help: 0, bad options: 2), or nothing
// when the program should go on.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "node_support.hpp"
#include "pmlsm/util/data_files.hpp"

namespace pmlsm::node {

struct TrainerOptions {
  dds::ParticipantOptions dds;
  std::string config_path = pmlsm::data_file("configs/system.yaml");
  std::string training_path = pmlsm::data_file("configs/training.yaml");
  std::vector<std::string> overrides, training_overrides;
  std::string out_path = "out/rnn_weights.yaml";
  std::string checkpoint_path;  // default: <out>.checkpoint
  std::string history_path;     // default: <out>.history.csv
  bool resume = false;
  bool no_progress = false;
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  std::size_t wait_workers = 0;
  double wait_workers_s = 10.0;
  double worker_timeout_s = 1.5;
  std::uint64_t first_version = 1;
  double linger_s = 0;
  /// NetworkWeights readers to wait for at the end (0: none).
  std::size_t weights_readers = 0;
};

/// This host's name and this process's id: unique on the domain.
std::string default_worker_id();

struct WorkerOptions {
  dds::ParticipantOptions dds;
  unsigned threads = 1;
  std::string worker_id = default_worker_id();
  double idle_exit_s = 0;
};

std::optional<int> parse_de_trainer_command_line(int argc, char** argv, TrainerOptions& opt);
std::optional<int> parse_de_worker_command_line(int argc, char** argv, WorkerOptions& opt);

}  // namespace pmlsm::node
