// The ROS 2 graph of a process: which nodes its DDS participant holds and which of the
// participant's writers and readers belong to which node, announced on `ros_discovery_info` as
// rclcpp does (rmw_dds_common's ParticipantEntitiesInfo, one sample a participant, TRANSIENT_LOCAL
// so a tool that starts later gets it). `ros2 node list` and `ros2 node info` read it; without it
// a ROS 2 tool sees our topics but no node.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/rtps/common/Guid.h>

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "pmlsm/security/implicit_topics.hpp"

namespace pmlsm::dds {

/// The DDS topic ROS 2 announces its graph on (granted to every secure identity).
using security::kRos2GraphTopic;

/// `name` as a ROS 2 node name: letters, digits and '_' (anything else becomes '_'), not
/// starting with a digit (then '_' before it); "" stays "" (a participant with no node).
std::string ros2_node_name(std::string_view name);

/// A ROS 2 Gid (16 bytes, Jazzy's layout): the GUID's prefix, then its entity id.
std::array<std::uint8_t, 16> ros2_gid(const eprosima::fastrtps::rtps::GUID_t& guid);

/// What a participant announces: its nodes, each with its endpoints. Pure, so it is tested without
/// DDS; GraphAnnouncer publishes it.
class Ros2Graph {
 public:
  struct Node {
    std::string name;
    std::vector<eprosima::fastrtps::rtps::GUID_t> readers;
    std::vector<eprosima::fastrtps::rtps::GUID_t> writers;
    bool live = true;  ///< false once removed (indices stay valid)
  };
  /// Adds the node `name` (ros2_node_name applied); returns its index. An empty name adds none
  /// and returns -1: endpoints of that index are not announced.
  int add_node(std::string_view name);
  void add_endpoint(int node, const eprosima::fastrtps::rtps::GUID_t& guid, bool writer);
  void remove_endpoint(const eprosima::fastrtps::rtps::GUID_t& guid);
  /// The node is no longer announced (a component that ended).
  void remove_node(int node);
  /// Every node added, removed ones with live == false.
  const std::vector<Node>& nodes() const { return nodes_; }

 private:
  std::vector<Node> nodes_;
};

/// Publishes a participant's Ros2Graph on `ros_discovery_info` whenever it changes, and again
/// after a reader of the topic matched (at once, then 0.2 s, 1 s and 3 s later): a tool that does
/// not ask for the writer's kept sample (@foxglove/rtps takes only what is sent once it has taken
/// the writer's announcement, which may come after the match) still gets it. Those writes are made
/// by a thread of its own, not in Fast DDS's match callback, whose thread also carries the
/// participant's discovery. Thread-safe.
class GraphAnnouncer final : private eprosima::fastdds::dds::DataWriterListener {
 public:
  /// Creates the writer. A secure participant whose permissions lack the topic (a keystore made
  /// before it was granted) gets no writer: a warning on stderr, and nothing is announced.
  /// @throws std::runtime_error when Fast DDS refuses the type or the topic.
  GraphAnnouncer(eprosima::fastdds::dds::DomainParticipant& participant, eprosima::fastdds::dds::Publisher& publisher,
                 bool secure);
  ~GraphAnnouncer() override;
  GraphAnnouncer(const GraphAnnouncer&) = delete;
  GraphAnnouncer& operator=(const GraphAnnouncer&) = delete;

  int add_node(std::string_view name);
  void add_endpoint(int node, const eprosima::fastrtps::rtps::GUID_t& guid, bool writer);
  void remove_endpoint(const eprosima::fastrtps::rtps::GUID_t& guid);
  void remove_node(int node);
  /// False when the permissions refused the writer.
  bool announcing() const { return writer_ != nullptr; }

 private:
  void on_publication_matched(eprosima::fastdds::dds::DataWriter* writer,
                              const eprosima::fastdds::dds::PublicationMatchedStatus& info) override;
  void publish_locked();
  /// Writes the graph again after each match (kRepublishAfter), until the destructor.
  void republish_on_match();
  static constexpr std::array<std::chrono::milliseconds, 4> kRepublishAfter{
      std::chrono::milliseconds(0), std::chrono::milliseconds(200), std::chrono::milliseconds(1000),
      std::chrono::milliseconds(3000)};

  eprosima::fastdds::dds::DomainParticipant& participant_;
  eprosima::fastdds::dds::DataWriter* writer_ = nullptr;
  /// Held while the graph changes and while it is written.
  std::mutex mutex_;
  Ros2Graph graph_;
  /// The match callback's: Fast DDS calls it holding the writer's lock, which a write takes too,
  /// so it must never wait for mutex_ (held across writes).
  std::mutex signal_mutex_;
  std::condition_variable matched_;
  /// When the last reader matched (writes are due kRepublishAfter from it); empty: none yet.
  std::optional<std::chrono::steady_clock::time_point> matched_at_;
  bool stopping_ = false;
  std::thread republisher_;
};

}  // namespace pmlsm::dds
