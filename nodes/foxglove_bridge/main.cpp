#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("foxglove_bridge", pmlsm::node::make_foxglove_bridge, argc, argv);
}
