// The commissioning's parameters as the system holds them: three parameter sections
// (pmlsm/util/parameter_section.hpp) of the system file, declared by their Params beside their code
// and registered for every reader of a system file by common/CMakeLists.txt
// (pmlsm_parameter_section), so the system's own parameters (sim) do not know them. These read them
// from a SystemParams: the file's values over the declared defaults, completed by the system.
#pragma once

#include "pmlsm/analysis/filter_design.hpp"
#include "pmlsm/analysis/frequency_response_measurement.hpp"
#include "pmlsm/analysis/loop_tuning.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

/// The sections' key paths in the system file.
inline constexpr const char* kFrequencyResponseSection = "commissioning.frequency_response";
inline constexpr const char* kTuningTargetsSection = "commissioning.tuning";
inline constexpr const char* kFilterDesignSection = "commissioning.filter_design";

/// The frequency-response measurement at the system's control period, with the plant's pole pitch
/// (the motor's datasheet value: the force ripple's period in space). Not validated: the
/// measurement made from it is (FrequencyResponseMeasurement's constructor).
FrequencyResponseMeasurementParams frequency_response_params(const SystemParams& system);
/// The margins `pmlsm commission --tune` tunes the velocity PI to.
TuningTargets tuning_targets(const SystemParams& system);
/// What `pmlsm commission --design-filters` places a notch for.
FilterDesignParams filter_design_params(const SystemParams& system);

}  // namespace pmlsm
