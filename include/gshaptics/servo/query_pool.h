#pragma once
/// @file
/// A small pool of worker threads for the parallel narrow phase of large queries
/// (ContactQuery::set_executor). Created at start, optionally pinned; run() does not allocate,
/// lock or throw: the caller publishes a job through an atomic epoch, the workers wake
/// (std::atomic wait/notify: a futex, no mutex), run their part, and count themselves done; the
/// caller runs part 0 itself, then spins until every part is done.
///
/// Waking a sleeping worker costs a few microseconds (a futex wake and a context switch), so the
/// pool pays for queries of a few thousand candidates and more, which is what
/// set_executor's `min_candidates` is for. Defaults for a haptics PC: leave one core to the servo
/// thread and one to the collision worker, and use up to 3 more (see default_query_threads).

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "gshaptics/collision/contact_query.h"

namespace gshaptics {

class QueryPool final : public ParallelExecutor {
 public:
  /// `parts`: threads sharing a query, the caller included (>= 1; 1: no worker thread).
  /// `cpus`: CPU of each worker (parts - 1 entries) to pin to; empty: not pinned. A refused pin
  /// is reported in warnings(), not an error.
  /// `spin_us`: after each job a worker spins this long for the next one before sleeping.
  explicit QueryPool(int parts, const std::vector<int>& cpus = {}, int spin_us = 100);
  ~QueryPool() override;
  QueryPool(const QueryPool&) = delete;
  QueryPool& operator=(const QueryPool&) = delete;

  [[nodiscard]] int parts() const noexcept override { return parts_; }
  void run(void (*fn)(void* ctx, int part), void* ctx) noexcept override;
  [[nodiscard]] const std::vector<std::string>& warnings() const noexcept { return warnings_; }

 private:
  void worker(int part) noexcept;
  int parts_;
  int spin_us_;
  std::vector<std::thread> threads_;
  std::atomic<std::uint64_t> epoch_{0};
  std::atomic<int> done_{0};
  std::atomic<bool> stop_{false};
  void (*fn_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
  std::vector<std::string> warnings_;
};

/// Parts for a machine with `cores` hardware threads: all but two (the servo thread's and the
/// collision worker's), at most 4 (gains flatten past the memory bandwidth of one query), at
/// least 1. 2 cores -> 1, 4 -> 2, 8 -> 4, 16 -> 4.
[[nodiscard]] int default_query_threads(unsigned cores) noexcept;

}  // namespace gshaptics
