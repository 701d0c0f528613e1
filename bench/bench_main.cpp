// Simulation speed: simulated seconds per wall-clock second (the real-time
// factor) of the nonlinear plant alone at its 10 us step, and of the whole
// in-process closed loop (plant + current loop + velocity loop + Kalman
// filter + reference model), on one core. Figures only; nothing is asserted.
//
//   ./build/bin/pmlsm_bench                # all
//   ./build/bin/pmlsm_bench --benchmark_filter=Plant
#include <benchmark/benchmark.h>

#include <memory>
#include <string>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"

namespace {

const pmlsm::SystemParams& shipped_params() {
  static const pmlsm::SystemParams p =
      pmlsm::load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml");
  return p;
}

// The shipped parameters with the integrator chosen by the benchmark's argument.
pmlsm::SystemParams params_with(benchmark::State& state) {
  pmlsm::SystemParams p = shipped_params();
  const pmlsm::Integrator methods[] = {pmlsm::Integrator::kRk4, pmlsm::Integrator::kHeun,
                                       pmlsm::Integrator::kAdamsBashforth2};
  p.plant.integrator = methods[state.range(0)];
  state.SetLabel(pmlsm::to_string(p.plant.integrator));
  return p;
}

// Argument: 0 rk4, 1 heun, 2 ab2 (the label says which).
void name_integrator(benchmark::internal::Benchmark* b) { b->ArgName("integrator")->Arg(0)->Arg(1)->Arg(2); }

// Reports simulated seconds per wall second as "x_realtime".
void report_realtime_factor(benchmark::State& state, double simulated_s_per_iteration) {
  state.counters["x_realtime"] = benchmark::Counter(simulated_s_per_iteration * static_cast<double>(state.iterations()),
                                                    benchmark::Counter::kIsRate);
}

// The plant alone as the drive's current loop uses it: one step() per
// 31.25 us period (sub-steps of at most 10 us) with a voltage that changes
// every period. 32 periods (1 ms) per iteration.
void BM_PlantCurrentLoopPeriods(benchmark::State& state) {
  const pmlsm::SystemParams p = params_with(state);
  pmlsm::Plant plant(p.plant);
  plant.reset({0.0, 0.0, 0.01, 0.0});
  const double period = p.timing.current_loop_period_s;
  double u_q = 20.0;
  for (auto _ : state) {
    for (int i = 0; i < 32; ++i) {
      u_q = u_q > 30.0 ? 10.0 : u_q + 0.01;
      benchmark::DoNotOptimize(plant.step({1.0, u_q, 0.0}, period));
    }
    if (plant.state().motor_position_m > 0.4) plant.reset({0.0, 0.0, 0.01, 0.0});
  }
  report_realtime_factor(state, 32 * period);
}
BENCHMARK(BM_PlantCurrentLoopPeriods)->Apply(name_integrator);

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
  const pmlsm::Scenario scenario =
      pmlsm::load_scenario(std::string(PMLSM_SOURCE_DIR) + "/configs/scenarios/pulse.yaml", p.timing.control_period_s);
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
