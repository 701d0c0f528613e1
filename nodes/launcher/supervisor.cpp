#include "supervisor.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/signalfd.h>
#include <sys/wait.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif

#include <algorithm>
#include <cerrno>
#include <climits>
#include <csignal>
#include <cstring>
#include <optional>

#include "pmlsm/util/exit_codes.hpp"

extern char** environ;

namespace pmlsm::launch {

LineRelay::LineRelay(std::string prefix, Sink sink, std::size_t max_line)
    : prefix_(std::move(prefix)), sink_(std::move(sink)), max_line_(std::max<std::size_t>(max_line, 1)) {}

void LineRelay::feed(const char* data, std::size_t size) {
  std::size_t start = 0;
  for (std::size_t i = 0; i < size; ++i) {
    if (data[i] != '\n') continue;
    if (partial_.empty()) {
      emit(data + start, i - start);
    } else {
      partial_.append(data + start, i - start);
      emit(partial_.data(), partial_.size());
      partial_.clear();
    }
    start = i + 1;
  }
  partial_.append(data + start, size - start);
  std::size_t done = 0;
  while (partial_.size() - done >= max_line_) {
    emit(partial_.data() + done, max_line_);
    done += max_line_;
  }
  partial_.erase(0, done);
}

void LineRelay::finish() {
  if (!partial_.empty()) emit(partial_.data(), partial_.size());
  partial_.clear();
}

void LineRelay::emit(const char* data, std::size_t size) {
  std::size_t done = 0;
  do {
    const std::size_t piece = std::min(size - done, max_line_);
    std::string line;
    line.reserve(prefix_.size() + piece + 1);
    line.append(prefix_).append(data + done, piece).push_back('\n');
    sink_(line);
    done += piece;
  } while (done < size);
}

namespace {

using Clock = std::chrono::steady_clock;

// Owns one file descriptor.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
  Fd& operator=(Fd&& other) noexcept {
    if (this != &other) reset(std::exchange(other.fd_, -1));
    return *this;
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() { reset(); }
  int get() const { return fd_; }
  bool open() const { return fd_ >= 0; }
  void reset(int fd = -1) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
  }

 private:
  int fd_ = -1;
};

// Writes all of `text`; a closed or failing output drops it rather than stop supervision.
void write_all(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else if (n < 0 && errno == EAGAIN) {
      pollfd p{fd, POLLOUT, 0};  // an output left non-blocking by whoever started us
      ::poll(&p, 1, -1);
    } else {
      return;
    }
  }
}

const char* signal_name(int sig) {
  switch (sig) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    case SIGHUP: return "SIGHUP";
    case SIGKILL: return "SIGKILL";
    case SIGQUIT: return "SIGQUIT";
    case SIGABRT: return "SIGABRT";
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGPIPE: return "SIGPIPE";
    default: return ::strsignal(sig);
  }
}

std::string plural(std::size_t n, const char* word) { return std::to_string(n) + " " + word + (n == 1 ? "" : "s"); }

// Blocks the signals the supervisor handles and delivers them through a
// signalfd, so one poll() waits for output, exits and stop requests alike.
class SignalChannel {
 public:
  SignalChannel() {
    sigemptyset(&set_);
    // Linux queues a blocked signal even when it is ignored, so SIGINT works for a
    // launcher started with '&' from a script; an ignored SIGHUP is left alone,
    // though: that is nohup asking to outlive the terminal.
    struct sigaction hup {};
    ::sigaction(SIGHUP, nullptr, &hup);
    for (int sig : {SIGCHLD, SIGINT, SIGTERM}) sigaddset(&set_, sig);
    if (hup.sa_handler != SIG_IGN) sigaddset(&set_, SIGHUP);
    ::sigprocmask(SIG_BLOCK, &set_, &old_mask_);
    fd_.reset(::signalfd(-1, &set_, SFD_NONBLOCK | SFD_CLOEXEC));
    if (!fd_.open()) error_ = errno;
    // An inherited SIG_IGN for SIGCHLD would make the kernel reap the nodes
    // itself, and their exit statuses would be lost.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    ::sigaction(SIGCHLD, &dfl, &old_chld_);
    // A reader that goes away must not kill the launcher while nodes run.
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    ::sigaction(SIGPIPE, &ignore, &old_pipe_);
  }
  SignalChannel(const SignalChannel&) = delete;
  SignalChannel& operator=(const SignalChannel&) = delete;
  ~SignalChannel() {
    while (next()) {
    }
    fd_.reset();
    ::sigaction(SIGPIPE, &old_pipe_, nullptr);
    ::sigaction(SIGCHLD, &old_chld_, nullptr);
    ::sigprocmask(SIG_SETMASK, &old_mask_, nullptr);
  }
  bool ok() const { return fd_.open(); }
  int error() const { return error_; }
  int fd() const { return fd_.get(); }
  // The next pending signal, if any.
  std::optional<int> next() {
    signalfd_siginfo info{};
    if (::read(fd_.get(), &info, sizeof info) != static_cast<ssize_t>(sizeof info)) return std::nullopt;
    return static_cast<int>(info.ssi_signo);
  }

 private:
  sigset_t set_{};
  sigset_t old_mask_{};
  struct sigaction old_chld_ {};
  struct sigaction old_pipe_ {};
  Fd fd_;
  int error_ = 0;
};

struct Child {
  Child(const ProcessSpec& spec, const LineRelay::Sink& out_sink, const LineRelay::Sink& err_sink)
      : spec(&spec), out_relay("[" + spec.name + "] ", out_sink), err_relay("[" + spec.name + "] ", err_sink) {}
  const ProcessSpec* spec;
  pid_t pid = -1;  // >0 from fork until reaped
  Clock::time_point started;
  Fd out, err;
  LineRelay out_relay, err_relay;
  bool running = false;
  bool exec_failed = false;
  bool stop_sent = false;
  bool kill_sent = false;
  bool clean = false;
  std::string outcome;  // "exited with code 5 (...)" and the like, for the summary
};

// "exited with code 4 (a peer was lost)", "killed by signal 9 (SIGKILL, sent by
// the launcher)": the code's meaning, and whether a signal was the launcher's own.
std::string describe_exit(const Child& c, int status) {
  if (WIFEXITED(status)) {
    const int code = WEXITSTATUS(status);
    return "exited with code " + std::to_string(code) + " (" + pmlsm::exit_code_meaning(code) + ")";
  }
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    const bool ours = (sig == SIGINT && c.stop_sent) || (sig == SIGKILL && c.kill_sent);
    return "killed by signal " + std::to_string(sig) + " (" + signal_name(sig) +
           (ours ? ", sent by the launcher)" : ")");
  }
  return "ended with status " + std::to_string(status);
}

// Everything the child needs after fork(), built before it: only
// async-signal-safe calls are allowed there.
struct ExecImage {
  explicit ExecImage(const ProcessSpec& spec) : path(spec.path), argv_store(spec.argv) {
    if (argv_store.empty()) argv_store.push_back(spec.path);
    for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
      const std::string entry = *e;
      const std::string key = entry.substr(0, entry.find('='));
      const bool replaced =
          std::any_of(spec.env.begin(), spec.env.end(), [&](const auto& kv) { return kv.first == key; });
      if (!replaced) env_store.push_back(entry);
    }
    for (const auto& [key, value] : spec.env) env_store.push_back(key + "=" + value);
    for (auto& a : argv_store) argv.push_back(a.data());
    argv.push_back(nullptr);
    for (auto& e : env_store) envp.push_back(e.data());
    envp.push_back(nullptr);
  }
  std::string path;
  std::vector<std::string> argv_store, env_store;
  std::vector<char*> argv, envp;
};

class Supervisor {
 public:
  Supervisor(const std::vector<ProcessSpec>& processes, const SupervisorOptions& options)
      : options_(options), buffer_(64 * 1024) {
    const LineRelay::Sink out_sink = [this](const std::string& line) { write_all(options_.out_fd, line); };
    const LineRelay::Sink err_sink = [this](const std::string& line) { write_all(options_.err_fd, line); };
    children_.reserve(processes.size());
    for (const auto& spec : processes) children_.emplace_back(spec, out_sink, err_sink);
  }

  int run() {
    if (!signals_.ok()) {
      report(std::string("cannot create a signalfd: ") + std::strerror(signals_.error()));
      return pmlsm::kExitError;
    }
    Fd dev_null(::open("/dev/null", O_RDONLY | O_CLOEXEC));
    for (Child& child : children_) {
      if (!start(child, dev_null.get())) {  // the failure is noted
        request_stop();
        break;
      }
    }
    while (any_running()) wait_and_handle();
    return summarise();
  }

 private:
  void report(const std::string& message) const { write_all(options_.err_fd, "[launcher] " + message + "\n"); }

  bool any_running() const {
    return std::any_of(children_.begin(), children_.end(), [](const Child& c) { return c.running; });
  }

  bool start(Child& child, int dev_null) {
    const ProcessSpec& spec = *child.spec;
    int out[2], err[2], exec_status[2];
    if (::pipe2(out, O_CLOEXEC) != 0) return start_error(child, "pipe");
    Fd out_read(out[0]), out_write(out[1]);
    if (::pipe2(err, O_CLOEXEC) != 0) return start_error(child, "pipe");
    Fd err_read(err[0]), err_write(err[1]);
    // Closed by a successful exec; otherwise the child writes its errno here.
    if (::pipe2(exec_status, O_CLOEXEC) != 0) return start_error(child, "pipe");
    Fd status_read(exec_status[0]), status_write(exec_status[1]);
    const ExecImage image(spec);
    const pid_t parent = ::getpid();

    const pid_t pid = ::fork();
    if (pid < 0) return start_error(child, "fork");
    if (pid == 0) {
      exec_child(image, parent, dev_null, out_write.get(), err_write.get(), status_write.get());
    }
    // Also here, so the group exists whichever of parent and child runs first.
    ::setpgid(pid, pid);
    child.pid = pid;
    child.running = true;
    child.started = Clock::now();
    out_write.reset();
    err_write.reset();
    status_write.reset();

    int child_errno = 0;
    std::size_t got = 0;
    while (got < sizeof child_errno) {
      const ssize_t n =
          ::read(status_read.get(), reinterpret_cast<char*>(&child_errno) + got, sizeof child_errno - got);
      if (n > 0) {
        got += static_cast<std::size_t>(n);
      } else if (n == 0 || errno != EINTR) {
        break;
      }
    }
    ::fcntl(out_read.get(), F_SETFL, O_NONBLOCK);
    ::fcntl(err_read.get(), F_SETFL, O_NONBLOCK);
    child.out = std::move(out_read);
    child.err = std::move(err_read);
    if (got == sizeof child_errno) {
      child.exec_failed = true;
      child.outcome = "could not be executed";
      report("node '" + spec.name + "' failed to start: cannot execute '" + spec.path +
             "': " + std::strerror(child_errno));
      // A node started earlier may have failed already; its exit comes first.
      reap();
      note_failure(child, pmlsm::kExitError);
      return false;
    }
    report(spec.name + " started (pid " + std::to_string(pid) + ")");
    return true;
  }

  bool start_error(Child& child, const char* call) {
    report("node '" + child.spec->name + "' failed to start: " + call + ": " + std::strerror(errno));
    child.outcome = std::string("not started (") + call + " failed)";
    note_failure(child, pmlsm::kExitError);
    return false;
  }

  [[noreturn]] static void exec_child(const ExecImage& image, pid_t parent, int dev_null, int out_fd, int err_fd,
                                      int status_fd) {
    ::setpgid(0, 0);  // away from the terminal's group: only the launcher forwards Ctrl-C
#ifdef __linux__
    // Nodes stop too if the launcher is killed outright.
    ::prctl(PR_SET_PDEATHSIG, SIGINT);
    if (::getppid() != parent) ::_exit(127);
#else
    (void)parent;
#endif
    if (dev_null >= 0) ::dup2(dev_null, STDIN_FILENO);
    ::dup2(out_fd, STDOUT_FILENO);
    ::dup2(err_fd, STDERR_FILENO);
    // Ignored signals and the blocked mask survive exec: give the node a clean slate.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGCHLD, SIGPIPE, SIGQUIT}) ::sigaction(sig, &dfl, nullptr);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::execve(image.path.c_str(), image.argv.data(), image.envp.data());
    const int e = errno;
    [[maybe_unused]] const ssize_t n = ::write(status_fd, &e, sizeof e);
    ::_exit(127);
  }

  void wait_and_handle() {
    std::vector<pollfd> fds{{signals_.fd(), POLLIN, 0}};
    std::vector<std::pair<Child*, bool>> owners{{nullptr, false}};  // (child, is stderr)
    for (Child& c : children_) {
      if (c.out.open()) {
        fds.push_back({c.out.get(), POLLIN, 0});
        owners.emplace_back(&c, false);
      }
      if (c.err.open()) {
        fds.push_back({c.err.get(), POLLIN, 0});
        owners.emplace_back(&c, true);
      }
    }
    int timeout_ms = -1;
    if (kill_deadline_) {
      const auto left = std::chrono::ceil<std::chrono::milliseconds>(*kill_deadline_ - Clock::now());
      timeout_ms = static_cast<int>(std::clamp<long long>(left.count(), 0, INT_MAX));
    }
    const int ready = ::poll(fds.data(), fds.size(), timeout_ms);
    if (ready < 0 && errno != EINTR) {
      report(std::string("poll failed: ") + std::strerror(errno) + "; killing all nodes");
      failed_ = true;
      abort_all();
      return;
    }
    // Output first, so a node's last lines come before the report of its exit.
    for (std::size_t i = 1; ready > 0 && i < fds.size(); ++i) {
      if (fds[i].revents != 0) read_output(*owners[i].first, owners[i].second, 1);
    }
    if (ready > 0 && fds[0].revents != 0) {
      while (const auto sig = signals_.next()) {
        if (*sig == SIGCHLD) {
          reap();
        } else {
          on_stop_signal(*sig);
        }
      }
    }
    if (kill_deadline_ && Clock::now() >= *kill_deadline_) {
      kill_deadline_.reset();
      for (Child& c : children_) {
        if (c.running && !c.kill_sent) {
          report(c.spec->name + " did not stop within " + std::to_string(options_.stop_timeout.count()) +
                 " ms of SIGINT; sending SIGKILL");
          send(c, SIGKILL);
        }
      }
    }
  }

  // Reads up to `max_reads` chunks; closes the pipe at end of stream.
  void read_output(Child& c, bool is_err, int max_reads) {
    Fd& fd = is_err ? c.err : c.out;
    LineRelay& relay = is_err ? c.err_relay : c.out_relay;
    for (int i = 0; i < max_reads && fd.open(); ++i) {
      const ssize_t n = ::read(fd.get(), buffer_.data(), buffer_.size());
      if (n > 0) {
        relay.feed(buffer_.data(), static_cast<std::size_t>(n));
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && errno == EAGAIN) return;
      relay.finish();
      fd.reset();
    }
  }

  void reap() {
    for (;;) {
      int status = 0;
      const pid_t pid = ::waitpid(-1, &status, WNOHANG);
      if (pid <= 0) return;
      const auto it =
          std::find_if(children_.begin(), children_.end(), [pid](const Child& c) { return c.running && c.pid == pid; });
      if (it != children_.end()) on_exit(*it, status);
    }
  }

  void on_exit(Child& c, int status) {
    const auto lived = Clock::now() - c.started;
    c.running = false;
    c.pid = -1;
    // What the node wrote before exiting is in the pipes now; a grandchild that
    // still holds them open must not keep the launcher waiting.
    constexpr int kDrainReads = 16;
    read_output(c, false, kDrainReads);
    read_output(c, true, kDrainReads);
    c.out_relay.finish();
    c.err_relay.finish();
    c.out.reset();
    c.err.reset();
    if (c.exec_failed) return;  // reported at start

    c.outcome = describe_exit(c, status);
    report(c.spec->name + " " + c.outcome);
    const bool exited_zero = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    const bool ended_by_our_sigint = c.stop_sent && !c.kill_sent && WIFSIGNALED(status) && WTERMSIG(status) == SIGINT;
    c.clean = exited_zero || ended_by_our_sigint;
    if (!c.clean) {
      // A node's own code says why it failed; a signal (or a SIGKILL the stop
      // needed) carries no code, so it is a plain error.
      note_failure(c, WIFEXITED(status) ? WEXITSTATUS(status) : pmlsm::kExitError);
    }
    if (!c.clean && !c.stop_sent && options_.start_grace.count() > 0 && lived < options_.start_grace) {
      report("node '" + c.spec->name + "' died at start: " + c.outcome);
      request_stop();
    } else if (c.spec->ends_launch && !stopping_) {
      report(c.spec->name + " ends the launch");
      request_stop();
    }
  }

  void on_stop_signal(int sig) {
    if (!stopping_) {
      report(std::string("got ") + signal_name(sig));
      request_stop();
      return;
    }
    report(std::string("got ") + signal_name(sig) + " again; sending SIGKILL");
    kill_deadline_.reset();
    kill_all();
  }

  // SIGINT to every running node, SIGKILL to those still running after the timeout.
  void request_stop() {
    if (stopping_) return;
    stopping_ = true;
    std::size_t running = 0;
    for (Child& c : children_) {
      if (c.running) {
        send(c, SIGINT);
        ++running;
      }
    }
    if (running == 0) return;
    report("stopping " + plural(running, "node") + " (SIGINT, then SIGKILL after " +
           std::to_string(options_.stop_timeout.count()) + " ms)");
    kill_deadline_ = Clock::now() + options_.stop_timeout;
  }

  void kill_all() {
    for (Child& c : children_) send(c, SIGKILL);
  }

  // Without poll() nothing can be supervised: kill and reap everything, blocking.
  void abort_all() {
    kill_all();
    for (Child& c : children_) {
      int status = 0;
      if (c.running && ::waitpid(c.pid, &status, 0) == c.pid) on_exit(c, status);
    }
  }

  // Only to a child not yet reaped, so the PID cannot belong to anyone else.
  static void send(Child& c, int sig) {
    if (!c.running) return;
    ::kill(c.pid, sig);
    if (sig == SIGINT) c.stop_sent = true;
    if (sig == SIGKILL) c.kill_sent = true;
  }

  // Failures in the order they were seen: the first one's code is the launch's.
  void note_failure(const Child& c, int code) {
    if (failures_.empty()) exit_code_ = code;
    failures_.push_back(&c);
  }

  int summarise() const {
    const bool all_clean = std::all_of(children_.begin(), children_.end(), [](const Child& c) { return c.clean; });
    if (all_clean && !failed_) {
      report("all " + plural(children_.size(), "node") + " ended cleanly");
      return pmlsm::kExitOk;
    }
    std::vector<std::string> problems;
    for (const Child* c : failures_) problems.push_back(c->spec->name + " " + c->outcome);
    // The rest: nodes left unstarted after an earlier one failed to start.
    for (const Child& c : children_) {
      const bool listed = std::find(failures_.begin(), failures_.end(), &c) != failures_.end();
      if (!c.clean && !listed) problems.push_back(c.spec->name + " " + (c.outcome.empty() ? "not started" : c.outcome));
    }
    std::string text = "launch failed with exit code " + std::to_string(exit_code_);
    if (failures_.size() > 1) text += " (from " + failures_.front()->spec->name + ", the first to fail)";
    std::string list;
    for (const auto& p : problems) list += (list.empty() ? "" : "; ") + p;
    report(text + (list.empty() ? "" : ": " + list));
    return exit_code_;
  }

  const SupervisorOptions options_;
  SignalChannel signals_;
  std::vector<Child> children_;
  std::vector<char> buffer_;
  bool stopping_ = false;
  bool failed_ = false;                 // the launcher's own failure (poll)
  std::vector<const Child*> failures_;  // nodes that did not end cleanly, first seen first
  int exit_code_ = pmlsm::kExitError;
  std::optional<Clock::time_point> kill_deadline_;
};

}  // namespace

int supervise(const std::vector<ProcessSpec>& processes, const SupervisorOptions& options) {
  Supervisor supervisor(processes, options);
  return supervisor.run();
}

}  // namespace pmlsm::launch
