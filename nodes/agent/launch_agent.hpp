// The launch agent of a host (`pmlsm agent`): made as a component is, but not registered as one,
// since it starts programs itself (an agent never starts another, a container never holds one).
#pragma once

#include "component.hpp"

namespace pmlsm::node {

MadeComponent make_launch_agent(const ComponentContext& context, int argc, char** argv);

}  // namespace pmlsm::node
