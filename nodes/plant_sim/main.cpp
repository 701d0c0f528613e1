#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("plant_sim", pmlsm::node::make_plant_sim, argc, argv);
}
