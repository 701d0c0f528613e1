// What discovery tells a participant about the domain: every writer and reader by topic, with
// its node's name and QoS (`pmlsm topic list`; `pmlsm play` checks for live writers with it).
#pragma once

#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/rtps/participant/ParticipantDiscoveryInfo.h>
#include <fastdds/rtps/reader/ReaderDiscoveryInfo.h>
#include <fastdds/rtps/writer/WriterDiscoveryInfo.h>

#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "pmlsm/dds/catalog.hpp"

namespace pmlsm::tools {

namespace rtps = eprosima::fastrtps::rtps;

inline std::string guid_text(const rtps::GUID_t& guid) {
  std::ostringstream s;
  s << guid;
  return s.str();
}

inline std::string prefix_text(const rtps::GuidPrefix_t& prefix) {
  std::ostringstream s;
  s << prefix;
  return s.str();
}

struct Endpoint {
  std::string participant_prefix;
  bool reliable = false;
  bool transient_local = false;
};

struct TopicInfo {
  std::string type_name;
  std::map<std::string, Endpoint> writers;  // by endpoint GUID
  std::map<std::string, Endpoint> readers;
};

class DiscoveryCollector : public eprosima::fastdds::dds::DomainParticipantListener {
 public:
  void on_participant_discovery(eprosima::fastdds::dds::DomainParticipant*,
                                rtps::ParticipantDiscoveryInfo&& info) override {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string prefix = prefix_text(info.info.m_guid.guidPrefix);
    if (info.status == rtps::ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT) {
      participant_names_[prefix] = info.info.m_participantName.to_string();
    }
  }
  void on_publisher_discovery(eprosima::fastdds::dds::DomainParticipant*, rtps::WriterDiscoveryInfo&& info) override {
    note(info.info, info.status == rtps::WriterDiscoveryInfo::REMOVED_WRITER, &TopicInfo::writers);
  }
  void on_subscriber_discovery(eprosima::fastdds::dds::DomainParticipant*, rtps::ReaderDiscoveryInfo&& info) override {
    note(info.info, info.status == rtps::ReaderDiscoveryInfo::REMOVED_READER, &TopicInfo::readers);
  }

  std::string participant_name(const std::string& prefix) const {
    const auto found = participant_names_.find(prefix);
    return found == participant_names_.end() || found->second.empty() ? "?" : found->second;
  }

  /// The nodes (participant names) with a live writer on `dds_topic`, other than the
  /// participant `own_prefix` (GUID prefix text of the asking participant).
  std::vector<std::string> writers_of(const std::string& dds_topic, const std::string& own_prefix) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::string> out;
    const auto found = topics_.find(dds_topic);
    if (found == topics_.end()) return out;
    for (const auto& [guid, e] : found->second.writers) {
      if (e.participant_prefix != own_prefix) out.push_back(participant_name(e.participant_prefix));
    }
    return out;
  }

  /// One block per topic: type, then each writer and reader with its node and QoS.
  std::string report(bool verbose) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::ostringstream out;
    for (const auto& [dds_name, topic] : topics_) {
      if (topic.writers.empty() && topic.readers.empty()) continue;
      const std::string name = dds::display_name(dds_name);
      out << name << " [" << topic.type_name << "]";
      if (dds::find_topic(dds_name) == nullptr) out << " (not a project topic)";
      out << "  writers: " << topic.writers.size() << "  readers: " << topic.readers.size() << "\n";
      if (!verbose) continue;
      const auto list = [&](const char* role, const std::map<std::string, Endpoint>& endpoints) {
        for (const auto& [guid, e] : endpoints) {
          out << "    " << role << " " << participant_name(e.participant_prefix) << "  "
              << (e.reliable ? "reliable" : "best-effort") << ", "
              << (e.transient_local ? "transient-local" : "volatile") << "\n";
        }
      };
      list("writer", topic.writers);
      list("reader", topic.readers);
    }
    return out.str();
  }

 private:
  /// Adds or removes one writer or reader (`role` picks which map) of its topic.
  template <typename ProxyData>
  void note(const ProxyData& data, bool removed, std::map<std::string, Endpoint> TopicInfo::*role) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto& topic = topics_[data.topicName().to_string()];
    topic.type_name = data.typeName().to_string();
    const std::string key = guid_text(data.guid());
    if (removed) {
      (topic.*role).erase(key);
      return;
    }
    (topic.*role)[key] = Endpoint{prefix_text(data.guid().guidPrefix),
                                  data.m_qos.m_reliability.kind == eprosima::fastdds::dds::RELIABLE_RELIABILITY_QOS,
                                  data.m_qos.m_durability.kind != eprosima::fastdds::dds::VOLATILE_DURABILITY_QOS};
  }

  std::mutex mutex_;
  std::map<std::string, std::string> participant_names_;
  std::map<std::string, TopicInfo> topics_;
};

}  // namespace pmlsm::tools
