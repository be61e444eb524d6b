#include "gshaptics/servo/query_pool.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include "gshaptics/error.h"

namespace gshaptics {

QueryPool::QueryPool(int parts, const std::vector<int>& cpus, int spin_us) : parts_(std::max(1, parts)), spin_us_(std::max(0, spin_us)) {
  if (parts < 1 || parts > 64) throw InputError("query threads: must be 1..64, got " + std::to_string(parts));
  for (int p = 1; p < parts_; ++p) {
    threads_.emplace_back([this, p] { worker(p); });
    if (std::size_t(p - 1) < cpus.size()) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(cpus[std::size_t(p - 1)], &set);
      const int err = pthread_setaffinity_np(threads_.back().native_handle(), sizeof set, &set);
      if (err != 0)
        warnings_.push_back("query thread " + std::to_string(p) + ": not pinned to CPU " +
                            std::to_string(cpus[std::size_t(p - 1)]) + ": " + std::strerror(err));
    }
  }
}

QueryPool::~QueryPool() {
  stop_.store(true, std::memory_order_release);
  epoch_.fetch_add(1, std::memory_order_acq_rel);
  epoch_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void QueryPool::worker(int part) noexcept {
  std::uint64_t seen = 0;
  for (;;) {
    // Spin a little first: queries come in bursts (a servo loop's neighbours, a benchmark), and
    // a futex wake costs tens of microseconds on a busy machine. Then sleep.
    const auto spin_until = std::chrono::steady_clock::now() + std::chrono::microseconds(spin_us_);
    while (epoch_.load(std::memory_order_acquire) == seen && std::chrono::steady_clock::now() < spin_until) {
#if defined(__x86_64__)
      __builtin_ia32_pause();
#endif
    }
    epoch_.wait(seen, std::memory_order_acquire);
    const std::uint64_t now = epoch_.load(std::memory_order_acquire);
    if (now == seen) continue;  // spurious wake
    seen = now;
    if (stop_.load(std::memory_order_acquire)) return;
    fn_(ctx_, part);
    done_.fetch_add(1, std::memory_order_acq_rel);
  }
}

void QueryPool::run(void (*fn)(void*, int), void* ctx) noexcept {
  if (parts_ == 1) {
    fn(ctx, 0);
    return;
  }
  fn_ = fn;
  ctx_ = ctx;
  done_.store(0, std::memory_order_relaxed);
  epoch_.fetch_add(1, std::memory_order_acq_rel);  // publishes fn_/ctx_ (release)
  epoch_.notify_all();
  fn(ctx, 0);
  const int workers = parts_ - 1;
  while (done_.load(std::memory_order_acquire) < workers) {
#if defined(__x86_64__)
    __builtin_ia32_pause();
#endif
  }
}

int default_query_threads(unsigned cores) noexcept {
  const int spare = int(cores) - 2;
  return std::clamp(spare, 1, 4);
}

}  // namespace gshaptics
