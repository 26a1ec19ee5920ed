// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The refinements the fidelity benchmark compares: our schemes through stlrefine::refine
// (uniform levels, or the curvature-adaptive mode: RefineParams::adaptive_tol / max_level)
// and OpenMesh's ModifiedButterflyT and InterpolatingSqrt3LGT.

#include <cstddef>
#include <string>

#include "core/mesh/mesh.h"

namespace stlrefine::fidelity {

struct Variant {
  enum class Kind { Ours, OursAdaptive, OpenMeshButterfly, OpenMeshSqrt3LG } kind = Kind::Ours;
  std::string scheme;       //!< our scheme name (Ours, OursAdaptive)
  int level = 1;            //!< uniform levels (sqrt3 steps); the level cap in adaptive mode
  double adaptive_tol = 0;  //!< mm, OursAdaptive only

  std::string label() const;
};

struct RunSettings {
  double crease_angle_deg = 35;
  int threads = 1;
  int reps = 3;  //!< the time is the median of this many runs
};

struct RunOutput {
  Mesh mesh;
  double seconds = 0;
  std::size_t fold_fallbacks = 0;
};

RunOutput run_variant(const Variant& variant, const Mesh& input, const RunSettings& settings);

}  // namespace stlrefine::fidelity
