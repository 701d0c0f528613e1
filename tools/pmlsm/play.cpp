// `pmlsm play`: publishes a recording back on DDS with its original timing (scaled by --rate),
// so a recording can stand in for a node: e.g. the plant's MotorFeedback played to a fresh
// kalman_estimator, whose estimates then equal the recorded ones.
//
// A recording played onto a live domain would take over its loop (the controller and the
// estimator would follow the recorded MotorFeedback while the live drive waits): play first
// listens for discovery and refuses topics that already have writers there, naming them and
// their nodes, unless --force.
//
// Two passes over the file: the first learns its channels (so a topic selection is checked
// against what the file holds, and every writer exists before the first sample), the second
// publishes. What is not whole in a truncated or corrupt file is reported; the rest is played.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <thread>

#include "commands.hpp"
#include "discovery.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/mcap/mcap.hpp"
#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

using Clock = std::chrono::steady_clock;

struct PlayOptions {
  std::string file;
  std::vector<std::string> topics;
  double rate = 1.0;
  bool loop = false;
  double wait_matched_s = 2.0;
  double discovery_s = -1.0;  // < 0: 1.5 s open, 5 s secure (each new peer's handshake first)
  bool force = false;
  bool no_progress = false;
};

struct PlayedChannel {
  const dds::CatalogEntry* entry = nullptr;
  std::unique_ptr<dds::Writer<dds::RawPubSubType>> writer;
  std::uint64_t published = 0;
  std::uint64_t refused = 0;
};

struct FileChannels {
  std::map<std::uint16_t, mcap::Channel> channels;
  std::map<std::uint16_t, mcap::Schema> schemas;
  mcap::ReadReport report;
};

FileChannels scan(const std::string& path) {
  FileChannels f;
  mcap::ReadCallbacks callbacks;
  callbacks.on_schema = [&](const mcap::Schema& s) { f.schemas[s.id] = s; };
  callbacks.on_channel = [&](const mcap::Channel& c) { f.channels[c.id] = c; };
  f.report = mcap::read(path, callbacks);
  return f;
}

void print_problems(const mcap::ReadReport& report) {
  for (const auto& p : report.problems) std::cerr << "pmlsm play: " << p << "\n";
}

/// Listens `o.discovery_s` for writers on the selected topics; unless --force, any found is a
/// UsageError naming each topic and the nodes writing it.
void refuse_live_writers(dds::Participant& participant, DiscoveryCollector& discovery, FileChannels& file,
                         const std::set<std::uint16_t>& selected, const PlayOptions& o) {
  // A secure participant learns of a peer's endpoints only after their handshake, which took
  // 1-4 s here on a loaded 2-core host.
  const double wait_s = o.discovery_s >= 0 ? o.discovery_s : (participant.identity().empty() ? 1.5 : 5.0);
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_s));
  while (Clock::now() < deadline && !dds::stop_requested()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::string own = prefix_text(participant.entity()->guid().guidPrefix);
  std::string live;
  for (const auto id : selected) {
    const auto* entry = dds::find_topic(file.channels[id].topic);
    const auto writers = discovery.writers_of(entry->spec.name, own);
    if (writers.empty()) continue;
    live += "  " + dds::display_name(entry->spec.name) + ": written by";
    for (const auto& w : writers) live += " " + w;
    live += "\n";
  }
  if (live.empty()) return;
  if (o.force) {
    std::cerr << "pmlsm play: --force: publishing next to live writers:\n" << live;
    return;
  }
  throw UsageError("these topics already have live writers on domain " +
                   std::to_string(participant.entity()->get_domain_id()) + " (playing would take over from them):\n" +
                   live + "play on another --domain, choose other --topics, or add --force");
}

FileChannels scan_play_file(const std::string& path) {
  try {
    return scan(path);
  } catch (const std::runtime_error& e) {
    throw UsageError(e.what());
  }
}

/// The channels that can be played: those of project topics, in cdr, whose schema is our type in
/// either profile (omgidl or ros2); display topic -> channel id. Channels of other topics are
/// skipped. @throws UsageError naming each channel of a project topic that does not match: a
/// player never puts bytes of another type on a topic of ours, so nothing is played then.
std::map<std::string, std::uint16_t> playable_channels(const FileChannels& file) {
  std::map<std::string, std::uint16_t> playable;
  std::string refused;
  for (const auto& [id, channel] : file.channels) {
    if (dds::find_topic(channel.topic) == nullptr) {
      std::cerr << "pmlsm play: skipping channel " << channel.topic << " (not a project topic)\n";
      continue;
    }
    const auto schema = file.schemas.find(channel.schema_id);
    std::string why;  // play sends the bytes as they are: no decoder needed
    const auto* entry =
        recorded_channel(channel, schema != file.schemas.end() ? &schema->second : nullptr, nullptr, why);
    if (entry == nullptr) {
      refused += "  channel " + std::to_string(id) + " " + channel.topic + ": " + why + "\n";
      continue;
    }
    playable[dds::display_name(entry->spec.name)] = id;
  }
  if (!refused.empty()) {
    throw UsageError("not played: channels of project topics that do not carry the topic's type:\n" + refused);
  }
  return playable;
}

/// The channel ids of --topics (all playable ones without). @throws UsageError for a topic the
/// file does not hold, or when nothing is left to play.
std::set<std::uint16_t> select_played_channels(const PlayOptions& o,
                                               const std::map<std::string, std::uint16_t>& playable) {
  std::set<std::uint16_t> selected;
  if (o.topics.empty()) {
    for (const auto& [topic, id] : playable) selected.insert(id);
  } else {
    for (const auto* entry : select_topics(o.topics)) {  // an unknown name: UsageError listing the known ones
      const auto found = playable.find(dds::display_name(entry->spec.name));
      if (found == playable.end()) {
        std::string known;
        for (const auto& [topic, id] : playable) known += "  " + topic + "\n";
        throw UsageError("topic '" + dds::display_name(entry->spec.name) + "' is not in " + o.file + "; it holds:\n" +
                         known);
      }
      selected.insert(found->second);
    }
  }
  if (selected.empty()) throw UsageError(o.file + " holds no project topic to play");
  return selected;
}

/// A writer per selected channel, then up to `wait_matched_s` for each to match a subscriber.
std::map<std::uint16_t, PlayedChannel> make_played_writers(dds::Participant& participant, FileChannels& file,
                                                           const std::set<std::uint16_t>& selected,
                                                           double wait_matched_s) {
  std::map<std::uint16_t, PlayedChannel> played;
  for (const auto id : selected) {
    const auto* entry = dds::find_topic(file.channels[id].topic);
    played[id] = PlayedChannel{
        entry, std::make_unique<dds::Writer<dds::RawPubSubType>>(participant.make_raw_writer(*entry)), 0, 0};
  }
  // Give subscribers a moment to match, so the first samples are not sent into the void (the
  // writers are transient-local besides, so a reader matching a little later still gets them).
  const auto match_deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_matched_s));
  for (auto& [id, p] : played) {
    while (p.writer->matched_readers() == 0 && Clock::now() < match_deadline && !dds::stop_requested()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  return played;
}

/// One pass over the file, each message published at its original time divided by --rate;
/// `total` counts the messages of every pass, `sample` is a reused buffer.
mcap::ReadReport play_file_once(const PlayOptions& o, std::map<std::uint16_t, PlayedChannel>& played,
                                bool show_progress, dds::RawSample& sample, std::uint64_t& total) {
  bool have_origin = false;
  std::uint64_t first_log_ns = 0;
  Clock::time_point wall_origin;
  auto next_progress = Clock::now();
  mcap::ReadCallbacks callbacks;
  callbacks.on_message = [&](const mcap::Message& m) {
    if (dds::stop_requested()) return;
    const auto found = played.find(m.channel_id);
    if (found == played.end()) return;
    if (!have_origin) {
      have_origin = true;
      first_log_ns = m.log_time_ns;
      wall_origin = Clock::now();
    }
    // Original timing: the message's offset from the first one, divided by the rate.
    const double offset_s = static_cast<double>(m.log_time_ns - std::min(m.log_time_ns, first_log_ns)) * 1e-9 / o.rate;
    std::this_thread::sleep_until(wall_origin +
                                  std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(offset_s)));
    sample.bytes.assign(m.data, m.data + m.size);
    auto& p = found->second;
    if (p.writer->write(sample)) {
      ++p.published;
    } else {
      ++p.refused;
    }
    ++total;
    if (show_progress && Clock::now() >= next_progress) {
      next_progress = Clock::now() + std::chrono::milliseconds(250);
      std::fprintf(stderr, "\rplaying %8.2f s of the recording  %10llu messages  ", offset_s * o.rate,
                   static_cast<unsigned long long>(total));
    }
  };
  return mcap::read(o.file, callbacks);
}

/// Waits for the readers' acknowledgements, prints what each channel published; kExitError when
/// a writer refused a sample.
int finish_playing(std::map<std::uint16_t, PlayedChannel>& played, const mcap::ReadReport& last_report,
                   const std::string& file) {
  // Reliable readers get everything before the writers go.
  for (auto& [id, p] : played) p.writer->wait_for_acknowledgments(std::chrono::seconds(15));
  std::uint64_t refused = 0;
  for (const auto& [id, p] : played) {
    refused += p.refused;
    std::printf("%-36s %10llu published%s\n", dds::display_name(p.entry->spec.name).c_str(),
                static_cast<unsigned long long>(p.published),
                p.refused > 0 ? (", " + std::to_string(p.refused) + " refused").c_str() : "");
  }
  if (!last_report.complete()) {
    std::printf("played what is whole of %s; not whole:\n", file.c_str());
    for (const auto& p : last_report.problems) std::printf("  %s\n", p.c_str());
  }
  return refused == 0 ? kExitOk : kExitError;
}

int run_play(const dds::ParticipantOptions& dds_options, const PlayOptions& o) {
  FileChannels file = scan_play_file(o.file);
  print_problems(file.report);
  const std::set<std::uint16_t> selected = select_played_channels(o, playable_channels(file));

  DiscoveryCollector discovery;
  dds::ParticipantOptions options = with_node_name(dds_options, "pmlsm_play", "pmlsm_play");
  options.listener = &discovery;
  dds::Participant participant(options);
  refuse_live_writers(participant, discovery, file, selected, o);
  std::map<std::uint16_t, PlayedChannel> played = make_played_writers(participant, file, selected, o.wait_matched_s);

  const bool show_progress = !o.no_progress && isatty(STDERR_FILENO) != 0;
  dds::RawSample sample;
  std::uint64_t total = 0;
  mcap::ReadReport last_report;
  do {
    last_report = play_file_once(o, played, show_progress, sample, total);
  } while (o.loop && !dds::stop_requested());
  if (show_progress) std::fprintf(stderr, "\n");
  return finish_playing(played, last_report, o.file);
}

}  // namespace

void add_play_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto o = std::make_shared<PlayOptions>();
  auto* play = app.add_subcommand("play", "Publishes a recording back with its original timing");
  play->add_option("file", o->file, "MCAP file")->required();
  play->add_option("--topics", o->topics, "Only these topics (default: every project topic in the file)");
  play->add_option("-r,--rate", o->rate, "Speed factor (2 = twice as fast)")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 1e6));
  play->add_flag("-l,--loop", o->loop, "Start again at the end, until Ctrl-C");
  play->add_option("--wait-matched-s", o->wait_matched_s, "Wait at most this long for subscribers before playing [s]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  play->add_flag("--no-progress", o->no_progress, "No progress line on stderr");
  play->add_option("--discovery-s", o->discovery_s,
                   "Listen this long for live writers on the played topics first [s] (default 1.5, with a keystore 5)")
      ->check(CLI::Range(0.0, 600.0));
  play->add_flag("--force", o->force, "Play even onto topics that have live writers on the domain");
  play->callback([&dds_options, o, &exit_code] { exit_code = run_play(dds_options, *o); });
}

}  // namespace pmlsm::tools
