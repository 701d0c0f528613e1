// Commissioning identification (pmlsm/sim/identification.hpp): the load and the bearing friction
// fitted to what the drive measured with PI alone, on plants of the family the shipped models do
// not match; bad samples refused naming the index.
#include "pmlsm/sim/identification.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "pmlsm/config/config.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

SystemParams plant_of(double load_mass_kg, double spring_n_per_m, double coulomb_n, double viscous_n_s_per_m) {
  SystemParams p = test::shipped_params();
  p.plant.mechanics.load_mass_kg = load_mass_kg;
  p.plant.mechanics.spring_n_per_m = spring_n_per_m;
  p.plant.friction.coulomb_n = coulomb_n;
  p.plant.friction.viscous_n_s_per_m = viscous_n_s_per_m;
  return p;
}

std::vector<IdentificationSample> commissioning_run(const SystemParams& p) {
  const Scenario s = test::shipped_scenario("identification");
  return identification_samples(run_scenario(p, s));
}

TEST(Identification, FindsTheLoadOfPlantsTheModelDoesNotMatch) {
  struct Case {
    double m, k, fc, fv;
  };
  for (const Case c : {Case{4.0, 13700, 20, 30}, Case{2.0, 27400, 10, 15}, Case{8.0, 6850, 30, 45},
                       Case{2.0, 6850, 30, 45}, Case{8.0, 27400, 10, 15}}) {
    const SystemParams p = plant_of(c.m, c.k, c.fc, c.fv);
    const IdentifiedLoad id = identify_load(p, commissioning_run(p));
    const double true_hz = std::sqrt(c.k / c.m) / (2 * M_PI);
    std::printf("[ identify   ] %.1f kg %.0f N/m %.0f N %.0f N s/m -> %.2f kg %.0f N/m %.1f N %.1f N s/m, mode %.2f Hz (true %.2f), "
                "innovation %.3f mm/s (configured model %.3f), %u runs%s%s\n",
                c.m, c.k, c.fc, c.fv, id.load_mass_kg, id.spring_n_per_m, id.coulomb_n, id.viscous_n_s_per_m,
                id.load_mode_hz(), true_hz, 1e3 * id.innovation_rms_mps, 1e3 * id.configured_innovation_rms_mps,
                id.evaluations, id.at_bound.empty() ? "" : ", at bound: ", id.at_bound.c_str());
  }
}

}  // namespace
}  // namespace pmlsm
