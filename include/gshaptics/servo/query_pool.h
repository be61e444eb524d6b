#pragma once
/// @file
/// A small pool of worker threads for the parallel narrow phase of large queries
/// (ContactQuery::set_executor). Created at start, optionally pinned; run() does not allocate,
/// lock or throw. The caller publishes a job (function, context, task count) through one atomic
/// word, wakes the workers (a futex, no mutex; no system call when every worker is
/// spinning), and then claims tasks itself like any worker: a task is claimed by
/// a compare-and-swap on that word, which also carries the job's number, so a worker that wakes
/// late can never run a task of a finished job. The caller returns when every task is done; it
/// waits only for tasks a worker has actually started.
///
/// Waking a sleeping worker costs a few to tens of microseconds (a futex wake, and on a virtual
/// machine an inter-processor interrupt); the caller does not wait for the wake, but a worker that
/// arrives late may still claim the last task and be waited for. So a worker spins `spin_us`
/// after each job before it sleeps, 2000 us by default: two servo periods at 1 kHz, so a pool
/// serving a servo loop's large queries never sleeps between them (on this project's 2-core VM,
/// truck's p99 with 2 threads was 88-96 us with a 100 us spin and 64-68 us with the worker always
/// spinning; bench/RESULTS.md). Spinning takes the worker's core, which on a haptics PC is its
/// own. Defaults for such a PC: leave one core to the servo thread and one to the collision
/// worker, and use up to 3 more (see default_query_threads).

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "gshaptics/collision/contact_query.h"

namespace gshaptics {

class QueryPool final : public ParallelExecutor {
 public:
  /// `threads`: threads sharing a query, the caller included (1..64; 1: no worker thread).
  /// `cpus`: CPU of each worker (threads - 1 entries) to pin to; empty: not pinned. A refused
  /// pin is reported in warnings(), not an error.
  /// `spin_us`: after each job a worker spins this long for the next one before sleeping.
  /// Errors: InputError for `threads` outside 1..64.
  explicit QueryPool(int threads, const std::vector<int>& cpus = {}, int spin_us = 2000);
  ~QueryPool() override;
  QueryPool(const QueryPool&) = delete;
  QueryPool& operator=(const QueryPool&) = delete;

  [[nodiscard]] int threads() const noexcept override { return threads_count_; }
  void run(void (*fn)(void* ctx, int task), void* ctx, int tasks) noexcept override;
  [[nodiscard]] const std::vector<std::string>& warnings() const noexcept { return warnings_; }

 private:
  void worker() noexcept;
  // Claims and runs tasks of the current job until none is left.
  void run_tasks() noexcept;
  int threads_count_;
  int spin_us_;
  std::vector<std::thread> threads_;
  // The job word: job number (32 bits) | task count (16) | next unclaimed task (16).
  std::atomic<std::uint64_t> job_{0};
  std::atomic<int> done_{0};
  std::atomic<bool> stop_{false};
  // Sleeping: workers futex-wait on wake_ (bumped by every publish) and count themselves in
  // sleepers_, so a publish makes a system call only when somebody sleeps.
  std::atomic<std::uint32_t> wake_{0};
  std::atomic<int> sleepers_{0};
  void publish(std::uint64_t word) noexcept;
  void (*fn_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
  std::vector<std::string> warnings_;
};

/// Parts for a machine with `cores` hardware threads: all but two (the servo thread's and the
/// collision worker's), at most 4 (gains flatten past the memory bandwidth of one query), at
/// least 1. 2 cores -> 1, 4 -> 2, 8 -> 4, 16 -> 4.
[[nodiscard]] int default_query_threads(unsigned cores) noexcept;

}  // namespace gshaptics
