// The CoE side of a CiA 402 slave on EtherCAT: the sync manager objects a master reads to map the
// process data (0x1C00: each sync manager's type; 0x1C12 / 0x1C13: the RxPDO 0x1600 assigned to
// SM2, the outputs, and the TxPDO 0x1A00 to SM3, the inputs), added to the CiA 402 dictionary
// of common/canopen; and the process image between the sync managers' memory and the
// dictionary's mapped objects, through canopen's PDO mapping (the same bytes a CANopen PDO
// carries).
#pragma once

#include <cstdint>

#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/ethercat/esc.hpp"

namespace pmlsm::ethercat {

inline constexpr std::uint16_t kObjectSyncManagerTypes = 0x1C00;
inline constexpr std::uint16_t kObjectRxPdoAssign = 0x1C12;  ///< SM2, outputs
inline constexpr std::uint16_t kObjectTxPdoAssign = 0x1C13;  ///< SM3, inputs
inline constexpr std::uint16_t kRxPdoMapping = 0x1600;
inline constexpr std::uint16_t kTxPdoMapping = 0x1A00;

/// Adds 0x1C00 (4 sync managers: mailbox out, mailbox in, outputs, inputs) and 0x1C12 / 0x1C13
/// (one PDO each: 0x1600, 0x1A00). @throws std::invalid_argument from the dictionary (full, or
/// an object already there).
void add_coe_sync_manager_objects(canopen::ObjectDictionary& dictionary);

/// The slave application's side of the process data, between frames.
class CoeProcessImage {
 public:
  /// The PDO maps of 0x1600 and 0x1A00; SM2's memory at `outputs_at`, SM3's at `inputs_at`.
  /// @throws std::invalid_argument when a map is not valid against the dictionary.
  CoeProcessImage(canopen::ObjectDictionary& dictionary, std::uint16_t outputs_at, std::uint16_t inputs_at);
  std::uint16_t output_bytes() const { return rx_.byte_length(); }
  std::uint16_t input_bytes() const { return tx_.byte_length(); }
  /// The outputs the master wrote into SM2 into the dictionary's mapped objects, and the mapped
  /// TxPDO objects into SM3 for the master's next read. Never throws; outputs the dictionary
  /// refuses (out of range) are counted and not written.
  void exchange(Esc& esc);
  std::uint64_t refused_outputs() const { return refused_outputs_; }

 private:
  canopen::ObjectDictionary& dictionary_;
  canopen::PdoMap rx_;
  canopen::PdoMap tx_;
  std::uint16_t outputs_at_;
  std::uint16_t inputs_at_;
  std::uint64_t refused_outputs_ = 0;
};

}  // namespace pmlsm::ethercat
