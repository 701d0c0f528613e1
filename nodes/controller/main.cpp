#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("controller", pmlsm::node::make_controller, argc, argv);
}
