#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("de_trainer", pmlsm::node::make_de_trainer, argc, argv);
}
