// `pmlsm topic list|echo|hz|delay`: what is on the domain, in the style of `ros2 topic`.

#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "commands.hpp"
#include "discovery.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"
#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

using Clock = std::chrono::steady_clock;
namespace rtps = eprosima::fastrtps::rtps;

// Monitors read with a volatile reader: they want what is published from now on, not a writer's
// history (which the recorder's transient-local profile asks for).
constexpr const char* kMonitorProfile = "pmlsm_monitor";

int run_list(dds::ParticipantOptions options, double wait_s, bool verbose) {
  DiscoveryCollector collector;
  options.listener = &collector;
  dds::Participant participant(with_node_name(options, "pmlsm_topic_list", "pmlsm_topic"));
  // Discovery has no "done": listen for a while, as `ros2 topic list` does with its daemon.
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_s));
  while (Clock::now() < deadline && !dds::stop_requested()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::string text = collector.report(verbose);
  std::cout << (text.empty()
                    ? "no topics seen (is anything running on domain " + std::to_string(options.domain_id) + "?)\n"
                    : text);
  return kExitOk;
}

// ---- echo, hz, delay: one raw reader on one topic -------------------------------------------

struct TopicReader {
  TopicReader(dds::ParticipantOptions options, const std::string& topic_name, const char* tool)
      : entry(*select_topics({topic_name}).front()),
        participant(with_node_name(options, tool, "pmlsm_topic")),
        reader(participant.make_raw_reader(entry, wakeup, kMonitorProfile)),
        schema(introspect::MessageSchema::parse(entry.schema_idl, entry.type_name)) {}
  const dds::CatalogEntry& entry;
  dds::Wakeup wakeup;  // outlives the participant, whose listeners signal it
  dds::Participant participant;
  dds::Reader<dds::RawPubSubType> reader;
  introspect::MessageSchema schema;
};

/// Calls on_sample for every sample until a stop request, the duration (if > 0) or on_sample
/// returning false. Wakes at least every 100 ms for on_tick (reports).
template <typename OnSample, typename OnTick>
void pump(TopicReader& r, double duration_s, OnSample&& on_sample, OnTick&& on_tick) {
  const auto start = Clock::now();
  dds::RawSample sample;
  eprosima::fastdds::dds::SampleInfo info;
  while (!dds::stop_requested()) {
    const auto seen = r.wakeup.generation();
    while (r.reader.take(sample, info)) {
      if (!on_sample(sample, info)) return;
    }
    on_tick();
    if (duration_s > 0 && Clock::now() - start >= std::chrono::duration<double>(duration_s)) return;
    r.wakeup.wait_for(seen, std::chrono::milliseconds(100));
  }
}

int run_echo(const dds::ParticipantOptions& options, const std::string& topic, std::uint64_t count, double timeout_s) {
  TopicReader r(options, topic, "pmlsm_topic_echo");
  std::uint64_t printed = 0;
  std::uint64_t undecodable = 0;
  pump(
      r, timeout_s,
      [&](const dds::RawSample& sample, const eprosima::fastdds::dds::SampleInfo&) {
        const auto decoded = r.schema.decode(sample.bytes.data(), sample.bytes.size());
        std::cout << introspect::MessageSchema::to_yaml(decoded);
        if (!decoded.ok()) {
          ++undecodable;
          std::cout << "# not decodable: " << decoded.error << "\n";
        }
        std::cout << "---\n" << std::flush;
        return count == 0 || ++printed < count;
      },
      [] {});
  if (count > 0 && printed < count && !dds::stop_requested()) {
    std::cerr << "pmlsm topic echo: " << printed << " of " << count << " samples on "
              << dds::display_name(r.entry.spec.name) << " within " << timeout_s << " s\n";
    return kExitError;
  }
  return undecodable == 0 ? kExitOk : kExitError;
}

int run_hz(const dds::ParticipantOptions& options, const std::string& topic, std::size_t window, double duration_s) {
  TopicReader r(options, topic, "pmlsm_topic_hz");
  RollingWindow periods_s(window);  // the last `window` reception intervals
  std::int64_t last_ns = -1;
  std::uint64_t samples = 0;
  auto next_report = Clock::now() + std::chrono::seconds(1);
  const auto report = [&] {
    const Summary s = summarize(periods_s.values());
    if (s.count == 0) {
      std::printf("%s: no samples yet\n", dds::display_name(r.entry.spec.name).c_str());
    } else {
      std::printf("average rate: %.3f Hz\n\tmin: %.6fs max: %.6fs std dev: %.6fs window: %zu\n", 1.0 / s.mean, s.min,
                  s.max, s.stddev, s.count);
    }
    std::fflush(stdout);
  };
  pump(
      r, duration_s,
      [&](const dds::RawSample&, const eprosima::fastdds::dds::SampleInfo& info) {
        const std::int64_t t_ns = to_ns(info.reception_timestamp);
        if (last_ns >= 0) {
          periods_s.add(static_cast<double>(t_ns - last_ns) * 1e-9);
        }
        last_ns = t_ns;
        ++samples;
        return true;
      },
      [&] {
        if (Clock::now() < next_report) return;
        next_report += std::chrono::seconds(1);
        report();
      });
  report();
  return samples > 0 ? kExitOk : kExitError;
}

int run_delay(const dds::ParticipantOptions& options, const std::string& topic, std::size_t window, double duration_s) {
  TopicReader r(options, topic, "pmlsm_topic_delay");
  RollingWindow delays_s(window);
  std::uint64_t samples = 0;
  std::uint64_t without_stamp = 0;
  auto next_report = Clock::now() + std::chrono::seconds(1);
  const auto report = [&] {
    const Summary s = summarize(delays_s.values());
    if (s.count == 0) {
      std::printf("%s: no samples yet\n", dds::display_name(r.entry.spec.name).c_str());
    } else {
      std::printf("average delay: %.6fs\n\tmin: %.6fs max: %.6fs p50: %.6fs p99: %.6fs std dev: %.6fs window: %zu\n",
                  s.mean, s.min, s.max, s.p50, s.p99, s.stddev, s.count);
    }
    std::fflush(stdout);
  };
  pump(
      r, duration_s,
      [&](const dds::RawSample& sample, const eprosima::fastdds::dds::SampleInfo& info) {
        ++samples;
        // The publisher's wall clock at write (Stamp.source_time_ns) against ours at reception:
        // across hosts this includes their clock offset, as ros2 topic delay does.
        const auto decoded = r.schema.decode(sample.bytes.data(), sample.bytes.size());
        const auto* stamp = decoded.find("stamp.source_time_ns");
        const auto source_ns = stamp != nullptr ? stamp->as_double() : std::nullopt;
        if (!source_ns || *source_ns <= 0) {
          ++without_stamp;
          return true;
        }
        delays_s.add((static_cast<double>(to_ns(info.reception_timestamp)) - *source_ns) * 1e-9);
        return true;
      },
      [&] {
        if (Clock::now() < next_report) return;
        next_report += std::chrono::seconds(1);
        report();
      });
  report();
  if (without_stamp > 0)
    std::printf("%llu samples without a source time\n", static_cast<unsigned long long>(without_stamp));
  return samples > without_stamp ? kExitOk : kExitError;
}

}  // namespace

void add_topic_commands(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto* topic = app.add_subcommand("topic", "What is on the DDS domain: list, echo, hz, delay");
  topic->require_subcommand(1);

  struct Options {
    double wait_s = -1.0;  // < 0: 2 s open, 5 s secure (each peer's handshake comes first)
    bool verbose = false;
    std::string topic;
    std::uint64_t count = 0;
    double timeout_s = 0.0;
    std::size_t window = 1000;
    double duration_s = 0.0;
  };
  auto o = std::make_shared<Options>();

  auto* list = topic->add_subcommand("list", "Topics seen on the domain, with type, writers, readers and QoS");
  list->add_option("--wait-s", o->wait_s, "How long to listen for discovery (default 2 s, with a keystore 5 s)")
      ->check(CLI::Range(0.1, 600.0));
  list->add_flag("-v,--verbose", o->verbose, "Every writer and reader with its node and QoS");
  list->callback([&dds_options, o, &exit_code] {
    const double wait_s = o->wait_s > 0 ? o->wait_s : (dds_options.keystore.empty() ? 2.0 : 5.0);
    exit_code = run_list(dds_options, wait_s, o->verbose);
  });

  auto* echo = topic->add_subcommand("echo", "Prints the samples of a topic, decoded");
  echo->add_option("topic", o->topic, "Topic, e.g. /pmlsm/motor_feedback")->required();
  echo->add_option("-n,--count", o->count, "Stop after this many samples (0 = until Ctrl-C)");
  echo->add_option("--timeout-s", o->timeout_s, "Give up after this long (0 = never)")->check(CLI::NonNegativeNumber);
  echo->callback(
      [&dds_options, o, &exit_code] { exit_code = run_echo(dds_options, o->topic, o->count, o->timeout_s); });

  auto* hz = topic->add_subcommand("hz", "Rate and jitter of a topic, from reception times");
  hz->add_option("topic", o->topic, "Topic")->required();
  hz->add_option("-w,--window", o->window, "Intervals in the statistics")
      ->capture_default_str()
      ->check(CLI::Range(2, 10000000));
  hz->add_option("--duration-s", o->duration_s, "Stop after this long (0 = until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  hz->callback([&dds_options, o, &exit_code] { exit_code = run_hz(dds_options, o->topic, o->window, o->duration_s); });

  auto* delay = topic->add_subcommand("delay", "Latency of a topic: reception time minus the sample's source time");
  delay->add_option("topic", o->topic, "Topic")->required();
  delay->add_option("-w,--window", o->window, "Samples in the statistics")
      ->capture_default_str()
      ->check(CLI::Range(1, 10000000));
  delay->add_option("--duration-s", o->duration_s, "Stop after this long (0 = until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  delay->callback(
      [&dds_options, o, &exit_code] { exit_code = run_delay(dds_options, o->topic, o->window, o->duration_s); });
}

}  // namespace pmlsm::tools
