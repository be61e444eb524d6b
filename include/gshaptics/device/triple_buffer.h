#pragma once
/// @file
/// A single-producer / single-consumer triple buffer: the hand-off between the servo loop and the
/// collision worker (docs/design.md Sec. 6). The writer never waits for the reader and the reader
/// never waits for the writer; the reader always gets the newest complete value.
///
/// Threading contract: exactly one thread calls write() and exactly one thread calls read() /
/// read_if_new() (they may be the same thread). Both are wait-free, lock-free, allocation-free
/// and noexcept; T's copy assignment must not allocate or throw (plain structs of numbers and
/// Eigen fixed-size types). Memory: three copies of T plus one atomic byte.
///
/// How it works (the classic three-slot scheme): the writer owns one slot, the reader owns one,
/// and the third ("middle") slot is exchanged atomically together with a "fresh" bit. write()
/// fills the writer's slot and swaps it into the middle with fresh = 1 (release); read() swaps its
/// slot with the middle only when fresh is set (acquire), so a value is never torn and never
/// older than one already returned.

#include <array>
#include <atomic>
#include <cstdint>
#include <type_traits>

namespace gshaptics {

template <class T>
class TripleBuffer {
  static_assert(std::is_copy_assignable_v<T> && std::is_default_constructible_v<T>,
                "TripleBuffer<T> needs a copyable T");

 public:
  TripleBuffer() = default;
  explicit TripleBuffer(const T& initial) { slots_.fill(initial); }
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  /// Writer: publishes `value` as the newest.
  void write(const T& value) noexcept {
    slots_[back_] = value;
    const std::uint8_t old = middle_.exchange(std::uint8_t(back_ | kFresh), std::memory_order_acq_rel);
    back_ = old & kIndexMask;
  }

  /// Reader: takes the newest value if one was written since the last take; returns whether it
  /// did. `out` is written only on true.
  bool read_if_new(T& out) noexcept {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndexMask;
    out = slots_[front_];
    return true;
  }

  /// Reader: the newest value (the last one taken when nothing new was written).
  [[nodiscard]] const T& read() noexcept {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) != 0) {
      const std::uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
      front_ = old & kIndexMask;
    }
    return slots_[front_];
  }

 private:
  static constexpr std::uint8_t kFresh = 0x4;
  static constexpr std::uint8_t kIndexMask = 0x3;
  std::array<T, 3> slots_{};
  alignas(64) std::uint8_t back_ = 0;                   // writer's slot (writer thread only)
  alignas(64) std::atomic<std::uint8_t> middle_{1};     // exchanged slot + fresh bit
  alignas(64) std::uint8_t front_ = 2;                  // reader's slot (reader thread only)
};

}  // namespace gshaptics
