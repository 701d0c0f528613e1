// `pmlsm record`: every project topic (or a selection) into an MCAP file, as the DDS bytes
// arrived: message encoding 'cdr' with its encapsulation header; log time = reception, publish
// time = the writer's source timestamp. The schemas follow --profile: omgidl (the flattened IDL,
// Foxglove's) or ros2 (ROS 2's .msg definitions, MCAP's ros2 profile, as rosbag2 writes it).
//
// Losses are counted from each writer's sequence numbers (a reliable writer skips none unless a
// reader's history overflowed) and from Fast DDS's sample-lost status. Chunks are written when
// full and at least every --flush-interval-s, so a recorder killed by SIGKILL loses at most that.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <map>
#include <memory>
#include <optional>

#include "commands.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/mcap/mcap.hpp"
#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

using Clock = std::chrono::steady_clock;

struct RecordOptions {
  std::string output;
  std::vector<std::string> topics;
  std::string compression = "zstd";
  std::size_t chunk_size_kib = 1024;
  double flush_interval_s = 1.0;
  double duration_s = 0.0;
  double stop_after_idle_s = 0.0;
  bool no_progress = false;
  std::string profile = "omgidl";
};

struct RecordedTopic {
  const dds::CatalogEntry* entry = nullptr;
  dds::Reader<dds::RawPubSubType> reader;
  std::uint16_t channel_id = 0;
  std::uint64_t messages = 0;
  std::uint64_t bytes = 0;
  SequenceTracker sequences;
};

std::string default_file_name() {
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  localtime_r(&now, &local);
  char name[64];
  std::strftime(name, sizeof name, "pmlsm_%Y%m%d-%H%M%S.mcap", &local);
  return name;
}

std::uint64_t sample_lost_count(dds::Reader<dds::RawPubSubType>& reader) {
  eprosima::fastdds::dds::SampleLostStatus status;
  reader.entity()->get_sample_lost_status(status);
  return static_cast<std::uint64_t>(status.total_count);
}

mcap::Compression parse_record_compression(const std::string& name) {
  try {
    return mcap::parse_compression(name);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

/// A channel per topic and a schema per type in `writer`, and a reader per topic.
std::vector<std::unique_ptr<RecordedTopic>> add_recorded_topics(const std::vector<const dds::CatalogEntry*>& entries,
                                                                dds::Participant& participant, dds::Wakeup& wakeup,
                                                                mcap::Writer& writer, dds::RecordingProfile profile) {
  std::map<std::string, std::uint16_t> schema_ids;  // one schema per type
  std::vector<std::unique_ptr<RecordedTopic>> recorded;
  for (const auto* entry : entries) {
    auto [schema, added] = schema_ids.try_emplace(entry->type_name, 0);
    if (added) {
      const dds::RecordedSchema recorded_schema = dds::recorded_schema(*entry, profile);
      schema->second = writer.add_schema(recorded_schema.name, recorded_schema.encoding, recorded_schema.data);
    }
    // The observer profile: deep, reliable, transient-local, so a recorder started just after
    // the nodes still gets the run from its first tick (up to the writers' history depth).
    auto t = std::make_unique<RecordedTopic>(
        RecordedTopic{entry, participant.make_raw_reader(*entry, wakeup, dds::kObserverProfile), 0, 0, 0, {}});
    t->channel_id = writer.add_channel(schema->second, dds::display_name(entry->spec.name), "cdr",
                                       {{"dds_topic", entry->spec.name}, {"qos_profile", entry->spec.qos_profile}});
    recorded.push_back(std::move(t));
  }
  return recorded;
}

/// What the recording loop counted since `start`.
struct RecordTally {
  Clock::time_point start;
  std::uint64_t messages = 0;
  // The drive's run (MotorFeedback's Stamp.run_id): a restarted drive is a new run in the same
  // file; say so, so that nobody reads the file as one run.
  std::optional<std::uint64_t> drive_run;
  std::uint64_t drive_runs = 0;
};

void note_drive_run(const std::vector<std::uint8_t>& feedback_cdr, bool show_progress, RecordTally& tally) {
  const auto run = stamp_run_id(feedback_cdr);
  if (!run || run == tally.drive_run) return;
  if (tally.drive_run) {
    std::fprintf(stderr, "%spmlsm record: the drive restarted (run %016llx -> %016llx): a new run from here\n",
                 show_progress ? "\n" : "", static_cast<unsigned long long>(*tally.drive_run),
                 static_cast<unsigned long long>(*run));
  }
  tally.drive_run = run;
  ++tally.drive_runs;
}

/// Writes every sample the topic's reader holds into the file (`sample` and `info` are reused
/// buffers); true when there was one.
bool record_taken_samples(RecordedTopic& t, mcap::Writer& writer, bool show_progress, dds::RawSample& sample,
                          eprosima::fastdds::dds::SampleInfo& info, RecordTally& tally) {
  bool took = false;
  while (t.reader.take(sample, info)) {
    took = true;
    const std::int64_t received_ns = to_ns(info.reception_timestamp);
    const std::int64_t published_ns = to_ns(info.source_timestamp);
    const std::uint64_t sequence = static_cast<std::uint64_t>(info.sample_identity.sequence_number().to64long());
    t.sequences.observe(writer_key(info), sequence);
    writer.write(t.channel_id, static_cast<std::uint32_t>(sequence),
                 static_cast<std::uint64_t>(received_ns > 0 ? received_ns : published_ns),
                 static_cast<std::uint64_t>(published_ns), sample.bytes.data(), sample.bytes.size());
    ++t.messages;
    t.bytes += sample.bytes.size();
    if (t.entry->spec.name == std::string(dds::topics::kMotorFeedback.name)) {
      note_drive_run(sample.bytes, show_progress, tally);
    }
    ++tally.messages;
  }
  return took;
}

/// Takes and writes until a stop request, --duration-s or --stop-after-idle-s; the open chunk
/// goes to the file at least every --flush-interval-s.
RecordTally record_until_done(const RecordOptions& o, std::vector<std::unique_ptr<RecordedTopic>>& recorded,
                              mcap::Writer& writer, dds::Wakeup& wakeup, bool show_progress) {
  RecordTally tally;
  tally.start = Clock::now();
  auto last_sample = tally.start;
  auto last_flush = tally.start;
  auto next_progress = tally.start;
  std::uint64_t flushed_messages = 0;
  bool any = false;
  dds::RawSample sample;
  eprosima::fastdds::dds::SampleInfo info;
  while (!dds::stop_requested()) {
    const auto seen = wakeup.generation();
    bool took = false;
    for (auto& t : recorded) {
      if (record_taken_samples(*t, writer, show_progress, sample, info, tally)) took = true;
    }
    const auto now = Clock::now();
    if (took) {
      last_sample = now;
      any = true;
    }
    if (tally.messages != flushed_messages && now - last_flush >= std::chrono::duration<double>(o.flush_interval_s)) {
      writer.flush_chunk();
      flushed_messages = tally.messages;
      last_flush = now;
    }
    if (show_progress && now >= next_progress) {
      next_progress = now + std::chrono::milliseconds(250);
      const double elapsed_s = std::chrono::duration<double>(now - tally.start).count();
      std::fprintf(stderr, "\rrecording %7.1f s  %10llu messages  %10s  ", elapsed_s,
                   static_cast<unsigned long long>(tally.messages),
                   human_bytes(static_cast<double>(writer.statistics().file_bytes)).c_str());
    }
    if (o.duration_s > 0 && now - tally.start >= std::chrono::duration<double>(o.duration_s)) break;
    if (o.stop_after_idle_s > 0 && any && now - last_sample >= std::chrono::duration<double>(o.stop_after_idle_s))
      break;
    if (!took) wakeup.wait_for(seen, std::chrono::milliseconds(50));
  }
  return tally;
}

/// The table of topics (messages, lost, missed before the recorder joined) and the totals.
void print_record_summary(const std::vector<std::unique_ptr<RecordedTopic>>& recorded, const mcap::Writer& writer,
                          const RecordTally& tally, const std::string& output) {
  std::uint64_t lost = 0;
  std::uint64_t raw_bytes = 0;
  std::printf("%-36s %10s %8s %14s\n", "topic", "messages", "lost", "before start");
  for (auto& t : recorded) {
    const std::uint64_t topic_lost = std::max(t->sequences.lost(), sample_lost_count(t->reader));
    lost += topic_lost;
    raw_bytes += t->bytes;
    if (t->messages == 0 && topic_lost == 0) continue;
    std::printf("%-36s %10llu %8llu %14llu\n", dds::display_name(t->entry->spec.name).c_str(),
                static_cast<unsigned long long>(t->messages), static_cast<unsigned long long>(topic_lost),
                static_cast<unsigned long long>(t->sequences.missed_before_join()));
  }
  if (tally.drive_runs > 1) {
    std::printf("the file holds %llu runs of the drive (it restarted %llu times)\n",
                static_cast<unsigned long long>(tally.drive_runs),
                static_cast<unsigned long long>(tally.drive_runs - 1));
  }
  const auto& stats = writer.statistics();
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - tally.start).count();
  std::printf("recorded %llu messages in %.1f s, %llu lost; CDR %s, file %s (%.1fx smaller), %llu chunks -> %s\n",
              static_cast<unsigned long long>(tally.messages), elapsed_s, static_cast<unsigned long long>(lost),
              human_bytes(static_cast<double>(raw_bytes)).c_str(),
              human_bytes(static_cast<double>(stats.file_bytes)).c_str(),
              stats.file_bytes > 0 ? static_cast<double>(raw_bytes) / static_cast<double>(stats.file_bytes) : 0.0,
              static_cast<unsigned long long>(stats.chunk_count), output.c_str());
}

int run_record(const dds::ParticipantOptions& dds_options, RecordOptions o) {
  const auto entries = select_topics(o.topics);
  const mcap::Compression compression = parse_record_compression(o.compression);
  dds::RecordingProfile profile = dds::RecordingProfile::kOmgIdl;
  try {
    profile = dds::recording_profile_from_string(o.profile);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--profile: ") + e.what());
  }
  if (o.output.empty()) o.output = default_file_name();
  require_output_folder("pmlsm record: -o", o.output);

  dds::Wakeup wakeup;  // outlives the participant, whose listeners signal it
  dds::Participant participant(with_node_name(dds_options, "pmlsm_record", "pmlsm_record"));
  mcap::WriterOptions writer_options;
  writer_options.compression = compression;
  writer_options.chunk_size_bytes = o.chunk_size_kib * 1024;
  if (profile == dds::RecordingProfile::kRos2) writer_options.profile = "ros2";
  mcap::Writer writer(o.output, writer_options);
  auto recorded = add_recorded_topics(entries, participant, wakeup, writer, profile);
  std::cerr << "pmlsm record: " << recorded.size() << " topics on domain " << dds_options.domain_id << " -> "
            << o.output << " (" << o.compression << ", " << o.profile << " profile)\n";

  const bool show_progress = !o.no_progress && isatty(STDERR_FILENO) != 0;
  const RecordTally tally = record_until_done(o, recorded, writer, wakeup, show_progress);
  writer.close();
  if (show_progress) std::fprintf(stderr, "\n");
  print_record_summary(recorded, writer, tally, o.output);
  return kExitOk;
}

}  // namespace

void add_record_command(CLI::App& app, dds::ParticipantOptions& dds_options, int& exit_code) {
  auto o = std::make_shared<RecordOptions>();
  auto* record = app.add_subcommand("record", "Records topics into an MCAP file (cdr messages)");
  record->add_option("topics", o->topics, "Topics to record (default: every project topic)");
  record->add_option("-o,--output", o->output, "MCAP file (default: pmlsm_<date>-<time>.mcap)");
  record->add_option("--compression", o->compression, "Chunk compression: zstd, lz4 or none")->capture_default_str();
  record->add_option("--chunk-size-kib", o->chunk_size_kib, "Uncompressed bytes per chunk [KiB]")
      ->capture_default_str()
      ->check(CLI::Range(1, 1 << 20));
  record
      ->add_option("--flush-interval-s", o->flush_interval_s,
                   "Write the open chunk at least this often: the most a SIGKILL can lose [s]")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 3600.0));
  record->add_option("--duration-s", o->duration_s, "Stop after this long (0 = until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  record
      ->add_option("--stop-after-idle-s", o->stop_after_idle_s,
                   "Stop once nothing arrived for this long after the first sample (0 = never)")
      ->check(CLI::NonNegativeNumber);
  record->add_flag("--no-progress", o->no_progress, "No progress line on stderr");
  record
      ->add_option("--profile", o->profile,
                   "Schemas: omgidl (the IDL, Foxglove) or ros2 (ROS 2 .msg definitions: rosbag2, ROS 2 tools)")
      ->capture_default_str();
  record->callback([&dds_options, o, &exit_code] { exit_code = run_record(dds_options, *o); });
}

}  // namespace pmlsm::tools
