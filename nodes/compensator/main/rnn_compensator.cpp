#include "component.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("rnn_compensator", pmlsm::node::make_rnn_compensator, argc, argv);
}
