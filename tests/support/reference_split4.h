// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// An independent, deliberately plain re-implementation of one 1-to-4 step of Loop
// (spec section 1, Hoppe's sharp rules) and of the modified butterfly (spec section 2),
// written from docs/spec only. The production stencils are compared against it edge by
// edge, so a wrong weight anywhere shows up as a named edge with both values.
//
// Scope: any mesh and any sharp-edge set. For the butterfly, the spec does not say whether
// an interior edge at a dart vertex treats the dart as a crease vertex or as an interior
// vertex; those edges are marked `unspecified` and callers skip them.

#include <array>
#include <span>
#include <string>
#include <vector>

#include "core/schemes/scheme.h"

namespace stlrefine::test {

struct ReferenceStep {
  //! V entries (old vertices, moved for Loop) then one per coarse edge (index V + e).
  std::vector<Vec3> positions;
  //! Per coarse edge: true where the spec leaves the rule open (the point is a guess).
  std::vector<bool> unspecified;
};

ReferenceStep reference_loop_step(const Level& coarse);
ReferenceStep reference_butterfly_step(const Level& coarse);

//! Loop's beta(n) (spec section 1).
double loop_beta(int n);
//! Zorin's one-sided weights s_0..s_{k-1} (spec section 2): k = 3, 4 special, else formula.
std::vector<double> butterfly_ring_weights(int k);

//! Loop's regular crease test (spec section 1): a crease vertex (exactly two sharp edges)
//! that is interior with valence 6 and two smooth edges on each side, or on the boundary
//! with valence 4.
bool loop_regular_crease(const Level& level, VertexId v);

//! Fine faces of a 1-to-4 split in the order split4_host.h promises: 4f+k is the corner
//! triangle at corner k, 4f+3 the middle one (vertex ids: old ones, then V + e).
std::vector<std::array<std::uint32_t, 3>> reference_split4_faces(const Mesh& coarse);

//! Smallest cosine between a child face normal and its parent's normal, for the fine
//! positions `fine` laid out as in ReferenceStep (1 = no turn, < 0 = turned past 90 deg).
//! Degenerate (zero-normal) faces are skipped.
double min_child_parent_cos(const Mesh& coarse, std::span<const Vec3> fine);

}  // namespace stlrefine::test
