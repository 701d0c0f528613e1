#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("virtual_drive", pmlsm::node::make_virtual_drive, argc, argv);
}
