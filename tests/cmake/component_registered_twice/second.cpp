// The other registration of the same name (configured only, never compiled).
namespace pmlsm::node {

PMLSM_COMPONENT(twin, make_other_twin, 2);

}  // namespace pmlsm::node
