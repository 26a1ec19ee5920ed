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
// Each comes for one double, for a pair (V2d, GCC/Clang vector extensions: two lanes of
// SSE2 on x86-64, plain scalar code elsewhere) and for a quadruple (V4d: one AVX register,
// or two SSE2 ones); all run the same operations, so a lane gives exactly the scalar result.
//
// Only exact mathematics goes in: Taylor coefficients 1/n! and (-1)^k/(2k+1), the
// arctangents of j/8 from std::atan, and pi/2 split into pieces for the reduction.

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#if defined(__AVX__)
#include <immintrin.h>
#elif defined(__SSE2__)
#include <emmintrin.h>
#endif

// 32-byte vectors (V4d) in the signatures of internal inline functions: GCC warns that
// their ABI differs with and without AVX, which cannot matter for functions never called
// across translation units built with different flags. Deliberately not popped: it holds
// for the includer's own V4d functions and calls (lsf_kernels.cpp, the tests) too.
#if defined(__clang__)
#pragma clang diagnostic ignored "-Wunknown-warning-option"
#endif
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

namespace stlrefine::lsf_math {

using V2d = double __attribute__((vector_size(16)));
using V2i = std::int64_t __attribute__((vector_size(16)));  // lane masks and bits
using V4d = double __attribute__((vector_size(32)));
using V4i = std::int64_t __attribute__((vector_size(32)));

namespace detail {

//! atan(j / 8) for j = 0..8, from std::atan (accurate to half an ulp or so).
inline const std::array<double, 9> kAtanEighths = [] {
  std::array<double, 9> t{};
  for (int j = 0; j < 9; ++j) t[j] = std::atan(j / 8.0);
  return t;
}();

// pi/2 = kPio2Hi + kPio2Mid + kPio2Lo, the first two with 33 significant bits, so k times
// them is exact for |k| < 2^20 (Cody-Waite reduction).
constexpr double kPio2Hi = 0x1.921fb544p+0;
constexpr double kPio2Mid = 0x1.0b4611a6p-34;
constexpr double kPio2Lo = 0x1.3198a2e037073p-69;
constexpr double kTwoOverPi = 0x1.45f306dc9c883p-1;
//! Larger arguments go to std::sin / std::cos (|k| stays far below 2^20).
constexpr double kSincosLimit = 1e5;
//! Adding 1.5 * 2^52 to a double of magnitude below 2^51 rounds it to an integer (to
//! nearest, the default mode) held in the low bits of the sum's mantissa, in two's
//! complement modulo 2^51; subtracting it again gives that integer as a double.
constexpr double kRoundMagic = 0x1.8p52;
constexpr std::int64_t kSignBit = std::numeric_limits<std::int64_t>::min();

//! atan(t) for |t| <= 1/16: Taylor to t^13; the first omitted term is below 2^-60 / 15.
template <class T>
T atan_small(T t) {
  const T t2 = t * t;
  const T p =
      -1.0 / 3 +
      t2 * (1.0 / 5 + t2 * (-1.0 / 7 + t2 * (1.0 / 9 + t2 * (-1.0 / 11 + t2 * (1.0 / 13)))));
  return t + t * t2 * p;
}

//! sin(r) and cos(r) for |r| <= pi/4 (+ rounding): Taylor to r^17 and r^16; the first
//! omitted terms are below 1e-19.
template <class T>
void sincos_small(T r, T& s, T& c) {
  const T r2 = r * r;
  const T sp =
      -1.0 / 6 +
      r2 * (1.0 / 120 +
            r2 * (-1.0 / 5040 +
                  r2 * (1.0 / 362880 +
                        r2 * (-1.0 / 39916800 +
                              r2 * (1.0 / 6227020800 +
                                    r2 * (-1.0 / 1307674368000 + r2 * (1.0 / 355687428096000)))))));
  const T cp =
      1.0 / 24 +
      r2 * (-1.0 / 720 +
            r2 * (1.0 / 40320 + r2 * (-1.0 / 3628800 + r2 * (1.0 / 479001600 +
                                                             r2 * (-1.0 / 87178291200 +
                                                                   r2 * (1.0 / 20922789888000))))));
  s = r + r * r2 * sp;
  c = 1.0 - 0.5 * r2 + (r2 * r2) * cp;
}

// Bit views and lane selection, the same for one double (bool masks) and a pair.
inline std::int64_t bits(double x) {
  return std::bit_cast<std::int64_t>(x);
}
inline double from_bits(std::int64_t b) {
  return std::bit_cast<double>(b);
}
inline V2i bits(V2d x) {
  return reinterpret_cast<V2i>(x);
}
inline V2d from_bits(V2i b) {
  return reinterpret_cast<V2d>(b);
}
inline V4i bits(V4d x) {
  return reinterpret_cast<V4i>(x);
}
inline V4d from_bits(V4i b) {
  return reinterpret_cast<V4d>(b);
}
inline double select(bool m, double a, double b) {
  return m ? a : b;
}
inline V2d select(V2i m, V2d a, V2d b) {
  return from_bits((bits(a) & m) | (bits(b) & ~m));
}
inline V4d select(V4i m, V4d a, V4d b) {
  return from_bits((bits(a) & m) | (bits(b) & ~m));
}
inline double abs(double x) {
  return std::abs(x);
}
inline V2d abs(V2d x) {
  return from_bits(bits(x) & ~kSignBit);
}
inline V4d abs(V4d x) {
  return from_bits(bits(x) & ~kSignBit);
}
inline double atan_eighths(std::int64_t j) {
  return kAtanEighths[j & 15];
}
inline V2d atan_eighths(V2i j) {
  return V2d{kAtanEighths[j[0] & 15], kAtanEighths[j[1] & 15]};
}
inline V4d atan_eighths(V4i j) {
  return V4d{kAtanEighths[j[0] & 15], kAtanEighths[j[1] & 15], kAtanEighths[j[2] & 15],
             kAtanEighths[j[3] & 15]};
}
// All ones where the low bit of q is set.
inline bool odd(std::int64_t q) {
  return (q & 1) != 0;
}
inline V2i odd(V2i q) {
  return V2i{0, 0} - (q & 1);
}
inline V4i odd(V4i q) {
  return V4i{0, 0, 0, 0} - (q & 1);
}
// The sign bit where bit 1 of q is set.
inline std::int64_t sign_of_bit1(std::int64_t q) {
  return (0 - ((q >> 1) & 1)) & kSignBit;
}
inline V2i sign_of_bit1(V2i q) {
  return (V2i{0, 0} - ((q >> 1) & 1)) & kSignBit;
}
inline V4i sign_of_bit1(V4i q) {
  return (V4i{0, 0, 0, 0} - ((q >> 1) & 1)) & kSignBit;
}

// The fast paths; `ok` is false (a lane of zeros) where the caller must use std::.
template <class T, class M>
T atan2_core(T y, T x, M& ok) {
  const T ax = abs(x), ay = abs(y);
  const M swap = ay > ax;
  const T num = select(swap, ax, ay);
  const T den = select(swap, ay, ax);
  // Zero, infinite and NaN arguments (signed zeros, quadrants at infinity) go to std::.
  ok = (den > 0) & (den <= std::numeric_limits<double>::max()) & (num <= den);
  const T t = num / den;  // [0, 1]
  const T jm = t * 8.0 + kRoundMagic;
  const T c = (jm - kRoundMagic) * 0.125;
  // atan(t) = atan(c) + atan((t - c) / (1 + t c)), |t - c| <= 1/16.
  T a = atan_eighths(bits(jm)) + atan_small((t - c) / (1.0 + t * c));
  a = select(swap, std::numbers::pi / 2 - a, a);
  a = select(x < 0.0, std::numbers::pi - a, a);
  return from_bits(bits(a) ^ (bits(y) & kSignBit));
}

template <class T, class M>
void sincos_core(T x, T& s, T& c, M& ok) {
  ok = abs(x) <= kSincosLimit;  // false for huge and NaN arguments
  const T km = x * kTwoOverPi + kRoundMagic;
  const T k = km - kRoundMagic;
  const T r = ((x - k * kPio2Hi) - k * kPio2Mid) - k * kPio2Lo;
  T sr, cr;
  sincos_small(r, sr, cr);
  const auto q = bits(km);  // k modulo 4 in the low bits
  const M swap = odd(q);
  s = from_bits(bits(select(swap, cr, sr)) ^ sign_of_bit1(q));
  c = from_bits(bits(select(swap, sr, cr)) ^ sign_of_bit1(q + 1));
}

}  // namespace detail

//! atan2(y, x) in [-pi, pi], within a few units in the last place of std::atan2.
inline double atan2(double y, double x) {
  bool ok;
  const double a = detail::atan2_core(y, x, ok);
  return ok ? a : std::atan2(y, x);
}

//! atan2 of two pairs, lane by lane exactly as the scalar version.
inline V2d atan2(V2d y, V2d x) {
  V2i ok;
  const V2d a = detail::atan2_core(y, x, ok);
  if (ok[0] && ok[1]) [[likely]]
    return a;
  return V2d{atan2(y[0], x[0]), atan2(y[1], x[1])};
}

//! atan2 of four lanes, lane by lane exactly as the scalar version.
inline V4d atan2(V4d y, V4d x) {
  V4i ok;
  const V4d a = detail::atan2_core(y, x, ok);
  if (ok[0] && ok[1] && ok[2] && ok[3]) [[likely]]
    return a;
  return V4d{atan2(y[0], x[0]), atan2(y[1], x[1]), atan2(y[2], x[2]), atan2(y[3], x[3])};
}

//! sin(x) and cos(x), within a few units in the last place of std::sin / std::cos.
inline void sincos(double x, double& s, double& c) {
  bool ok;
  detail::sincos_core(x, s, c, ok);
  if (!ok) [[unlikely]] {
    s = std::sin(x);
    c = std::cos(x);
  }
}

//! sincos of a pair, lane by lane exactly as the scalar version.
inline void sincos(V2d x, V2d& s, V2d& c) {
  V2i ok;
  detail::sincos_core(x, s, c, ok);
  if (ok[0] && ok[1]) [[likely]]
    return;
  for (int i = 0; i < 2; ++i) {
    double si, ci;
    sincos(x[i], si, ci);
    s[i] = si, c[i] = ci;
  }
}

//! sincos of four lanes, lane by lane exactly as the scalar version.
inline void sincos(V4d x, V4d& s, V4d& c) {
  V4i ok;
  detail::sincos_core(x, s, c, ok);
  if (ok[0] && ok[1] && ok[2] && ok[3]) [[likely]]
    return;
  for (int i = 0; i < 4; ++i) {
    double si, ci;
    sincos(x[i], si, ci);
    s[i] = si, c[i] = ci;
  }
}

//! Square roots of a pair (correctly rounded, as std::sqrt).
inline V2d sqrt(V2d x) {
#if defined(__SSE2__)
  return reinterpret_cast<V2d>(_mm_sqrt_pd(reinterpret_cast<__m128d>(x)));
#else
  return V2d{std::sqrt(x[0]), std::sqrt(x[1])};
#endif
}

//! Square roots of four lanes (correctly rounded, as std::sqrt).
inline V4d sqrt(V4d x) {
#if defined(__AVX__)
  return reinterpret_cast<V4d>(_mm256_sqrt_pd(reinterpret_cast<__m256d>(x)));
#else
  const V2d lo = sqrt(V2d{x[0], x[1]}), hi = sqrt(V2d{x[2], x[3]});
  return V4d{lo[0], lo[1], hi[0], hi[1]};
#endif
}

}  // namespace stlrefine::lsf_math
