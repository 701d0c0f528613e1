#include "foxglove_protocol.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <limits>

namespace pmlsm::foxglove {

using nlohmann::json;

namespace {

// Text from clients may be cut mid-character when quoted; replace rather than throw.
std::string to_text(const json& message) { return message.dump(-1, ' ', false, json::error_handler_t::replace); }

/// The start of a client's text, for quoting it in a status.
std::string excerpt(std::string_view text) {
  constexpr std::size_t kMaxQuotedChars = 40;
  if (text.size() <= kMaxQuotedChars) return std::string(text);
  return std::string(text.substr(0, kMaxQuotedChars)) + "...";
}

bool is_uint32(const json& value) {
  return value.is_number_unsigned() && value.get<std::uint64_t>() <= std::numeric_limits<std::uint32_t>::max();
}

void put_le(std::string& out, std::size_t at, std::uint64_t value, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) out[at + i] = static_cast<char>((value >> (8 * i)) & 0xFFU);
}

// Ops of the spec that need a capability this server does not declare.
constexpr const char* kUnsupportedOps[] = {"advertise",
                                           "unadvertise",
                                           "getParameters",
                                           "setParameters",
                                           "subscribeParameterUpdates",
                                           "unsubscribeParameterUpdates",
                                           "subscribeConnectionGraph",
                                           "unsubscribeConnectionGraph",
                                           "fetchAsset"};

}  // namespace

std::string server_info_json(const std::string& name, const std::string& session_id,
                             const std::map<std::string, std::string>& metadata) {
  // No capabilities: the bridge only streams. supportedEncodings is only for client publishing
  // and services (spec), so it is left out.
  json info{{"op", "serverInfo"},
            {"name", name},
            {"capabilities", json::array()},
            {"metadata", metadata},
            {"sessionId", session_id}};
  return to_text(info);
}

std::string advertise_json(const std::vector<Channel>& channels) {
  json list = json::array();
  for (const auto& c : channels) {
    list.push_back({{"id", c.id},
                    {"topic", c.topic},
                    {"encoding", c.encoding},
                    {"schemaName", c.schema_name},
                    {"schema", c.schema},
                    {"schemaEncoding", c.schema_encoding}});
  }
  return to_text(json{{"op", "advertise"}, {"channels", list}});
}

std::string status_json(StatusLevel level, const std::string& message) {
  return to_text(json{{"op", "status"}, {"level", static_cast<int>(level)}, {"message", message}});
}

std::string message_data_frame(SubscriptionId subscription, std::uint64_t receive_time_ns, const std::uint8_t* payload,
                               std::size_t payload_bytes) {
  std::string frame(kMessageDataHeaderBytes + payload_bytes, '\0');
  frame[0] = static_cast<char>(kMessageDataOpcode);
  put_le(frame, 1, subscription, 4);
  put_le(frame, 5, receive_time_ns, 8);
  if (payload_bytes > 0) std::memcpy(&frame[kMessageDataHeaderBytes], payload, payload_bytes);
  return frame;
}

ClientSession::ClientSession(std::vector<ChannelId> channel_ids) : channel_ids_(std::move(channel_ids)) {
  std::sort(channel_ids_.begin(), channel_ids_.end());
}

bool ClientSession::is_channel(ChannelId id) const {
  return std::binary_search(channel_ids_.begin(), channel_ids_.end(), id);
}

std::optional<SubscriptionId> ClientSession::subscription_for(ChannelId channel) const {
  const auto found = subscription_of_channel_.find(channel);
  if (found == subscription_of_channel_.end()) return std::nullopt;
  return found->second;
}

std::vector<ChannelId> ClientSession::subscribed_channels() const {
  std::vector<ChannelId> out;
  for (const auto& [channel, subscription] : subscription_of_channel_) out.push_back(channel);
  return out;
}

void ClientSession::reject(SessionReply& reply, StatusLevel level, const std::string& why) {
  ++bad_requests_;
  reply.texts.push_back(status_json(level, why));
  if (bad_requests_ >= kMaxBadRequests && !reply.close) {
    reply.texts.push_back(
        status_json(StatusLevel::kError, "too many bad requests (" + std::to_string(bad_requests_) + "): closing"));
    reply.close = std::make_pair(kClosePolicyViolation, std::string("too many bad requests"));
  }
}

SessionReply ClientSession::malformed(std::uint16_t close_code, const std::string& why) {
  ++bad_requests_;
  SessionReply reply;
  reply.texts.push_back(status_json(StatusLevel::kError, why + "; closing the connection"));
  reply.close = std::make_pair(close_code, why);
  return reply;
}

SessionReply ClientSession::on_binary(const std::uint8_t* data, std::size_t bytes) {
  const std::string opcode = bytes > 0 ? std::to_string(static_cast<unsigned>(data[0])) : std::string("none");
  return malformed(kCloseUnsupportedData,
                   "binary client message (opcode " + opcode +
                       ") not supported: the server declares neither clientPublish nor services");
}

SessionReply ClientSession::on_text(std::string_view text) {
  const json request = json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  if (request.is_discarded()) return malformed(kCloseInvalidPayload, "request is not JSON: '" + excerpt(text) + "'");
  if (!request.is_object())
    return malformed(kCloseInvalidPayload, "request is not a JSON object: '" + excerpt(text) + "'");
  const auto op = request.find("op");
  if (op == request.end() || !op->is_string()) {
    return malformed(kCloseInvalidPayload, "request has no string field 'op': '" + excerpt(text) + "'");
  }
  const std::string& name = op->get_ref<const std::string&>();
  if (name == "subscribe") return subscribe(request);
  if (name == "unsubscribe") return unsubscribe(request);
  SessionReply reply;
  const bool in_spec =
      std::find(std::begin(kUnsupportedOps), std::end(kUnsupportedOps), name) != std::end(kUnsupportedOps);
  reject(reply, StatusLevel::kError,
         in_spec ? "op '" + excerpt(name) + "' not supported: the server declares no capability for it"
                 : "unknown op '" + excerpt(name) + "'");
  return reply;
}

SessionReply ClientSession::subscribe(const json& request) {
  const auto list = request.find("subscriptions");
  if (list == request.end() || !list->is_array()) {
    return malformed(kCloseInvalidPayload, "subscribe: 'subscriptions' is not an array");
  }
  // Check the whole request before applying any of it: a malformed one changes nothing.
  for (const auto& item : *list) {
    if (!item.is_object() || !item.contains("id") || !item.contains("channelId") || !is_uint32(item["id"]) ||
        !is_uint32(item["channelId"])) {
      return malformed(kCloseInvalidPayload,
                       "subscribe: entry " + excerpt(to_text(item)) + " is not {id: uint32, channelId: uint32}");
    }
  }
  SessionReply reply;
  for (const auto& item : *list) {
    const auto id = item["id"].get<SubscriptionId>();
    const auto channel = item["channelId"].get<ChannelId>();
    if (!is_channel(channel)) {
      reject(reply, StatusLevel::kWarning,
             "subscribe: unknown channel " + std::to_string(channel) + " (subscription " + std::to_string(id) + ")");
    } else if (channel_of_subscription_.count(id) != 0) {
      reject(reply, StatusLevel::kError, "subscribe: subscription id " + std::to_string(id) + " is in use");
    } else if (const auto existing = subscription_for(channel)) {
      reject(reply, StatusLevel::kWarning,
             "subscribe: channel " + std::to_string(channel) + " is already subscribed as subscription " +
                 std::to_string(*existing));
    } else {
      channel_of_subscription_[id] = channel;
      subscription_of_channel_[channel] = id;
      reply.channels_subscribed.push_back(channel);
    }
    if (reply.close) break;
  }
  return reply;
}

SessionReply ClientSession::unsubscribe(const json& request) {
  const auto list = request.find("subscriptionIds");
  if (list == request.end() || !list->is_array() ||
      !std::all_of(list->begin(), list->end(), [](const json& v) { return is_uint32(v); })) {
    return malformed(kCloseInvalidPayload, "unsubscribe: 'subscriptionIds' is not an array of uint32");
  }
  SessionReply reply;
  for (const auto& item : *list) {
    const auto id = item.get<SubscriptionId>();
    const auto found = channel_of_subscription_.find(id);
    if (found == channel_of_subscription_.end()) {
      reject(reply, StatusLevel::kWarning, "unsubscribe: unknown subscription id " + std::to_string(id));
      if (reply.close) break;
      continue;
    }
    reply.channels_unsubscribed.push_back(found->second);
    subscription_of_channel_.erase(found->second);
    channel_of_subscription_.erase(found);
  }
  return reply;
}

FrameQueue::FrameQueue(std::size_t capacity) : capacity_(std::max<std::size_t>(capacity, 1)) {}

bool FrameQueue::push(std::string frame) {
  bool kept_all = true;
  if (frames_.size() >= capacity_) {
    frames_.pop_front();
    ++dropped_;
    kept_all = false;
  }
  frames_.push_back(std::move(frame));
  return kept_all;
}

std::deque<std::string> FrameQueue::take_all() {
  std::deque<std::string> out;
  out.swap(frames_);
  return out;
}

}  // namespace pmlsm::foxglove
