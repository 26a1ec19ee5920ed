// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include "core/schemes/split4_host.h"

namespace stlrefine {

//! Loop's approximating scheme with Hoppe et al.'s piecewise-smooth rules
//! (spec section 1; Hoppe et al. 1994, "Piecewise smooth surface reconstruction").
class LoopStencil final : public Split4Stencil {
 public:
  void edge_points(const Level& coarse, std::span<Vec3> out) const override;
  void vertex_points(const Level& coarse, std::span<Vec3> out) const override;
  bool interpolating() const override { return false; }
};

//! Loop's vertex weight: beta(n) = (5/8 - (3/8 + cos(2 pi / n) / 4)^2) / n.
double loop_beta(int valence);

//! True for a crease vertex whose neighbourhood is regular for Hoppe's rules: interior
//! with valence 6 and two smooth edges on each side of the crease, or boundary with
//! valence 4.
bool is_regular_crease_vertex(const Mesh& mesh, const Features& features, VertexId v);

}  // namespace stlrefine
