#pragma once
/// @file
/// A fixed-size log-linear histogram of durations in nanoseconds (the bucketing of
/// HdrHistogram: 32 linear sub-buckets per power of two, so any percentile is within 1/32 ~ 3 %
/// of the true value). Used for tick jitter and query latency, live and in the summary.
///
/// Threading: one writer thread calls record(); any thread may read (percentile(), count(),
/// max()) at the same time and sees a consistent-enough snapshot (relaxed atomics: counts may lag
/// by the records in flight). record() never allocates, locks or throws.

#include <array>
#include <atomic>
#include <bit>
#include <cstdint>

namespace gshaptics {

class LatencyHistogram {
 public:
  static constexpr int kSubBits = 5;
  static constexpr std::uint64_t kSub = 1u << kSubBits;  // 32
  static constexpr int kBuckets = int(kSub) * 40;        // up to 2^44 ns (~4.9 h)

  /// Adds one duration (ns; negative counts as 0).
  void record(std::int64_t ns) noexcept {
    const std::uint64_t v = ns > 0 ? std::uint64_t(ns) : 0;
    bins_[std::size_t(index(v))].fetch_add(1, std::memory_order_relaxed);
    count_.fetch_add(1, std::memory_order_relaxed);
    if (v > max_.load(std::memory_order_relaxed)) max_.store(v, std::memory_order_relaxed);
  }
  void reset() noexcept {
    for (auto& b : bins_) b.store(0, std::memory_order_relaxed);
    count_.store(0, std::memory_order_relaxed);
    max_.store(0, std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }
  /// Largest recorded value, ns (exact).
  [[nodiscard]] std::uint64_t max() const noexcept { return max_.load(std::memory_order_relaxed); }
  /// Value at percentile p in [0, 100], ns: the upper edge of the bucket holding it, never above
  /// max(). 0 when empty.
  [[nodiscard]] double percentile(double p) const noexcept {
    std::uint64_t total = 0;
    for (const auto& b : bins_) total += b.load(std::memory_order_relaxed);
    if (total == 0) return 0;
    const double want = p / 100.0 * double(total);
    std::uint64_t seen = 0;
    for (int i = 0; i < kBuckets; ++i) {
      seen += bins_[std::size_t(i)].load(std::memory_order_relaxed);
      if (double(seen) >= want && seen > 0) {
        const double edge = double(upper_edge(i));
        const double m = double(max());
        return edge < m ? edge : m;
      }
    }
    return double(max());
  }

  /// Bucket of a value (exposed for tests).
  [[nodiscard]] static int index(std::uint64_t v) noexcept {
    if (v < kSub) return int(v);
    const int e = int(std::bit_width(v)) - 1 - kSubBits;  // v >> e in [32, 64)
    const int i = int(kSub) * (e + 1) + int((v >> e) - kSub);
    return i < kBuckets ? i : kBuckets - 1;
  }
  /// Largest value that falls in bucket i.
  [[nodiscard]] static std::uint64_t upper_edge(int i) noexcept {
    if (i < int(kSub)) return std::uint64_t(i);
    const int e = i / int(kSub) - 1;
    const std::uint64_t m = kSub + std::uint64_t(i % int(kSub));
    return ((m + 1) << e) - 1;
  }

 private:
  std::array<std::atomic<std::uint32_t>, kBuckets> bins_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::uint64_t> max_{0};
};

}  // namespace gshaptics
