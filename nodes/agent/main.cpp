#include "launch_agent.hpp"

int main(int argc, char** argv) {
  return pmlsm::node::run_standalone("launch_agent", pmlsm::node::make_launch_agent, argc, argv);
}
