#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("drive_bridge", pmlsm::node::make_drive_bridge, argc, argv);
}
