#include "gshaptics/servo/query_pool.h"

#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include "gshaptics/error.h"
#include "gshaptics/servo/realtime_thread.h"

namespace gshaptics {

namespace {

constexpr std::uint64_t kIndexBits = 16;
constexpr std::uint64_t kIndexMask = (std::uint64_t(1) << kIndexBits) - 1;

constexpr std::uint64_t job_number(std::uint64_t word) noexcept { return word >> 32; }
constexpr std::uint64_t job_tasks(std::uint64_t word) noexcept { return (word >> kIndexBits) & kIndexMask; }
constexpr std::uint64_t job_next(std::uint64_t word) noexcept { return word & kIndexMask; }

inline void cpu_relax() noexcept {
#if defined(__x86_64__)
  __builtin_ia32_pause();
#endif
}

// The kernel compares the word with `expected` and sleeps atomically, so a wake between the
// caller's load and this call is never lost (it returns at once). Used directly rather than
// through std::atomic::wait, whose notify in libstdc++ 12 skips the wake on a waiter count
// that is not ordered with the value check.
inline void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected) noexcept {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAIT_PRIVATE, expected, nullptr, nullptr, 0);
}

inline void futex_wake_all(std::atomic<std::uint32_t>& word) noexcept {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE_PRIVATE, 0x7fffffff, nullptr, nullptr, 0);
}

}  // namespace

void QueryPool::publish(std::uint64_t word) noexcept {
  // Sequentially consistent with the sleeper's increment-then-check (a Dekker handshake): either
  // a worker about to sleep sees the new job, or this sees it counted and wakes it.
  job_.store(word, std::memory_order_seq_cst);
  wake_.fetch_add(1, std::memory_order_seq_cst);
  if (sleepers_.load(std::memory_order_seq_cst) > 0) futex_wake_all(wake_);
}

QueryPool::QueryPool(int threads, const std::vector<int>& cpus, int spin_us)
    : threads_count_(std::max(1, threads)), spin_us_(std::max(0, spin_us)) {
  if (threads < 1 || threads > 64) throw InputError("query threads: must be 1..64, got " + std::to_string(threads));
  for (int p = 1; p < threads_count_; ++p) {
    threads_.emplace_back([this] { worker(); });
    if (std::size_t(p - 1) < cpus.size()) {
      const int err = pin_thread_to_cpu(threads_.back().native_handle(), cpus[std::size_t(p - 1)]);
      if (err != 0)
        warnings_.push_back("query thread " + std::to_string(p) + ": not pinned to CPU " +
                            std::to_string(cpus[std::size_t(p - 1)]) + ": " + std::strerror(err));
    }
  }
}

QueryPool::~QueryPool() {
  stop_.store(true, std::memory_order_release);
  publish(job_.load(std::memory_order_relaxed) + (std::uint64_t(1) << 32));
  for (std::thread& t : threads_) t.join();
}

void QueryPool::run_tasks() noexcept {
  std::uint64_t word = job_.load(std::memory_order_acquire);
  for (;;) {
    if (job_next(word) >= job_tasks(word)) return;
    // The claim and the job number are one word: a claim of a finished job's task fails.
    if (!job_.compare_exchange_weak(word, word + 1, std::memory_order_acquire, std::memory_order_acquire))
      continue;
    // Claimed: the job cannot finish before this task is done, so fn_ and ctx_ (written before
    // the job word was published) are this job's.
    fn_(ctx_, int(job_next(word)));
    done_.fetch_add(1, std::memory_order_acq_rel);
    word = job_.load(std::memory_order_acquire);
  }
}

void QueryPool::worker() noexcept {
  // Job 0 is the constructor's (no job): a thread that starts after jobs (or the destructor's
  // stop) were published sees them as new.
  std::uint64_t seen = 0;
  for (;;) {
    // Spin a little first: queries come in bursts (a servo loop's neighbours, a benchmark), and
    // a futex wake costs tens of microseconds on a busy machine. Then sleep.
    const auto spin_until = std::chrono::steady_clock::now() + std::chrono::microseconds(spin_us_);
    std::uint64_t word = job_.load(std::memory_order_acquire);
    while (job_number(word) == seen && std::chrono::steady_clock::now() < spin_until) {
      cpu_relax();
      word = job_.load(std::memory_order_acquire);
    }
    // Sleep until a new job is published.
    while (job_number(word) == seen) {
      const std::uint32_t wake = wake_.load(std::memory_order_seq_cst);
      sleepers_.fetch_add(1, std::memory_order_seq_cst);
      word = job_.load(std::memory_order_seq_cst);
      if (job_number(word) == seen) futex_wait(wake_, wake);
      sleepers_.fetch_sub(1, std::memory_order_seq_cst);
      word = job_.load(std::memory_order_acquire);
    }
    seen = job_number(word);
    if (stop_.load(std::memory_order_acquire)) return;
    run_tasks();
  }
}

void QueryPool::run(void (*fn)(void*, int), void* ctx, int tasks) noexcept {
  if (tasks <= 0) return;
  const std::uint64_t n = std::min<std::uint64_t>(std::uint64_t(tasks), kIndexMask);
  if (threads_count_ == 1 || n == 1) {
    for (std::uint64_t t = 0; t < n; ++t) fn(ctx, int(t));
    return;
  }
  fn_ = fn;
  ctx_ = ctx;
  done_.store(0, std::memory_order_relaxed);
  // Every task of the previous job is done, so nobody holds a claim: publish the new job
  // (release: fn_, ctx_ and done_ are visible to whoever claims one of its tasks).
  const std::uint64_t number = job_number(job_.load(std::memory_order_relaxed)) + 1;
  publish((number << 32) | (n << kIndexBits));
  run_tasks();
  while (std::uint64_t(done_.load(std::memory_order_acquire)) < n) cpu_relax();
}

int default_query_threads(unsigned cores) noexcept {
  const int spare = int(cores) - 2;
  return std::clamp(spare, 1, 4);
}

}  // namespace gshaptics
