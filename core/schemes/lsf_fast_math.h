// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Inline atan2 and sincos for LSF's Welch-Witkin parameters (one atan2 per ring gap, one
// sincos per ring point, for every vertex of every level). glibc's versions are calls
// with argument checks, slow paths and rounding-mode guards; these are straight-line code
// of the same accuracy to within a few units in the last place (tests/core/lsf_test.cpp
// bounds the difference to std:: over the whole double range). Arguments outside the
// range the fast path is built for (non-finite, zero, huge) go to std::.
//
// Only exact mathematics goes in: Taylor coefficients 1/n! and (-1)^k/(2k+1), the
// arctangents of j/8 from std::atan, and pi/2 split into pieces for the reduction.

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

namespace stlrefine::lsf_math {

namespace detail {

//! atan(j / 8) for j = 0..8, from std::atan (accurate to half an ulp or so).
inline const std::array<double, 9> kAtanEighths = [] {
  std::array<double, 9> t{};
  for (int j = 0; j < 9; ++j) t[j] = std::atan(j / 8.0);
  return t;
}();

//! atan(t) for |t| <= 1/16: Taylor to t^13; the first omitted term is below 2^-60 / 15.
inline double atan_small(double t) {
  const double t2 = t * t;
  const double p =
      -1.0 / 3 +
      t2 * (1.0 / 5 + t2 * (-1.0 / 7 + t2 * (1.0 / 9 + t2 * (-1.0 / 11 + t2 * (1.0 / 13)))));
  return t + t * t2 * p;
}

// pi/2 = kPio2Hi + kPio2Mid + kPio2Lo, the first two with 33 significant bits, so k times
// them is exact for |k| < 2^20 (Cody-Waite reduction).
constexpr double kPio2Hi = 0x1.921fb544p+0;
constexpr double kPio2Mid = 0x1.0b4611a6p-34;
constexpr double kPio2Lo = 0x1.3198a2e037073p-69;
constexpr double kTwoOverPi = 0x1.45f306dc9c883p-1;
//! Larger arguments go to std::sin / std::cos (|k| stays far below 2^20).
constexpr double kSincosLimit = 1e5;
//! Adding and subtracting 1.5 * 2^52 rounds a double of magnitude below 2^51 to an integer
//! (round to nearest, the default mode), without a library call.
constexpr double kRoundMagic = 0x1.8p52;

//! sin(r) and cos(r) for |r| <= pi/4 (+ rounding): Taylor to r^17 and r^16; the first
//! omitted terms are below 1e-19.
inline void sincos_small(double r, double& s, double& c) {
  const double r2 = r * r;
  const double sp =
      -1.0 / 6 +
      r2 * (1.0 / 120 +
            r2 * (-1.0 / 5040 +
                  r2 * (1.0 / 362880 +
                        r2 * (-1.0 / 39916800 +
                              r2 * (1.0 / 6227020800 +
                                    r2 * (-1.0 / 1307674368000 + r2 * (1.0 / 355687428096000)))))));
  const double cp =
      1.0 / 24 +
      r2 * (-1.0 / 720 +
            r2 * (1.0 / 40320 + r2 * (-1.0 / 3628800 + r2 * (1.0 / 479001600 +
                                                             r2 * (-1.0 / 87178291200 +
                                                                   r2 * (1.0 / 20922789888000))))));
  s = r + r * r2 * sp;
  c = 1.0 - 0.5 * r2 + (r2 * r2) * cp;
}

}  // namespace detail

//! atan2(y, x) in [-pi, pi], within a few units in the last place of std::atan2.
inline double atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const bool swap = ay > ax;
  const double num = swap ? ax : ay;
  const double den = swap ? ay : ax;
  // Zero, infinite and NaN arguments (signed zeros, quadrants at infinity): std::.
  if (!(den > 0 && den <= std::numeric_limits<double>::max() && num <= den))
    return std::atan2(y, x);
  const double t = num / den;  // [0, 1]
  const int j = static_cast<int>(t * 8.0 + 0.5);
  const double c = j * 0.125;
  // atan(t) = atan(c) + atan((t - c) / (1 + t c)), |t - c| <= 1/16.
  double a = detail::kAtanEighths[j] + detail::atan_small((t - c) / (1.0 + t * c));
  if (swap) a = std::numbers::pi / 2 - a;
  if (x < 0) a = std::numbers::pi - a;
  return std::signbit(y) ? -a : a;
}

//! sin(x) and cos(x), within a few units in the last place of std::sin / std::cos.
inline void sincos(double x, double& s, double& c) {
  if (!(std::abs(x) <= detail::kSincosLimit)) {  // huge or NaN
    s = std::sin(x);
    c = std::cos(x);
    return;
  }
  const double k = (x * detail::kTwoOverPi + detail::kRoundMagic) - detail::kRoundMagic;
  const double r = ((x - k * detail::kPio2Hi) - k * detail::kPio2Mid) - k * detail::kPio2Lo;
  double sr, cr;
  detail::sincos_small(r, sr, cr);
  const auto q = static_cast<std::uint32_t>(static_cast<std::int64_t>(k)) & 3u;
  const double s1 = (q & 1u) ? cr : sr;
  const double c1 = (q & 1u) ? sr : cr;
  s = (q & 2u) ? -s1 : s1;
  c = ((q + 1u) & 2u) ? -c1 : c1;
}

}  // namespace stlrefine::lsf_math
