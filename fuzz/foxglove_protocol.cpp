// The Foxglove WebSocket protocol's client messages (ClientSession::on_text / on_binary): one
// client's session over the bridge's channels. Input: one message per line; a line starting with
// 'B' is a binary frame (the rest of the line), any other a text frame. The session must answer
// every message (status texts, a close) and keep its two maps consistent.
#include <cstdlib>

#include "foxglove_protocol.hpp"
#include "fuzz_support.hpp"

namespace pmlsm::fuzz::foxglove_protocol {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::foxglove;
  const std::string text = as_text(data, size);
  ClientSession session({1, 2, 3, 7});
  FrameQueue queue(4);
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + begin, end - begin);
    const SessionReply reply =
        !line.empty() && line[0] == 'B'
            ? session.on_binary(reinterpret_cast<const std::uint8_t*>(line.data()) + 1, line.size() - 1)
            : session.on_text(line);
    for (const std::string& status : reply.texts) queue.push(status);
    for (const ChannelId channel : reply.channels_subscribed) {
      const std::optional<SubscriptionId> subscription = session.subscription_for(channel);
      if (!subscription) std::abort();  // reported as subscribed, but no subscription
      queue.push(message_data_frame(*subscription, 1, reinterpret_cast<const std::uint8_t*>(line.data()), line.size()));
    }
    for (const ChannelId channel : reply.channels_unsubscribed) {
      if (session.subscription_for(channel)) std::abort();  // reported as unsubscribed, but still there
    }
    if (reply.close) break;
    begin = end + 1;
  }
  session.subscribed_channels();
  queue.take_all();
  return 0;
}

}  // namespace pmlsm::fuzz::foxglove_protocol
