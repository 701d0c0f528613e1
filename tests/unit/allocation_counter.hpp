// Counts the heap allocations of a whole test executable, so a test can check that a hot path
// (a control step, a frame codec, a per-tick mapping) makes none. It replaces the global
// operator new and delete: include it from exactly one file of an executable (those tests get
// executables of their own for that reason).
#pragma once

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace pmlsm::test {

inline std::atomic<std::uint64_t> g_allocations{0};

/// Allocations since the program started; compare two readings around the code under test.
inline std::uint64_t allocations() { return g_allocations.load(); }

// Out of line, so that GCC does not pair an inlined free() with a new-expression
// (-Wmismatched-new-delete).
[[gnu::noinline]] inline void release_allocation(void* p) noexcept { std::free(p); }

}  // namespace pmlsm::test

void* operator new(std::size_t size) {
  ++pmlsm::test::g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { pmlsm::test::release_allocation(p); }
void operator delete(void* p, std::size_t) noexcept { pmlsm::test::release_allocation(p); }
