// The Foxglove server's threads without DDS: a publisher thread hands samples in while the
// network thread sends them to a real WebSocket client (websocketpp's, in-process) and a third
// thread reads the counters. Every published sample is either sent or dropped, never both or
// lost; the client receives each frame sent, in order. Run under ThreadSanitizer by
// scripts/sanitize.sh thread (the per-client queues and their locks).
#include <gtest/gtest.h>

#include <websocketpp/client.hpp>
#include <websocketpp/config/asio_no_tls_client.hpp>

#include <atomic>
#include <chrono>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "foxglove_protocol.hpp"
#include "foxglove_server.hpp"

namespace pmlsm::foxglove {
namespace {

using Client = websocketpp::client<websocketpp::config::asio_client>;
using Clock = std::chrono::steady_clock;

template <typename Predicate>
bool wait_for(Predicate done, std::chrono::milliseconds limit) {
  const auto deadline = Clock::now() + limit;
  while (!done()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

TEST(FoxgloveServerThreads, EveryPublishedSampleIsSentOrDroppedAndArrivesInOrder) {
  Channel channel;
  channel.id = 1;
  channel.topic = "/pmlsm/force_command";
  channel.schema_name = "t::Sample";
  channel.schema = "module t { struct Sample { uint32 k; }; };";
  ServerOptions options;
  options.address = "127.0.0.1";
  options.port = 0;
  options.queue_frames = 16;  // small: the publisher outruns the socket now and then
  Server server(
      options, {channel}, [](const std::string&) {}, [] {});
  server.start();

  Client client;
  client.clear_access_channels(websocketpp::log::alevel::all);
  client.clear_error_channels(websocketpp::log::elevel::all);
  client.init_asio();
  std::mutex mutex;
  std::vector<std::uint32_t> received;  // the sample numbers, in arrival order
  std::atomic<bool> opened{false};
  client.set_open_handler([&](websocketpp::connection_hdl hdl) {
    client.send(hdl, R"({"op":"subscribe","subscriptions":[{"id":7,"channelId":1}]})",
                websocketpp::frame::opcode::text);
    opened = true;
  });
  client.set_message_handler([&](websocketpp::connection_hdl, Client::message_ptr message) {
    if (message->get_opcode() != websocketpp::frame::opcode::binary) return;
    const std::string& frame = message->get_payload();
    ASSERT_EQ(frame.size(), kMessageDataHeaderBytes + 8);
    std::uint32_t k = 0;
    std::memcpy(&k, frame.data() + kMessageDataHeaderBytes + 4, sizeof k);
    std::lock_guard<std::mutex> lock(mutex);
    received.push_back(k);
  });
  websocketpp::lib::error_code error;
  Client::connection_ptr connection = client.get_connection("ws://127.0.0.1:" + std::to_string(server.port()), error);
  ASSERT_FALSE(error) << error.message();
  connection->add_subprotocol(kSubprotocol);
  client.connect(connection);
  std::thread network([&] { client.run(); });

  ASSERT_TRUE(wait_for([&] { return server.subscriber_count(1) == 1; }, std::chrono::seconds(10)));

  constexpr std::uint32_t kSamples = 20000;
  std::atomic<bool> publishing{true};
  std::thread reader([&] {  // counters and subscriber counts from a third thread meanwhile
    while (publishing) {
      const ServerCounters c = server.counters();
      EXPECT_LE(c.frames_sent + c.frames_dropped, kSamples);
      EXPECT_EQ(server.subscriber_count(1), 1u);
    }
  });
  std::thread publisher([&] {
    for (std::uint32_t k = 0; k < kSamples; ++k) {
      std::uint8_t sample[8] = {0, 1, 0, 0};  // encapsulation header, then k (LE)
      std::memcpy(sample + 4, &k, sizeof k);
      server.publish(1, k, sample, sizeof sample);
      if (k % 512 == 0) std::this_thread::yield();
    }
  });
  publisher.join();
  ASSERT_TRUE(wait_for(
      [&] {
        const ServerCounters c = server.counters();
        return c.frames_sent + c.frames_dropped == kSamples;
      },
      std::chrono::seconds(30)))
      << "sent " << server.counters().frames_sent << " dropped " << server.counters().frames_dropped;
  publishing = false;
  reader.join();
  const ServerCounters counters = server.counters();
  ASSERT_TRUE(wait_for(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return received.size() == counters.frames_sent;
      },
      std::chrono::seconds(30)));

  client.close(connection->get_handle(), websocketpp::close::status::normal, "done", error);
  server.stop();
  client.stop();
  network.join();

  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_GT(counters.frames_sent, 0u);
  for (std::size_t i = 1; i < received.size(); ++i) {
    ASSERT_LT(received[i - 1], received[i]) << "frame " << i << " out of order or repeated";
  }
}

}  // namespace
}  // namespace pmlsm::foxglove
