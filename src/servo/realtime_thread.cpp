#include "gshaptics/servo/realtime_thread.h"

#include <pthread.h>
#include <sched.h>

#include <cerrno>

namespace gshaptics {

int pin_thread_to_cpu(std::thread::native_handle_type thread, int cpu) noexcept {
  if (cpu < 0 || cpu >= CPU_SETSIZE) return EINVAL;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(thread, sizeof set, &set);
}

int set_fifo_priority(std::thread::native_handle_type thread, int priority) noexcept {
  sched_param sp{};
  sp.sched_priority = priority;
  return pthread_setschedparam(thread, SCHED_FIFO, &sp);
}

}  // namespace gshaptics
