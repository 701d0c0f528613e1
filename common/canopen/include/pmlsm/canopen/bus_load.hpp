// The load a cycle's frames put on a classical CAN bus (11-bit identifiers).
//
// A data frame with n data bytes is 47 + 8n bits on the wire (SOF 1, identifier 11, RTR 1,
// IDE 1, r0 1, DLC 4, data 8n, CRC 15, CRC delimiter 1, ACK 2, EOF 7, intermission 3). Bit
// stuffing adds a bit after five equal ones in SOF..CRC (34 + 8n bits): at worst one every four
// after the first, floor((33 + 8n) / 4). So 8 data bytes: 111 bits, 135 at worst; 1 byte: 55 / 65.
#pragma once

#include <cstdint>
#include <vector>

namespace pmlsm::canopen {

/// Bits of one 11-bit data frame with `dlc` data bytes (0..8), without stuffing or at worst.
std::uint32_t can_frame_bits(std::uint8_t dlc, bool worst_case_stuffing) noexcept;

struct CycleFrame {
  const char* name;
  std::uint8_t dlc;
  double per_cycle;  ///< frames of this kind per cycle (0.02 for a heartbeat every 50 cycles)
};

struct BusLoad {
  double bits_per_cycle = 0;        ///< without stuffing
  double bits_per_cycle_worst = 0;  ///< with worst-case stuffing
  double load = 0;                  ///< bits / (bit rate x cycle), 0..1 (more: the bus cannot carry it)
  double load_worst = 0;
};

/// @throws std::invalid_argument for a bit rate or cycle <= 0, a DLC > 8 or a negative count.
BusLoad bus_load(const std::vector<CycleFrame>& frames, double bitrate_bps, double cycle_s);

/// The drive bridge's frames per 1 ms cycle (the bus contract in cia402_drive.hpp): SYNC with a
/// counter (1 byte), RPDO1, TPDO1, TPDO2 (8 bytes each), with a load sensor TPDO3 (8 bytes at
/// most), and both heartbeats (1 byte) every `heartbeat_ms` (0: none).
std::vector<CycleFrame> bridge_cycle_frames(double cycle_s, std::uint32_t drive_heartbeat_ms,
                                            std::uint32_t master_heartbeat_ms, bool load_sensor);

}  // namespace pmlsm::canopen
