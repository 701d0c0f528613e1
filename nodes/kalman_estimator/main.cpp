#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("kalman_estimator", pmlsm::node::make_kalman_estimator, argc, argv);
}
