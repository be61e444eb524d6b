#pragma once
/// @file
// Internal: an allocator for the big arrays a servo tick reads at random (the collision world's
// records and BVH nodes, the seen solid's entries, bounds and wide BVH) that asks
// the kernel for transparent huge pages (madvise(MADV_HUGEPAGE), which works when THP is set to
// "madvise", the Debian default). A query touches a few hundred records scattered over the
// whole world; with 4 KiB pages each is a TLB miss, and on a virtual machine a TLB miss walks two
// page tables. Measured on the 10.6M-Gaussian world (77 B per Gaussian, 800 MB): query p50
// 24 -> 13.5 us, p99 195-245 -> 62 us on this project's 2-core VM (bench/RESULTS.md).
// Arrays under 2 MiB use the ordinary allocator.

#include <sys/mman.h>

#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>

namespace gshaptics::internal {

template <typename T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr std::size_t kHugePage = std::size_t(2) << 20;

  HugePageAllocator() noexcept = default;
  template <typename U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}  // NOLINT: rebinding is implicit

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHugePage) return static_cast<T*>(::operator new(bytes, std::align_val_t(alignof(T))));
    const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
    void* p = std::aligned_alloc(kHugePage, rounded);
    if (p == nullptr) throw std::bad_alloc();
    ::madvise(p, rounded, MADV_HUGEPAGE);  // a hint: refused (THP "never") is fine
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < kHugePage) ::operator delete(p, std::align_val_t(alignof(T)));
    else std::free(p);
  }
  template <typename U>
  bool operator==(const HugePageAllocator<U>&) const noexcept { return true; }
};

/// A std::vector in huge pages (HugePageAllocator) where it reaches 2 MiB.
template <typename T>
using HugePageVector = std::vector<T, HugePageAllocator<T>>;

}  // namespace gshaptics::internal
