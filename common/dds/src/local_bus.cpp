#include "pmlsm/dds/local_bus.hpp"

namespace pmlsm::dds {

void LocalBus::recount(const LocalTopicBase& topic) {
  for (auto& entry : trackers_) {
    if (entry.topic == &topic) entry.remote->recount();
  }
}

void LocalBus::remove_owner(const void* owner) {
  std::vector<LocalTopicBase*> touched;
  for (auto& entry : readers_) {
    if (entry.owner != owner) continue;
    entry.detach();
    std::lock_guard<std::mutex> lock(entry.topic->mutex_);
    auto& handles = entry.topic->reader_handles_;
    const eprosima::fastrtps::rtps::InstanceHandle_t handle(entry.guid);
    handles.erase(std::remove(handles.begin(), handles.end(), handle), handles.end());
    touched.push_back(entry.topic);
  }
  readers_.erase(
      std::remove_if(readers_.begin(), readers_.end(), [owner](const ReaderEntry& e) { return e.owner == owner; }),
      readers_.end());
  for (auto& entry : trackers_) {
    if (entry.owner != owner) continue;
    std::lock_guard<std::mutex> lock(entry.topic->mutex_);
    auto& writers = entry.topic->writers_;
    writers.erase(std::remove(writers.begin(), writers.end(), entry.guid), writers.end());
  }
  trackers_.erase(
      std::remove_if(trackers_.begin(), trackers_.end(), [owner](const WriterEntry& e) { return e.owner == owner; }),
      trackers_.end());
  for (const LocalTopicBase* topic : touched) recount(*topic);
}

}  // namespace pmlsm::dds
