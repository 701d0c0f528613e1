#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("de_worker", pmlsm::node::make_de_worker, argc, argv);
}
