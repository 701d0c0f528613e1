#include "pmlsm/dds/ros2_graph.hpp"

#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "ParticipantEntitiesInfoPubSubTypes.h"
#include "pmlsm/dds/ros2_names.hpp"

namespace pmlsm::dds {

std::string ros2_node_name(std::string_view name) {
  std::string out;
  out.reserve(name.size() + 1);
  for (const char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    out += ok ? c : '_';
  }
  if (!out.empty() && out.front() >= '0' && out.front() <= '9') out.insert(out.begin(), '_');
  return out;
}

std::array<std::uint8_t, 16> ros2_gid(const eprosima::fastrtps::rtps::GUID_t& guid) {
  std::array<std::uint8_t, 16> gid{};
  std::copy(std::begin(guid.guidPrefix.value), std::end(guid.guidPrefix.value), gid.begin());
  std::copy(std::begin(guid.entityId.value), std::end(guid.entityId.value), gid.begin() + 12);
  return gid;
}

int Ros2Graph::add_node(std::string_view name) {
  std::string ros_name = ros2_node_name(name);
  if (ros_name.empty()) return -1;
  nodes_.push_back(Node{std::move(ros_name), {}, {}, true});
  return static_cast<int>(nodes_.size()) - 1;
}

void Ros2Graph::add_endpoint(int node, const eprosima::fastrtps::rtps::GUID_t& guid, bool writer) {
  if (node < 0 || node >= static_cast<int>(nodes_.size())) return;
  Node& n = nodes_[static_cast<std::size_t>(node)];
  if (n.live) (writer ? n.writers : n.readers).push_back(guid);
}

void Ros2Graph::remove_endpoint(const eprosima::fastrtps::rtps::GUID_t& guid) {
  for (Node& n : nodes_) {
    n.readers.erase(std::remove(n.readers.begin(), n.readers.end(), guid), n.readers.end());
    n.writers.erase(std::remove(n.writers.begin(), n.writers.end(), guid), n.writers.end());
  }
}

void Ros2Graph::remove_node(int node) {
  if (node < 0 || node >= static_cast<int>(nodes_.size())) return;
  Node& n = nodes_[static_cast<std::size_t>(node)];
  n.live = false;
  n.readers.clear();
  n.writers.clear();
}

namespace {

rmw_dds_common::msg::Gid to_gid(const eprosima::fastrtps::rtps::GUID_t& guid) {
  rmw_dds_common::msg::Gid gid;
  gid.data(ros2_gid(guid));
  return gid;
}

}  // namespace

GraphAnnouncer::GraphAnnouncer(eprosima::fastdds::dds::DomainParticipant& participant,
                               eprosima::fastdds::dds::Publisher& publisher, bool secure)
    : participant_(participant) {
  using eprosima::fastrtps::types::ReturnCode_t;
  eprosima::fastdds::dds::TypeSupport type(new rmw_dds_common::msg::ParticipantEntitiesInfoPubSubType());
  type->setName(ros2_type_name(type->getName()).c_str());
  if (type.register_type(&participant) != ReturnCode_t::RETCODE_OK) {
    throw std::runtime_error("cannot register type '" + type.get_type_name() + "'");
  }
  auto* topic =
      participant.create_topic(kRos2GraphTopic, type.get_type_name(), eprosima::fastdds::dds::TOPIC_QOS_DEFAULT);
  if (topic == nullptr) throw std::runtime_error(std::string("cannot create topic '") + kRos2GraphTopic + "'");
  // rmw's QoS for the topic: reliable, the newest sample kept for late joiners.
  eprosima::fastdds::dds::DataWriterQos qos = eprosima::fastdds::dds::DATAWRITER_QOS_DEFAULT;
  qos.reliability().kind = eprosima::fastdds::dds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = eprosima::fastdds::dds::TRANSIENT_LOCAL_DURABILITY_QOS;
  qos.history().kind = eprosima::fastdds::dds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 1;
  qos.data_sharing().off();
  writer_ = publisher.create_datawriter(topic, qos, this);
  if (writer_ == nullptr && !secure) {
    throw std::runtime_error(std::string("cannot create the writer of '") + kRos2GraphTopic + "'");
  }
  if (writer_ != nullptr) republisher_ = std::thread([this] { republish_on_match(); });
  if (writer_ == nullptr) {
    std::fprintf(stderr,
                 "%s: the permissions do not grant '%s' (a keystore made before it was granted: `pmlsm security "
                 "update-permissions`): ROS 2 tools will not list this process's nodes\n",
                 participant.get_qos().name().c_str(), kRos2GraphTopic);
  }
}

int GraphAnnouncer::add_node(std::string_view name) {
  std::lock_guard<std::mutex> lock(mutex_);
  const int node = graph_.add_node(name);
  publish_locked();
  return node;
}

void GraphAnnouncer::add_endpoint(int node, const eprosima::fastrtps::rtps::GUID_t& guid, bool writer) {
  std::lock_guard<std::mutex> lock(mutex_);
  graph_.add_endpoint(node, guid, writer);
  publish_locked();
}

void GraphAnnouncer::remove_endpoint(const eprosima::fastrtps::rtps::GUID_t& guid) {
  std::lock_guard<std::mutex> lock(mutex_);
  graph_.remove_endpoint(guid);
  publish_locked();
}

void GraphAnnouncer::remove_node(int node) {
  std::lock_guard<std::mutex> lock(mutex_);
  graph_.remove_node(node);
  publish_locked();
}

GraphAnnouncer::~GraphAnnouncer() {
  // The writer outlives this (its participant deletes it): no match may call back into it.
  if (writer_ != nullptr) writer_->set_listener(nullptr);
  {
    std::lock_guard<std::mutex> lock(signal_mutex_);
    stopping_ = true;
  }
  matched_.notify_all();
  if (republisher_.joinable()) republisher_.join();
}

void GraphAnnouncer::on_publication_matched(eprosima::fastdds::dds::DataWriter* /*writer*/,
                                            const eprosima::fastdds::dds::PublicationMatchedStatus& info) {
  if (info.current_count_change <= 0) return;
  {
    std::lock_guard<std::mutex> lock(signal_mutex_);
    matched_at_ = std::chrono::steady_clock::now();
  }
  matched_.notify_all();
}

void GraphAnnouncer::republish_on_match() {
  std::optional<std::chrono::steady_clock::time_point> from;  // the match being served
  std::size_t next = 0;                                       // its next write in kRepublishAfter
  for (;;) {
    {
      std::unique_lock<std::mutex> signal(signal_mutex_);
      if (matched_at_ != from) {  // a new match: its writes start over
        from = matched_at_;
        next = 0;
      }
      if (!from || next >= kRepublishAfter.size()) {
        matched_.wait(signal, [&] { return stopping_ || matched_at_ != from; });
        if (stopping_) return;
        continue;
      }
      const auto due = *from + kRepublishAfter[next];
      if (matched_.wait_until(signal, due, [&] { return stopping_ || matched_at_ != from; })) {
        if (stopping_) return;
        continue;
      }
      ++next;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    publish_locked();
  }
}

void GraphAnnouncer::publish_locked() {
  if (writer_ == nullptr) return;
  rmw_dds_common::msg::ParticipantEntitiesInfo info;
  info.gid(to_gid(participant_.guid()));
  for (const Ros2Graph::Node& n : graph_.nodes()) {
    if (!n.live) continue;
    rmw_dds_common::msg::NodeEntitiesInfo node;
    node.node_namespace("/");
    node.node_name(n.name);
    for (const auto& g : n.readers) node.reader_gid_seq().push_back(to_gid(g));
    for (const auto& g : n.writers) node.writer_gid_seq().push_back(to_gid(g));
    info.node_entities_info_seq().push_back(std::move(node));
  }
  writer_->write(&info);
}

}  // namespace pmlsm::dds
