#pragma once
// The ground-truth scenes' random numbers (internal to gshaptics_fidelity).

#include <cmath>
#include <cstdint>
#include <random>

namespace gshaptics::synth_detail {

inline constexpr double kPi = 3.14159265358979323846;

// Our own distributions over mt19937_64, so a seed gives the same file on any standard library.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  double uniform(double lo = 0, double hi = 1) { return lo + (hi - lo) * double(g_() >> 11) * (1.0 / 9007199254740992.0); }
  double normal() {  // Box-Muller
    const double u1 = std::max(uniform(), 1e-300), u2 = uniform();
    return std::sqrt(-2 * std::log(u1)) * std::cos(2 * kPi * u2);
  }

 private:
  std::mt19937_64 g_;
};

}  // namespace gshaptics::synth_detail
