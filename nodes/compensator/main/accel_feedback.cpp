#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("accel_feedback", pmlsm::node::make_accel_feedback, argc, argv);
}
