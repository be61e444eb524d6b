#pragma once
/// @file
/// The two real-time settings a servo, worker or measuring thread asks the OS for (POSIX
/// threads, Linux): a fixed CPU and the SCHED_FIFO class. Both return the error number instead
/// of throwing, so each caller can say in its own words what it runs without.

#include <thread>

namespace gshaptics {

/// Pins `thread` to CPU `cpu` (pthread_setaffinity_np). Returns 0, or the error number (e.g.
/// EINVAL for a CPU that is not online).
int pin_thread_to_cpu(std::thread::native_handle_type thread, int cpu) noexcept;

/// Runs `thread` under SCHED_FIFO at `priority` (1-99; pthread_setschedparam). Returns 0, or the
/// error number (EPERM without CAP_SYS_NICE or an rtprio limit).
int set_fifo_priority(std::thread::native_handle_type thread, int priority) noexcept;

}  // namespace gshaptics
