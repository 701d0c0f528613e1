// Helpers for tests that run the launcher as a real process: a scratch folder
// that cleans up every process its node scripts recorded, the launcher process
// with its output captured in files, and deadline-bounded polling.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "launch_file.hpp"

namespace launch_test {

using namespace std::chrono_literals;

/// The message of the LaunchFileError that parsing `text` (as "launch.yaml") throws, or "" if none.
std::string error_of(const std::string& text, const pmlsm::launch::ArgOverrides& overrides = {});

// Polls `condition` every few milliseconds until it holds or `timeout` passes.
bool wait_until(const std::function<bool()>& condition, std::chrono::milliseconds timeout);

// Whether `pid` still has a process-table entry (a zombie counts).
bool process_exists(pid_t pid);

// A fresh folder under $TMPDIR (or /tmp). On destruction it SIGKILLs every process
// named in a *.pid file in it that is still one of its scripts (or a sleep they
// became), then removes the folder, so a failing test leaves nothing behind.
class ScratchDir {
 public:
  ScratchDir();
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  // Writes `text` to `name`; `executable` sets mode 0755.
  std::string write(const std::string& name, const std::string& text, bool executable = false) const;
  bool exists(const std::string& name) const;
  // The PID in `name`.pid, once a script has written it.
  std::optional<pid_t> pid_of(const std::string& name) const;

 private:
  std::filesystem::path path_;
};

// Shell-script nodes. Each writes its PID to NAME.pid (atomically, by rename)
// once it is ready for what the test does next.
namespace script {
// Prints "NAME stopping on SIGINT" and exits `code` on SIGINT; otherwise waits.
std::string waits_for_sigint(const ScratchDir& dir, const std::string& name, int code = 0);
// Ignores SIGINT and sleeps: only SIGKILL ends it.
std::string ignores_sigint(const ScratchDir& dir, const std::string& name);
// Exits on SIGINT through the default action (killed by signal 2).
std::string dies_on_sigint(const ScratchDir& dir, const std::string& name);
// Waits (up to 10 s) for OTHER.pid, then prints "NAME done" and exits `code`.
std::string exits_after(const ScratchDir& dir, const std::string& name, const std::string& other, int code);
}  // namespace script

// The launcher under test, run in `dir` with stdout and stderr in files there.
// `ignored` signals are set to SIG_IGN for it, as a script's `launcher &`
// (SIGINT) or nohup (SIGHUP) do. Destruction SIGKILLs and reaps it if it is
// still running.
class LauncherProcess {
 public:
  LauncherProcess(const ScratchDir& dir, const std::vector<std::string>& args, const std::vector<int>& ignored = {});
  ~LauncherProcess();
  LauncherProcess(const LauncherProcess&) = delete;
  LauncherProcess& operator=(const LauncherProcess&) = delete;

  pid_t pid() const { return pid_; }
  void signal(int sig) const;
  // Waits for the exit; false if `timeout` passed first.
  bool wait_exit(std::chrono::milliseconds timeout = 10s);
  // The exit code, or -signal when killed by a signal. Only after wait_exit().
  int code() const { return code_; }
  std::string out() const;
  std::string err() const;

 private:
  const ScratchDir& dir_;
  pid_t pid_ = -1;
  bool running_ = false;
  int code_ = -1000;
};

// Runs the launcher to completion (10 s at most).
struct RunResult {
  int code;
  std::string out;
  std::string err;
  bool finished;
};
RunResult run_launcher(const ScratchDir& dir, const std::vector<std::string>& args);

std::string read_text(const std::string& path);

}  // namespace launch_test
