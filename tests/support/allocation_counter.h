#pragma once
// Counts heap allocations in the whole test binary that links this (operator new is replaced),
// for the "a servo tick does not allocate" tests (docs/design.md Sec. 6: the servo tick does not allocate).

#include <cstddef>

namespace gshaptics::test {

/// Number of operator new calls so far, from every thread.
std::size_t allocation_count() noexcept;

}  // namespace gshaptics::test
