// Simulation speed: simulated seconds per wall-clock second (the real-time
// factor) of the nonlinear plant alone at its 10 us step, and of the whole
// in-process closed loop (plant + current loop + velocity loop + Kalman
// filter + reference model), on one core. Figures only; nothing is asserted.
//
//   ./build/bench/pmlsm_bench                # all
//   ./build/bench/pmlsm_bench --benchmark_filter=Plant
#include <benchmark/benchmark.h>

#include <memory>
#include <string>

#include "pmlsm/closed_loop.hpp"
#include "pmlsm/config.hpp"
#include "pmlsm/kalman_filter.hpp"

namespace {

const pmlsm::SystemParams& shipped_params() {
  static const pmlsm::SystemParams p =
      pmlsm::load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml");
  return p;
}

// The shipped parameters with the integrator chosen by the benchmark's argument.
pmlsm::SystemParams params_with(const benchmark::State& state) {
  pmlsm::SystemParams p = shipped_params();
  p.plant.integrator = state.range(0) == 0 ? pmlsm::Integrator::kRk4 : pmlsm::Integrator::kHeun;
  return p;
}

void name_integrator(benchmark::internal::Benchmark* b) {
  b->ArgName("heun")->Arg(0)->Arg(1);
}

// Reports simulated seconds per wall second as "x_realtime".
void report_realtime_factor(benchmark::State& state, double simulated_s_per_iteration) {
  state.counters["x_realtime"] = benchmark::Counter(
      simulated_s_per_iteration * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// The plant alone, driven by a fixed voltage at its 10 us step: 1 ms per iteration.
void BM_PlantOneMillisecond(benchmark::State& state) {
  const pmlsm::SystemParams p = params_with(state);
  pmlsm::Plant plant(p.plant);
  plant.reset({0.0, 0.0, 0.01, 0.0});
  const pmlsm::PlantInput input{0.0, 20.0, 0.0};
  const double step = p.plant.max_step_s;
  for (auto _ : state) {
    for (int i = 0; i < 100; ++i) benchmark::DoNotOptimize(plant.step(input, step));
    if (plant.state().motor_position_m > 0.4) plant.reset({0.0, 0.0, 0.01, 0.0});
  }
  report_realtime_factor(state, 100 * step);
}
BENCHMARK(BM_PlantOneMillisecond)->Apply(name_integrator);

// The same plant driven by one step() call per millisecond (100 sub-steps of
// 10 us inside): the integrator's own speed, without the per-call input checks
// and encoder reading.
void BM_PlantOneCallPerMillisecond(benchmark::State& state) {
  const pmlsm::SystemParams p = params_with(state);
  pmlsm::Plant plant(p.plant);
  plant.reset({0.0, 0.0, 0.01, 0.0});
  const pmlsm::PlantInput input{0.0, 20.0, 0.0};
  for (auto _ : state) {
    benchmark::DoNotOptimize(plant.step(input, 1e-3));
    if (plant.state().motor_position_m > 0.4) plant.reset({0.0, 0.0, 0.01, 0.0});
  }
  report_realtime_factor(state, 1e-3);
}
BENCHMARK(BM_PlantOneCallPerMillisecond)->Apply(name_integrator);

// The closed loop on the pulse scenario: one control tick (1 ms) per iteration.
void BM_ClosedLoopTick(benchmark::State& state) {
  const pmlsm::SystemParams p = params_with(state);
  const pmlsm::Scenario scenario = pmlsm::load_scenario(
      std::string(PMLSM_SOURCE_DIR) + "/configs/scenarios/pulse.yaml", p.timing.control_period_s);
  auto loop = std::make_unique<pmlsm::ClosedLoop>(p, scenario);
  for (auto _ : state) {
    if (loop->done()) {
      state.PauseTiming();
      loop = std::make_unique<pmlsm::ClosedLoop>(p, scenario);
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(loop->step());
  }
  report_realtime_factor(state, p.timing.control_period_s);
}
BENCHMARK(BM_ClosedLoopTick)->Apply(name_integrator);

// The Kalman filter step alone, for scale.
void BM_KalmanStep(benchmark::State& state) {
  pmlsm::KalmanFilter kf(shipped_params().kalman_params());
  double y = 0.0;
  for (auto _ : state) {
    y = y > 0.2 ? 0.0 : y + 1e-3;
    benchmark::DoNotOptimize(kf.step({y, 10.0}));
  }
  report_realtime_factor(state, shipped_params().timing.control_period_s);
}
BENCHMARK(BM_KalmanStep);

}  // namespace

BENCHMARK_MAIN();
