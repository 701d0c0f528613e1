#include "commands.hpp"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "pmlsm/util/atomic_file.hpp"

namespace pmlsm::tools {

std::vector<const dds::CatalogEntry*> select_topics(const std::vector<std::string>& names) {
  std::vector<const dds::CatalogEntry*> out;
  if (names.empty()) {
    for (const auto& e : dds::catalog()) out.push_back(&e);
    return out;
  }
  for (const auto& name : names) {
    const auto* entry = dds::find_topic(name);
    if (entry == nullptr) {
      throw UsageError("unknown topic '" + name + "'; the known topics are:\n" + dds::known_topics_list());
    }
    out.push_back(entry);
  }
  return out;
}

void require_output_folder(const std::string& option, const std::string& file) {
  if (const std::string missing = missing_folder_of(file); !missing.empty()) {
    throw UsageError(option + " " + file + ": " + missing);
  }
}

void make_output_folder(const std::string& option, const std::string& folder) {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec || !std::filesystem::is_directory(folder)) {
    throw UsageError(option + " " + folder + ": cannot be made: " + (ec ? ec.message() : "not a folder"));
  }
}

std::string writer_key(const eprosima::fastdds::dds::SampleInfo& info) {
  std::ostringstream s;
  s << info.sample_identity.writer_guid();
  return s.str();
}

std::int64_t to_ns(const eprosima::fastrtps::rtps::Time_t& t) {
  return static_cast<std::int64_t>(t.seconds()) * 1000000000LL + static_cast<std::int64_t>(t.nanosec());
}

dds::ParticipantOptions with_node_name(dds::ParticipantOptions options, const std::string& name,
                                       const std::string& identity) {
  if (options.node_name.empty()) options.node_name = name;
  if (options.identity.empty()) options.identity = identity;
  return options;
}

std::string user_at_host() {
  const char* user = std::getenv("USER");
  if (user == nullptr || *user == '\0') user = std::getenv("LOGNAME");
  char host[256] = {};
  if (user == nullptr || *user == '\0' || gethostname(host, sizeof host - 1) != 0 || host[0] == '\0') return "pmlsm";
  return std::string(user) + "@" + host;
}

const dds::CatalogEntry* recorded_channel(const mcap::Channel& channel, const mcap::Schema* schema,
                                          std::optional<introspect::MessageSchema>* decoder, std::string& why) {
  if (decoder != nullptr) decoder->reset();
  if (schema == nullptr) {
    why = "no schema";
    return nullptr;
  }
  if (channel.message_encoding != "cdr") {
    why = "message encoding '" + channel.message_encoding + "', not cdr";
    return nullptr;
  }
  const dds::CatalogEntry* entry =
      dds::recorded_entry(channel.topic, {schema->name, schema->encoding, schema->data}, why);
  if (entry == nullptr || decoder == nullptr) return entry;
  try {
    *decoder = schema->encoding == "omgidl" ? introspect::MessageSchema::parse(schema->data, schema->name)
                                            : introspect::MessageSchema::parse(entry->schema_idl, entry->type_name);
  } catch (const introspect::SchemaError& e) {
    why = std::string("schema not usable: ") + e.what();
    return nullptr;
  }
  return entry;
}

}  // namespace pmlsm::tools
