#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("state_feedback", pmlsm::node::make_state_feedback, argc, argv);
}
