#include "launch_test_support.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#ifndef LAUNCHER_PATH
#error "LAUNCHER_PATH must name the launcher under test"
#endif

namespace launch_test {

std::string error_of(const std::string& text, const pmlsm::launch::ArgOverrides& overrides) {
  try {
    pmlsm::launch::parse_launch(text, "launch.yaml", overrides);
  } catch (const pmlsm::launch::LaunchFileError& e) {
    return e.what();
  }
  return "";
}

bool wait_until(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (condition()) return true;
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
}

bool process_exists(pid_t pid) { return pid > 0 && std::filesystem::exists("/proc/" + std::to_string(pid)); }

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

ScratchDir::ScratchDir() {
  const char* tmp = std::getenv("TMPDIR");
  std::string templ = std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/launch_test.XXXXXX";
  if (::mkdtemp(templ.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + templ);
  path_ = templ;
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(path_, ec)) {
    if (entry.path().extension() != ".pid") continue;
    const pid_t pid = static_cast<pid_t>(std::atol(read_text(entry.path().string()).c_str()));
    // Only a process that is still ours: a PID may have been reused since.
    const std::string cmdline = read_text("/proc/" + std::to_string(pid) + "/cmdline");
    const bool ours = cmdline.find(path_.string()) != std::string::npos || cmdline.rfind("sleep", 0) == 0;
    if (pid > 0 && ours) ::kill(pid, SIGKILL);
  }
  std::filesystem::remove_all(path_, ec);
}

std::string ScratchDir::write(const std::string& name, const std::string& text, bool executable) const {
  const std::string path = file(name);
  std::ofstream(path) << text;
  if (executable) ::chmod(path.c_str(), 0755);
  return path;
}

bool ScratchDir::exists(const std::string& name) const { return std::filesystem::exists(path_ / name); }

std::optional<pid_t> ScratchDir::pid_of(const std::string& name) const {
  const std::string text = read_text(file(name + ".pid"));
  if (text.empty()) return std::nullopt;
  return static_cast<pid_t>(std::atol(text.c_str()));
}

namespace script {
namespace {

std::string publish_pid(const ScratchDir& dir, const std::string& name) {
  const std::string pid_file = dir.file(name + ".pid");
  return "echo $$ > '" + pid_file + ".tmp' && mv '" + pid_file + ".tmp' '" + pid_file + "'\n";
}

}  // namespace

std::string waits_for_sigint(const ScratchDir& dir, const std::string& name, int code) {
  // Short foreground sleeps rather than one long one: the trap runs once the
  // current sleep is over, and nothing outlives the script by more than 50 ms.
  return "#!/bin/sh\n"
         "trap 'echo \"" +
         name + " stopping on SIGINT\"; exit " + std::to_string(code) + "' INT\n" + publish_pid(dir, name) +
         "while :; do sleep 0.05; done\n";
}

std::string ignores_sigint(const ScratchDir& dir, const std::string& name) {
  return "#!/bin/sh\ntrap '' INT\n" + publish_pid(dir, name) + "exec sleep 30\n";
}

std::string dies_on_sigint(const ScratchDir& dir, const std::string& name) {
  return "#!/bin/sh\n" + publish_pid(dir, name) + "exec sleep 30\n";
}

std::string exits_after(const ScratchDir& dir, const std::string& name, const std::string& other, int code) {
  return "#!/bin/sh\n" + publish_pid(dir, name) +
         "i=0\n"
         "while [ ! -f '" +
         dir.file(other + ".pid") +
         "' ]; do\n"
         "  i=$((i + 1)); [ $i -gt 1000 ] && exit 99\n"
         "  sleep 0.01\n"
         "done\n"
         "echo \"" +
         name +
         " done\"\n"
         "exit " +
         std::to_string(code) + "\n";
}

}  // namespace script

LauncherProcess::LauncherProcess(const ScratchDir& dir, const std::vector<std::string>& args,
                                 const std::vector<int>& ignored)
    : dir_(dir) {
  std::vector<std::string> argv_store{LAUNCHER_PATH};
  argv_store.insert(argv_store.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_store) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string out_path = dir.file("launcher.out");
  const std::string err_path = dir.file("launcher.err");
  const std::string work_dir = dir.path().string();

  pid_ = ::fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int in = ::open("/dev/null", O_RDONLY);
    if (out < 0 || err < 0 || in < 0 || ::chdir(work_dir.c_str()) != 0) ::_exit(126);
    ::dup2(in, 0);
    ::dup2(out, 1);
    ::dup2(err, 2);
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGCHLD, SIGPIPE}) ::sigaction(sig, &dfl, nullptr);
    for (int sig : ignored) ::signal(sig, SIG_IGN);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  running_ = true;
}

LauncherProcess::~LauncherProcess() {
  if (!running_) return;
  ::kill(pid_, SIGKILL);
  int status = 0;
  ::waitpid(pid_, &status, 0);
}

void LauncherProcess::signal(int sig) const {
  if (running_) ::kill(pid_, sig);
}

bool LauncherProcess::wait_exit(std::chrono::milliseconds timeout) {
  if (!running_) return true;
  int status = 0;
  const bool ended = wait_until([&] { return ::waitpid(pid_, &status, WNOHANG) == pid_; }, timeout);
  if (!ended) return false;
  running_ = false;
  code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
  return true;
}

std::string LauncherProcess::out() const { return read_text(dir_.file("launcher.out")); }
std::string LauncherProcess::err() const { return read_text(dir_.file("launcher.err")); }

RunResult run_launcher(const ScratchDir& dir, const std::vector<std::string>& args) {
  LauncherProcess launcher(dir, args);
  const bool finished = launcher.wait_exit(10s);
  return {launcher.code(), launcher.out(), launcher.err(), finished};
}

}  // namespace launch_test
