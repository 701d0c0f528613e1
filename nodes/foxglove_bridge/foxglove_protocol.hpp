// The Foxglove WebSocket protocol (subprotocol "foxglove.websocket.v1") as far as a live
// bridge needs it, with neither sockets nor DDS: the server's JSON messages (serverInfo,
// advertise, status), the binary MessageData frame, one client's subscriptions with the
// answer to each request, and the bounded queue of frames waiting for a client.
// Spec: https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pmlsm::foxglove {

inline constexpr const char* kSubprotocol = "foxglove.websocket.v1";

using ChannelId = std::uint32_t;
using SubscriptionId = std::uint32_t;

/// One advertised topic. Our samples are CDR with their encapsulation header and the schema is
/// the flattened IDL of the type, so encoding "cdr" with schemaEncoding "omgidl".
struct Channel {
  ChannelId id = 0;
  std::string topic;        // "/pmlsm/motor_feedback"
  std::string schema_name;  // "pmlsm_msgs::msg::MotorFeedback"
  std::string schema;       // IDL text defining schema_name
  std::string encoding = "cdr";
  std::string schema_encoding = "omgidl";
};

enum class StatusLevel : int { kInfo = 0, kWarning = 1, kError = 2 };

/// Close codes (RFC 6455, 7.4.1) the bridge ends a misbehaving client's connection with.
inline constexpr std::uint16_t kCloseUnsupportedData = 1003;  // a binary frame: we accept none
inline constexpr std::uint16_t kCloseInvalidPayload = 1007;   // text that is not a valid request
inline constexpr std::uint16_t kClosePolicyViolation = 1008;  // too many bad requests

std::string server_info_json(const std::string& name, const std::string& session_id,
                             const std::map<std::string, std::string>& metadata);
std::string advertise_json(const std::vector<Channel>& channels);
std::string status_json(StatusLevel level, const std::string& message);

/// MessageData header: opcode 0x01, uint32 LE subscription id, uint64 LE receive time [ns].
inline constexpr std::size_t kMessageDataHeaderBytes = 1 + 4 + 8;
inline constexpr std::uint8_t kMessageDataOpcode = 0x01;

/// The binary MessageData frame for one sample's payload.
std::string message_data_frame(SubscriptionId subscription, std::uint64_t receive_time_ns, const std::uint8_t* payload,
                               std::size_t payload_bytes);

/// What the server does after one client message: texts to send back (status messages), and
/// whether to end the connection (with code and reason) because the input was malformed.
struct SessionReply {
  std::vector<std::string> texts;
  std::optional<std::pair<std::uint16_t, std::string>> close;  // code, reason
  std::vector<ChannelId> channels_subscribed;                  // newly subscribed by this client
  std::vector<ChannelId> channels_unsubscribed;                // no longer subscribed by this client
};

/// One client's protocol state: its subscriptions and how many bad requests it sent. Not
/// thread-safe; the server guards it.
///
/// Malformed input (text that is not a JSON object with a string "op", a subscribe or
/// unsubscribe with wrong field types, any binary frame: we declare neither clientPublish nor
/// services) is answered with an error status and the connection is closed. Well-formed
/// requests we cannot honour (unknown or unsupported op, unknown channel, a subscription id in
/// use, a channel already subscribed, an unknown subscription id) get a status and the
/// connection stays, as the spec allows ("the server may ignore ... and send an error status"),
/// up to kMaxBadRequests per connection: then the client is closed as a flood.
class ClientSession {
 public:
  static constexpr std::uint64_t kMaxBadRequests = 32;

  /// `channel_ids`: the advertised channels.
  explicit ClientSession(std::vector<ChannelId> channel_ids);

  SessionReply on_text(std::string_view text);
  SessionReply on_binary(const std::uint8_t* data, std::size_t bytes);

  /// The client's subscription to `channel`, if it has one.
  std::optional<SubscriptionId> subscription_for(ChannelId channel) const;
  std::vector<ChannelId> subscribed_channels() const;
  std::uint64_t bad_requests() const { return bad_requests_; }

 private:
  SessionReply subscribe(const nlohmann::json& request);
  SessionReply unsubscribe(const nlohmann::json& request);
  SessionReply malformed(std::uint16_t close_code, const std::string& why);
  void reject(SessionReply& reply, StatusLevel level, const std::string& why);
  bool is_channel(ChannelId id) const;

  std::vector<ChannelId> channel_ids_;
  std::map<SubscriptionId, ChannelId> channel_of_subscription_;
  std::map<ChannelId, SubscriptionId> subscription_of_channel_;
  std::uint64_t bad_requests_ = 0;
};

/// Frames waiting for one client, at most `capacity`: when full the oldest is dropped (a live
/// view wants the newest data) and counted.
class FrameQueue {
 public:
  explicit FrameQueue(std::size_t capacity);
  /// @return false when a frame had to be dropped to make room.
  bool push(std::string frame);
  /// Moves every queued frame out, oldest first.
  std::deque<std::string> take_all();
  std::size_t size() const { return frames_.size(); }
  std::uint64_t dropped() const { return dropped_; }

 private:
  std::size_t capacity_;
  std::deque<std::string> frames_;
  std::uint64_t dropped_ = 0;
};

}  // namespace pmlsm::foxglove
