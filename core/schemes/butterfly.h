// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <vector>

#include "core/schemes/split4_host.h"

namespace stlrefine {

//! Zorin, Schroeder and Sweldens' modified butterfly ("Interpolating subdivision for meshes
//! with arbitrary topology", SIGGRAPH 1996), with the crease handling of spec section 2:
//! the 4-point rule along sharp polylines and virtual points where a stencil would cross
//! a sharp edge. Interpolating: old vertices never move.
class ButterflyStencil final : public Split4Stencil {
 public:
  //! Rule at an edge with an extraordinary end: Zorin et al.'s one-ring rule (the modified
  //! butterfly, our `butterfly`), or the 8-point stencil of Dyn, Levin and Gregory's
  //! original butterfly (w = 1/16) at every vertex, the base of Prautzsch and Umlauf's G1
  //! butterfly (spec 6).
  enum class Extraordinary { Zorin, EightPoint };
  //! `check_normals`: run check_edge_points_against_normals (split4_host.h) on the Zorin
  //! rule's points (off: the paper's stencil alone, for tests).
  explicit ButterflyStencil(Extraordinary rule = Extraordinary::Zorin, bool check_normals = true);
  void edge_points(const Level& coarse, std::span<Vec3> out) const override;
  bool interpolating() const override { return true; }
  bool checks_against_normals() const override {
    return check_normals_ && rule_ == Extraordinary::Zorin;
  }

  //! Weight s_j of ring vertex j (offset from the edge's other end) in the rule around an
  //! extraordinary vertex of valence k; the centre weighs 3/4 and sum_j s_j = 1/4.
  static double extraordinary_weight(int k, int j);

 private:
  //! Edge point from the 1-ring of the extraordinary vertex from(h) alone.
  Vec3 one_sided_point(const Mesh& mesh, HalfedgeId h, int valence) const;
  //! Rows of s_j for valences below kCachedValences; larger ones are computed on the fly.
  static constexpr int kCachedValences = 64;
  Extraordinary rule_;
  bool check_normals_;
  std::vector<std::vector<double>> weights_;
};

}  // namespace stlrefine
