// CSV trace of a closed-loop run: one row per control tick, SI units in the header. The load
// sensor's readings are nan when not measured; load_sensor_use is EstimatedState's LOAD_SENSOR_*
// (0 not used, 1 used, 2 refused, 3 failed).
#pragma once

#include <string>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"

namespace pmlsm {

/// Writes atomically (a temporary file renamed into place). @throws std::runtime_error on I/O failure.
void write_trace_csv(const std::string& path, const std::vector<TickRecord>& trace);

}  // namespace pmlsm
