#pragma once
/// @file
/// exp(x) for x <= 0 written so that GCC vectorises it in a `#pragma omp simd` lane loop (glibc's
/// exp is a call the vectoriser cannot take without -ffast-math). The shaded normal's kernels
/// (force/shaded_normal.cpp) weigh every Gaussian by one or two of these.
///
/// Method: Cody & Waite's range reduction (Cody and Waite 1980, "Software Manual for the
/// Elementary Functions"), x = n ln 2 + r with |r| <= ln 2 / 2 and ln 2 split in two parts, e^r by
/// its Taylor polynomial to r^13 (truncation under 5e-18), and 2^n written into the exponent
/// bits. The integer n is read off the low bits of x log2(e) + 1.5 2^52, the usual rounding
/// trick, so no float-to-integer conversion is needed. Relative error within a few units in the
/// last place of std::exp (tests/lane_exp_test.cpp); exactly 1 at x = 0. Inputs below -708 give
/// exp(-708) (about 3e-308: no subnormals); NaN gives NaN; x > 0 is taken as 0.

#include <bit>
#include <cstdint>

namespace gshaptics {

[[nodiscard]] inline double lane_exp(double x) noexcept {
  constexpr double kLog2e = 1.4426950408889634074;
  constexpr double kLn2Hi = 6.93147180369123816490e-01;  // ln 2's leading 32 bits
  constexpr double kLn2Lo = 1.90821492927058770002e-10;  // the rest
  constexpr double kShift = 6755399441055744.0;          // 1.5 2^52: adding it rounds to an integer
  // (By value, not std::min/max's references, which the vectoriser cannot follow; NaN stays NaN.)
  x = x < -708.0 ? -708.0 : x;
  x = x > 0.0 ? 0.0 : x;
  const double t = x * kLog2e + kShift;
  const double n = t - kShift;
  const double r = (x - n * kLn2Hi) - n * kLn2Lo;
  // Horner, the coefficients 1 / k! from k = 13 down.
  double p = 1.0 / 6227020800.0;
  p = p * r + 1.0 / 479001600.0;
  p = p * r + 1.0 / 39916800.0;
  p = p * r + 1.0 / 3628800.0;
  p = p * r + 1.0 / 362880.0;
  p = p * r + 1.0 / 40320.0;
  p = p * r + 1.0 / 5040.0;
  p = p * r + 1.0 / 720.0;
  p = p * r + 1.0 / 120.0;
  p = p * r + 1.0 / 24.0;
  p = p * r + 1.0 / 6.0;
  p = p * r + 0.5;
  p = p * r + 1.0;
  p = p * r + 1.0;
  // 2^n for n in [-1022, 0]: the biased exponent n + 1023 in bits 52-62.
  const std::int64_t ni = std::bit_cast<std::int64_t>(t) - std::bit_cast<std::int64_t>(kShift);
  return p * std::bit_cast<double>(static_cast<std::uint64_t>(ni + 1023) << 52);
}

}  // namespace gshaptics
