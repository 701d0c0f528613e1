// Process supervision for the launcher: starts each node in its own process
// group, relays its output line by line with a "[name] " prefix, forwards a
// stop request (SIGINT, then SIGKILL after a timeout) and reports every exit.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace pmlsm::launch {

struct ProcessSpec {
  std::string name;
  std::string path;                                      // what execve runs
  std::vector<std::string> argv;                         // argv[0] first
  std::vector<std::pair<std::string, std::string>> env;  // set on top of the launcher's own
  bool ends_launch = false;                              // its exit stops the others
};

struct SupervisorOptions {
  // A node failing within this time of its start fails the launch; 0 turns the check off.
  std::chrono::milliseconds start_grace{1000};
  // Time between the SIGINT of a stop and the SIGKILL.
  std::chrono::milliseconds stop_timeout{5000};
  int out_fd = STDOUT_FILENO;  // nodes' stdout lines
  int err_fd = STDERR_FILENO;  // nodes' stderr lines and the launcher's own messages
};

// Cuts a byte stream into lines and passes each on as "PREFIXline\n" in one
// piece, so lines from several nodes never mix. A line longer than max_line is
// passed on in max_line pieces, to bound the memory a runaway node can take.
class LineRelay {
 public:
  using Sink = std::function<void(const std::string&)>;
  LineRelay(std::string prefix, Sink sink, std::size_t max_line = 64 * 1024);
  void feed(const char* data, std::size_t size);
  // Passes on a last line that has no '\n' (call at end of stream).
  void finish();

 private:
  void emit(const char* data, std::size_t size);
  std::string prefix_;
  Sink sink_;
  std::size_t max_line_;
  std::string partial_;
};

// Starts `processes` in order and supervises them until all have exited.
// Stops them all (SIGINT; SIGKILL after options.stop_timeout) when the launcher
// gets SIGINT, SIGTERM or SIGHUP (unless SIGHUP is ignored, as under nohup; a
// second signal sends SIGKILL at once), when a node with ends_launch exits, or
// when a node fails to start or dies within options.start_grace. Takes over
// SIGCHLD and reaps every child: call it from a single-threaded process.
// Reports every exit with the meaning of its code (pmlsm/util/exit_codes.hpp) and
// ends with a summary that lists each node that did not end cleanly.
// A node ends cleanly when it exits with code 0, or, stopped by the launcher, dies
// from that SIGINT. Returns 0 only when every node ended cleanly; otherwise the
// code of the first failure seen, so a script learns why the run failed: the
// node's own exit code (2 bad config, 4 peer lost, 5 run not valid, ...), or 1 for
// a node killed by a signal other than the stop's SIGINT (a SIGKILL the stop
// needed included), a node that could not be started, or the launcher's own failure.
int supervise(const std::vector<ProcessSpec>& processes, const SupervisorOptions& options);

}  // namespace pmlsm::launch
