// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <vector>

#include "core/schemes/sqrt3_host.h"

namespace stlrefine {

//! Labsik and Greiner's interpolatory sqrt3 ("Interpolatory sqrt3-Subdivision", Eurographics
//! 2000), spec 3: the 12-point rule where every corner is regular, the single-step
//! extraordinary rule of spec 3.3 around an interior corner of valence n != 6 (averaged
//! over several such corners), virtual points where a stencil would cross a sharp edge,
//! and the trisection rules (17)-(19) along sharp curves. Old vertices never move.
class LabsikGreinerStencil final : public Sqrt3Stencil {
 public:
  LabsikGreinerStencil();
  bool interpolating() const override { return true; }
  void points(const Sqrt3Step& step, Sqrt3Points out) const override;
  Vec3 face_point(const Sqrt3Step& step, FaceId f) const override;
  Vec3 vertex_point(const Sqrt3Step& step, VertexId v) const override {
    return step.mesh.position(v);
  }
  std::array<Vec3, 2> curve_points(const Sqrt3Step& step, HalfedgeId h) const override;

  //! Regular rule (eq. 9): corners, tips across the edges, and the two far neighbours of
  //! each corner. 3 kCorner + 3 kTip + 6 kFar = 1.
  static constexpr double kCorner = 32.0 / 81.0, kTip = -1.0 / 81.0, kFar = -2.0 / 81.0;
  //! Extraordinary rule: the centre weighs 2/3 and ring vertex i (counted counter-clockwise
  //! from the triangle's next corner) alpha_i = (1/3 + 2/sqrt3 cos t + [n>=5] 2/3 cos 2t)/n
  //! with t = 2 pi (i - 1/2)/n; the alpha_i sum to 1/3.
  static constexpr double kCentre = 2.0 / 3.0;
  static double extraordinary_weight(int n, int i);

 private:
  //! The face point from the 1-ring of the extraordinary vertex from(h) (valence n in the
  //! step's lattice, virtual ring points included).
  Vec3 extraordinary_point(const Sqrt3Step& step, HalfedgeId h, int n) const;
  //! The face point of `face` given the extraordinary valence of each corner (0: regular).
  Vec3 face_point_from(const Sqrt3Step& step, FaceId face,
                       const std::array<int, 3>& extraordinary) const;
  static constexpr int kCachedValences = 64;  // larger valences are computed on the fly
  //! Weights of valences 3 .. kCachedValences - 1, built once per process and shared by
  //! every stencil (a scheme is made several times per request; building the table took
  //! 1.3 M instructions, more than refining a small mesh).
  static const std::vector<std::vector<double>>& cached_weights();
  const std::vector<std::vector<double>>& weights_;
};

}  // namespace stlrefine
