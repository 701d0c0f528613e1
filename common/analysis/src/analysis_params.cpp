#include "pmlsm/analysis/analysis_params.hpp"

namespace pmlsm {

FrequencyResponseMeasurementParams frequency_response_params(const SystemParams& system) {
  FrequencyResponseMeasurementParams p = system.section<FrequencyResponseMeasurementParams>(kFrequencyResponseSection);
  p.period_s = system.timing.control_period_s;
  p.pole_pitch_m = system.plant.electrical.pole_pitch_m;
  return p;
}

TuningTargets tuning_targets(const SystemParams& system) {
  return system.section<TuningTargets>(kTuningTargetsSection);
}

FilterDesignParams filter_design_params(const SystemParams& system) {
  return system.section<FilterDesignParams>(kFilterDesignSection);
}

}  // namespace pmlsm
