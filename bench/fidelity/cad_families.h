// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// stlrefine_fidelity --cad-families: every scheme on every CAD-like family
// (tests/support/cad_like.h) for many seeds, against the true surfaces (issue 17).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace stlrefine::fidelity {

struct CadOptions {
  std::vector<std::string> families;  //!< cad_family_name()s; empty: all
  int seeds = 10;
  std::uint64_t seed_base = 1000;  //!< seeds seed_base, seed_base + 1, ...
  double coarseness = 1.0;
  std::vector<std::string> schemes{"lsf",          "butterfly", "sqrt3-interp", "sqrt3-unified",
                                   "butterfly-g1", "loop",      "loop-g2",      "sqrt3"};
  std::vector<int> levels{1, 2, 3};  //!< 1-to-4 levels; sqrt3 schemes make twice as many steps
  bool openmesh = true;              //!< ModifiedButterflyT and InterpolatingSqrt3LGT rows
  double crease_angle_deg = 35;
  int jobs = 1;                  //!< seeds run in parallel (each refinement single-threaded)
  std::size_t samples = 60'000;  //!< distance samples per mesh
};

//! Markdown to stdout, progress to stderr. Returns the process exit code.
int run_cad_families(const CadOptions& options);

}  // namespace stlrefine::fidelity
