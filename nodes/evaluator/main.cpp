#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("evaluator", pmlsm::node::make_evaluator, argc, argv);
}
