// The components of this build, as their PMLSM_COMPONENT lines registered them (component.hpp):
// the table is generated into the build tree by cmake/PmlsmComponents.cmake, and a program that
// links pmlsm_component_registry links every registered component with it.
#pragma once

#include <vector>

#include "component.hpp"

namespace pmlsm::node {

struct RegisteredComponent {
  const char* name;  ///< its program's and its container type's
  ComponentFactory make;
  int priority;        ///< its place on a container's chain thread (lower first), or kRunsAlone
  const char* source;  ///< the file that registers it, from the source tree's root
};

/// Every registered component, in the order the build added them.
const std::vector<RegisteredComponent>& registered_components();

}  // namespace pmlsm::node
