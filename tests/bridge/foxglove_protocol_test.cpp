// The Foxglove protocol pieces of the bridge without sockets or DDS: the server's messages as
// the spec words them, the MessageData frame byte by byte, one client's subscriptions and the
// answers to bad requests, the bounded frame queue.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "foxglove_protocol.hpp"

namespace pmlsm::foxglove {
namespace {

using nlohmann::json;

json parse(const std::string& text) { return json::parse(text); }

json only_status(const SessionReply& reply) {
  EXPECT_EQ(reply.texts.size(), 1u);
  if (reply.texts.empty()) return json();
  const json status = parse(reply.texts.front());
  EXPECT_EQ(status["op"], "status");
  return status;
}

TEST(FoxgloveMessages, ServerInfoDeclaresNoCapabilities) {
  const json info = parse(server_info_json("bridge", "42", {{"dds_domain", "7"}}));
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["name"], "bridge");
  EXPECT_TRUE(info["capabilities"].is_array());
  EXPECT_TRUE(info["capabilities"].empty());
  EXPECT_FALSE(info.contains("supportedEncodings")) << "only for client publishing and services (spec)";
  EXPECT_EQ(info["metadata"]["dds_domain"], "7");
  EXPECT_EQ(info["sessionId"], "42");
}

TEST(FoxgloveMessages, AdvertiseCarriesCdrChannelsWithOmgidlSchemas) {
  Channel c;
  c.id = 3;
  c.topic = "/pmlsm/motor_feedback";
  c.schema_name = "pmlsm_msgs::msg::MotorFeedback";
  c.schema = "module pmlsm_msgs { module msg { struct MotorFeedback { double x; }; }; };";
  const json advertise = parse(advertise_json({c}));
  EXPECT_EQ(advertise["op"], "advertise");
  ASSERT_EQ(advertise["channels"].size(), 1u);
  const json& ch = advertise["channels"][0];
  EXPECT_EQ(ch["id"], 3);
  EXPECT_EQ(ch["topic"], "/pmlsm/motor_feedback");
  EXPECT_EQ(ch["encoding"], "cdr");
  EXPECT_EQ(ch["schemaName"], "pmlsm_msgs::msg::MotorFeedback");
  EXPECT_EQ(ch["schema"], c.schema);
  EXPECT_EQ(ch["schemaEncoding"], "omgidl");
}

TEST(FoxgloveMessages, StatusHasLevelAndMessage) {
  const json status = parse(status_json(StatusLevel::kWarning, "careful"));
  EXPECT_EQ(status["op"], "status");
  EXPECT_EQ(status["level"], 1);
  EXPECT_EQ(status["message"], "careful");
}

TEST(FoxgloveMessages, MessageDataIsOpcodeSubscriptionTimeAndPayloadLittleEndian) {
  const std::vector<std::uint8_t> payload{0x00, 0x01, 0x00, 0x00, 0xAB};
  const std::string frame = message_data_frame(0x04030201U, 0x0807060504030201ULL, payload.data(), payload.size());
  const std::vector<std::uint8_t> expected{0x01,                                            // opcode
                                           0x01, 0x02, 0x03, 0x04,                          // subscription id
                                           0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08,  // time [ns]
                                           0x00, 0x01, 0x00, 0x00, 0xAB};                   // payload
  ASSERT_EQ(frame.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(static_cast<std::uint8_t>(frame[i]), expected[i]) << "byte " << i;
  }
}

TEST(ClientSession, SubscribesAndUnsubscribes) {
  ClientSession session({1, 2, 3});
  SessionReply r =
      session.on_text(R"({"op":"subscribe","subscriptions":[{"id":10,"channelId":1},{"id":11,"channelId":3}]})");
  EXPECT_TRUE(r.texts.empty());
  EXPECT_FALSE(r.close);
  EXPECT_EQ(r.channels_subscribed, (std::vector<ChannelId>{1, 3}));
  EXPECT_EQ(session.subscription_for(1), std::optional<SubscriptionId>(10));
  EXPECT_EQ(session.subscription_for(3), std::optional<SubscriptionId>(11));
  EXPECT_FALSE(session.subscription_for(2));

  r = session.on_text(R"({"op":"unsubscribe","subscriptionIds":[10]})");
  EXPECT_TRUE(r.texts.empty());
  EXPECT_EQ(r.channels_unsubscribed, (std::vector<ChannelId>{1}));
  EXPECT_FALSE(session.subscription_for(1));
  EXPECT_EQ(session.subscribed_channels(), (std::vector<ChannelId>{3}));
  // The id is free again after unsubscribing (spec).
  r = session.on_text(R"({"op":"subscribe","subscriptions":[{"id":10,"channelId":2}]})");
  EXPECT_EQ(r.channels_subscribed, (std::vector<ChannelId>{2}));
  EXPECT_EQ(session.bad_requests(), 0u);
}

TEST(ClientSession, RequestsItCannotHonourGetAStatusAndKeepTheConnection) {
  ClientSession session({1, 2});
  ASSERT_TRUE(session.on_text(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1}]})").texts.empty());

  struct Case {
    const char* request;
    int level;
    const char* says;
  };
  const Case cases[] = {
      {R"({"op":"subscribe","subscriptions":[{"id":2,"channelId":99}]})", 1, "unknown channel 99"},
      {R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":2}]})", 2, "subscription id 1 is in use"},
      {R"({"op":"subscribe","subscriptions":[{"id":3,"channelId":1}]})", 1, "already subscribed"},
      {R"({"op":"unsubscribe","subscriptionIds":[77]})", 1, "unknown subscription id 77"},
      {R"({"op":"frobnicate"})", 2, "unknown op 'frobnicate'"},
      {R"({"op":"getParameters","parameterNames":[]})", 2, "not supported"},
  };
  std::uint64_t expected_bad = 0;
  for (const auto& c : cases) {
    const SessionReply r = session.on_text(c.request);
    const json status = only_status(r);
    EXPECT_EQ(status["level"], c.level) << c.request;
    EXPECT_NE(status["message"].get<std::string>().find(c.says), std::string::npos) << status.dump();
    EXPECT_FALSE(r.close) << c.request;
    EXPECT_TRUE(r.channels_subscribed.empty());
    EXPECT_EQ(session.bad_requests(), ++expected_bad);
  }
  EXPECT_EQ(session.subscription_for(1), std::optional<SubscriptionId>(1)) << "nothing changed";
  EXPECT_FALSE(session.subscription_for(2));
}

TEST(ClientSession, MalformedInputIsAnsweredAndClosed) {
  struct Case {
    const char* request;
    const char* says;
  };
  const Case cases[] = {
      {"this is not json {", "not JSON"},
      {"[1,2,3]", "not a JSON object"},
      {R"({"subscriptions":[]})", "no string field 'op'"},
      {R"({"op":7})", "no string field 'op'"},
      {R"({"op":"subscribe"})", "'subscriptions' is not an array"},
      {R"({"op":"subscribe","subscriptions":[{"id":"x","channelId":1}]})", "is not {id: uint32, channelId: uint32}"},
      {R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})", "is not {id: uint32, channelId: uint32}"},
      {R"({"op":"subscribe","subscriptions":[{"id":4294967296,"channelId":1}]})", "is not {id: uint32"},
      {R"({"op":"unsubscribe","subscriptionIds":[1.5]})", "not an array of uint32"},
  };
  for (const auto& c : cases) {
    ClientSession session({1});
    const SessionReply r = session.on_text(c.request);
    const json status = only_status(r);
    EXPECT_EQ(status["level"], 2) << c.request;
    EXPECT_NE(status["message"].get<std::string>().find(c.says), std::string::npos) << status.dump();
    ASSERT_TRUE(r.close) << c.request;
    EXPECT_EQ(r.close->first, kCloseInvalidPayload);
    EXPECT_TRUE(r.channels_subscribed.empty()) << "a malformed request changes nothing";
    EXPECT_EQ(session.bad_requests(), 1u);
  }
}

TEST(ClientSession, AMalformedEntryCancelsTheWholeSubscribe) {
  ClientSession session({1, 2});
  const SessionReply r =
      session.on_text(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1},{"id":2,"channelId":"two"}]})");
  ASSERT_TRUE(r.close);
  EXPECT_TRUE(r.channels_subscribed.empty());
  EXPECT_FALSE(session.subscription_for(1));
}

TEST(ClientSession, BinaryMessagesAreNotSupported) {
  ClientSession session({1});
  const std::uint8_t client_message_data[] = {0x01, 0x01, 0x00, 0x00, 0x00, 0xFF};
  const SessionReply r = session.on_binary(client_message_data, sizeof client_message_data);
  const json status = only_status(r);
  EXPECT_EQ(status["level"], 2);
  EXPECT_NE(status["message"].get<std::string>().find("binary client message (opcode 1)"), std::string::npos);
  ASSERT_TRUE(r.close);
  EXPECT_EQ(r.close->first, kCloseUnsupportedData);
}

TEST(ClientSession, AFloodOfBadRequestsIsClosed) {
  ClientSession session({1});
  SessionReply r;
  std::uint64_t sent = 0;
  while (!r.close && sent < 2 * ClientSession::kMaxBadRequests) {
    r = session.on_text(R"({"op":"nope"})");
    ++sent;
  }
  ASSERT_TRUE(r.close);
  EXPECT_EQ(sent, ClientSession::kMaxBadRequests);
  EXPECT_EQ(r.close->first, kClosePolicyViolation);
}

TEST(ClientSession, QuotesOfClientTextAreShortAndValidUtf8) {
  ClientSession session({1});
  // 'e' with acute accent, two bytes each: the 40-byte excerpt cuts one in half.
  std::string text = "x";
  for (int i = 0; i < 40; ++i) text += "\xC3\xA9";
  const SessionReply r = session.on_text(text);
  const json status = only_status(r);
  EXPECT_LT(status["message"].get<std::string>().size(), 120u);
}

TEST(FrameQueue, KeepsTheNewestAndCountsWhatItDrops) {
  FrameQueue queue(3);
  EXPECT_TRUE(queue.push("a"));
  EXPECT_TRUE(queue.push("b"));
  EXPECT_TRUE(queue.push("c"));
  EXPECT_FALSE(queue.push("d"));
  EXPECT_FALSE(queue.push("e"));
  EXPECT_EQ(queue.size(), 3u);
  EXPECT_EQ(queue.dropped(), 2u);
  const auto frames = queue.take_all();
  EXPECT_EQ(std::vector<std::string>(frames.begin(), frames.end()), (std::vector<std::string>{"c", "d", "e"}));
  EXPECT_EQ(queue.size(), 0u);
  EXPECT_TRUE(queue.push("f"));
}

}  // namespace
}  // namespace pmlsm::foxglove
