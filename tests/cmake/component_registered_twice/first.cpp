// One of two registrations of the same name (configured only, never compiled).
namespace pmlsm::node {

PMLSM_COMPONENT(twin, make_twin, 1);

}  // namespace pmlsm::node
