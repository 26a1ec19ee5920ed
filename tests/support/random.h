// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A seeded random source whose sequence is the same on every platform (std::mt19937_64 is
// specified bit for bit; the std distributions are not, so they are not used).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

#include "core/geometry/vec3.h"

namespace stlrefine::test {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}

  //! Uniform in [0, 1), 53 random bits.
  double uniform() { return double(engine_() >> 11) * 0x1.0p-53; }
  //! Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  //! Uniform integer in [lo, hi] (hi - lo small: the modulo bias is below 2^-50).
  int integer(int lo, int hi) {
    return lo + static_cast<int>(engine_() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  //! A uniformly distributed unit vector (Archimedes: z uniform, azimuth uniform).
  Vec3 unit_vector() {
    const double z = uniform(-1.0, 1.0);
    const double phi = uniform(0.0, 2.0 * std::numbers::pi);
    const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    return {s * std::cos(phi), s * std::sin(phi), z};
  }
  //! A fresh 64-bit value (to seed a derived generator).
  std::uint64_t next() { return engine_(); }

 private:
  std::mt19937_64 engine_;
};

}  // namespace stlrefine::test
