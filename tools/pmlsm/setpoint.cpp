// `pmlsm setpoint VALUE [--ramp-mps2 A] [--hold-s S]`: commands a rig live. Publishes the
// velocity setpoint on rt/pmlsm/velocity_setpoint (VelocitySetpoint) for a controller running
// an external scenario, repeated at --rate-hz while it holds (a setpoint lives only as long as
// its source repeats it: the controller's timeout brings the reference back to zero when this
// command dies), then a zero setpoint so the controller ramps down and the silence after it is
// a stop, not a lost source.
//
// It waits for the controller's reader before sending (none within --wait-s: exit 3), refuses a
// non-finite value or rate (exit 2); the controller checks the limits (speed, rate) itself.
// Ctrl-C ends the hold early, with the zero setpoint.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <random>
#include <thread>

#include "VelocitySetpointPubSubTypes.h"
#include "commands.hpp"
#include "pmlsm/dds/shutdown.hpp"

namespace pmlsm::tools {
namespace {

using Clock = std::chrono::steady_clock;
namespace msg = pmlsm_msgs::msg;

struct SetpointOptions {
  double velocity_mps = 0;
  double ramp_mps2 = 0;  // 0: the controller's limit
  double hold_s = 0;     // 0: until Ctrl-C
  double rate_hz = 20;
  double wait_s = 10;
  double zero_s = 0.2;  // how long the final zero is repeated
  std::string source;   // default user@host
};

int run_setpoint(const dds::ParticipantOptions& dds_options, const SetpointOptions& o) {
  if (!std::isfinite(o.velocity_mps))
    throw UsageError("setpoint: VALUE must be finite, got " + std::to_string(o.velocity_mps));
  if (!std::isfinite(o.ramp_mps2) || o.ramp_mps2 < 0) {
    throw UsageError("setpoint: --ramp-mps2 must be finite and >= 0, got " + std::to_string(o.ramp_mps2));
  }
  dds::Participant participant(with_node_name(dds_options, "pmlsm_setpoint", "pmlsm_setpoint"));
  auto writer = participant.make_writer(dds::topics::kVelocitySetpoint);

  const auto wait_deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.wait_s));
  while (writer.matched_readers() == 0) {
    if (dds::stop_requested()) return kExitError;
    if (Clock::now() >= wait_deadline) {
      std::cerr << "pmlsm setpoint: no controller follows setpoints on domain " << dds_options.domain_id << " (waited "
                << o.wait_s << " s; is its scenario's command.shape external?)\n";
      return kExitPeerMissing;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));  // discovery poll
  }

  msg::VelocitySetpoint sample;
  sample.session(std::random_device{}() | (static_cast<std::uint64_t>(std::random_device{}()) << 32) | 1u);
  sample.source(o.source.empty() ? user_at_host() : o.source);
  std::uint64_t sequence = 0;
  const auto send = [&](double velocity_mps) {
    ++sequence;
    msg::Stamp stamp;
    stamp.tick(sequence);
    stamp.source_time_ns(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
    sample.stamp(stamp);
    sample.velocity_mps(velocity_mps);
    sample.accel_limit_mps2(o.ramp_mps2);
    sample.sequence_number(sequence);
    writer.write(sample);
  };
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.rate_hz));
  const auto repeat = [&](double velocity_mps, double seconds) {
    const auto start = Clock::now();
    auto next = start;
    while (!dds::stop_requested() && (seconds <= 0 || Clock::now() - start < std::chrono::duration<double>(seconds))) {
      send(velocity_mps);
      next += period;
      std::this_thread::sleep_until(next);
    }
  };

  std::printf("pmlsm setpoint: %.6g m/s%s to %zu controller(s), %s\n", o.velocity_mps,
              o.ramp_mps2 > 0 ? (" at up to " + std::to_string(o.ramp_mps2) + " m/s^2").c_str() : "",
              writer.matched_readers(),
              o.hold_s > 0 ? ("for " + std::to_string(o.hold_s) + " s").c_str() : "until Ctrl-C");
  std::fflush(stdout);
  repeat(o.velocity_mps, o.hold_s);
  // Then zero, repeated for a while even after Ctrl-C: the controller ramps down on purpose.
  const auto zero_end =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.zero_s));
  while (Clock::now() < zero_end) {
    send(0.0);
    std::this_thread::sleep_for(period);
  }
  writer.wait_for_acknowledgments(std::chrono::seconds(1));
  std::printf("pmlsm setpoint: %llu setpoints sent, ended with 0 m/s\n", static_cast<unsigned long long>(sequence));
  return kExitOk;
}

}  // namespace

void add_setpoint_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto o = std::make_shared<SetpointOptions>();
  auto* sub = app.add_subcommand(
      "setpoint", "Commands a controller running an external scenario: VALUE m/s, repeated while it holds, then 0");
  sub->add_option("velocity_mps", o->velocity_mps, "The velocity setpoint [m/s]")->required();
  sub->add_option("--ramp-mps2", o->ramp_mps2, "A gentler rate than the controller's limit [m/s^2] (0: its limit)")
      ->capture_default_str();
  sub->add_option("--hold-s", o->hold_s, "How long to hold it (0: until Ctrl-C)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  sub->add_option("--rate-hz", o->rate_hz, "How often it is repeated (the controller's timeout must be longer)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--wait-s", o->wait_s, "How long to wait for a controller")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  sub->add_option("--source", o->source, "Who asks, for the controller's log (default: user@host)");
  sub->callback([&dds_options, o, &exit_code] { exit_code = run_setpoint(dds_options, *o); });
}

}  // namespace pmlsm::tools
