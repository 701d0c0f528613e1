// The virtual EtherCAT drive over the simulated drive as the shipped files make it (configs/
// system.yaml, the CANopen rig file's scaling and heartbeats, the CANopen device's dictionary), and
// the shipped EtherCAT rig file with this thread's time-outs: what the drive tests stand on.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/ethercat_config.hpp"
#include "pmlsm/ethercat/cia402_drive.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace pmlsm::ethercat::test {

struct ShippedDrive {
  /// `edit` changes the shipped system before the simulated drive is built from it.
  explicit ShippedDrive(const std::function<void(SystemParams&)>& edit = {})
      : root(std::string(PMLSM_SOURCE_DIR) + "/"),
        system(edited(load_system_params(root + "configs/system.yaml"), edit)),
        canopen_rig(load_canopen_config(root + "configs/canopen/drive.yaml")),
        device(load_device_dictionary(root + "configs/canopen/virtual_drive_od.yaml")),
        behind(system, PlantInitialCondition{}) {}

  /// The virtual drive over `behind`, with the CANopen device's dictionary (the lockstep contract)
  /// or the CiA 402 one alone; with `own_loops`, its velocity and position modes (the system's
  /// velocity PI), else torque only.
  std::unique_ptr<VirtualEthercatDrive> make_drive(bool device_dictionary, bool own_loops = false) {
    canopen::Cia402ApplicationParams params;
    params.scaling = canopen_rig.master.scaling;
    if (own_loops) {
      params.own_loops =
          canopen::DriveOwnLoopsParams::like_controller(system.velocity_loop, system.timing.control_period_s);
    }
    if (!device_dictionary) return std::make_unique<VirtualEthercatDrive>(params, behind);
    const std::uint32_t modes = own_loops ? canopen::kSupportedModesCyclicSynchronous : canopen::kSupportedModesTorque;
    return std::make_unique<VirtualEthercatDrive>(
        params, behind, build_device_dictionary(canopen_rig, device, system.timing.control_period_s, modes));
  }

  /// The shipped rig file, with this thread's time-outs (a reply is there at once or never).
  static Cia402DriveConfig rig_config() {
    Cia402DriveConfig c = load_ethercat_config(std::string(PMLSM_SOURCE_DIR) + "/configs/ethercat/drive.yaml");
    c.reply_timeout_ms = 1;
    c.cycle_timeout_ms = 1;
    return c;
  }

  static SystemParams edited(SystemParams system, const std::function<void(SystemParams&)>& edit) {
    if (edit) edit(system);
    return system;
  }

  std::string root;
  SystemParams system;
  CanopenRigConfig canopen_rig;
  DeviceDictionary device;
  SimulatedDriveBackend behind;
};

}  // namespace pmlsm::ethercat::test
