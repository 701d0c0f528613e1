#include "pmlsm/canopen/bus_load.hpp"

#include <stdexcept>
#include <string>

namespace pmlsm::canopen {

std::uint32_t can_frame_bits(std::uint8_t dlc, bool worst_case_stuffing) noexcept {
  const std::uint32_t n = dlc > 8 ? 8U : dlc;
  const std::uint32_t bits = 47U + 8U * n;
  return worst_case_stuffing ? bits + (33U + 8U * n) / 4U : bits;
}

BusLoad bus_load(const std::vector<CycleFrame>& frames, double bitrate_bps, double cycle_s) {
  if (!(bitrate_bps > 0)) throw std::invalid_argument("bitrate_bps: must be > 0, got " + std::to_string(bitrate_bps));
  if (!(cycle_s > 0)) throw std::invalid_argument("cycle_s: must be > 0, got " + std::to_string(cycle_s));
  BusLoad load;
  for (const CycleFrame& f : frames) {
    if (f.dlc > 8)
      throw std::invalid_argument(std::string(f.name) + ": DLC must be <= 8, got " + std::to_string(f.dlc));
    if (!(f.per_cycle >= 0)) {
      throw std::invalid_argument(std::string(f.name) + ": frames per cycle must be >= 0, got " +
                                  std::to_string(f.per_cycle));
    }
    load.bits_per_cycle += f.per_cycle * can_frame_bits(f.dlc, false);
    load.bits_per_cycle_worst += f.per_cycle * can_frame_bits(f.dlc, true);
  }
  const double capacity_bits = bitrate_bps * cycle_s;
  load.load = load.bits_per_cycle / capacity_bits;
  load.load_worst = load.bits_per_cycle_worst / capacity_bits;
  return load;
}

std::vector<CycleFrame> bridge_cycle_frames(double cycle_s, std::uint32_t drive_heartbeat_ms,
                                            std::uint32_t master_heartbeat_ms, bool load_sensor) {
  std::vector<CycleFrame> frames = {{"SYNC", 1, 1.0}, {"RPDO1", 8, 1.0}, {"TPDO1", 8, 1.0}, {"TPDO2", 8, 1.0}};
  if (load_sensor) frames.push_back({"TPDO3", 8, 1.0});
  if (drive_heartbeat_ms > 0) frames.push_back({"drive heartbeat", 1, cycle_s * 1e3 / drive_heartbeat_ms});
  if (master_heartbeat_ms > 0) frames.push_back({"master heartbeat", 1, cycle_s * 1e3 / master_heartbeat_ms});
  return frames;
}

}  // namespace pmlsm::canopen
