// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <vector>

#include "core/schemes/sqrt3_host.h"

namespace stlrefine {

//! Kobbelt's relaxation of old vertices (spec 4), shared by `sqrt3` and `sqrt3-unified`:
//! Delta(P) is how far Kobbelt's sqrt3 moves P in one step.
//! - smooth and dart vertices: beta_n (average of the 1-ring - P), beta_n = (4 - 2 cos(2 pi/n))/9;
//! - crease vertices: 4/27 (P_prev - 2P + P_next) in trisecting steps, 0 in the others
//!   (Kobbelt's boundary rule, only curve vertices used);
//! - corners (and isolated vertices): 0.
class KobbeltRelaxation {
 public:
  KobbeltRelaxation();
  static double beta(int valence);
  Vec3 displacement(const Sqrt3Step& step, VertexId v) const;

 private:
  static constexpr int kCachedValences = 64;  // larger valences are computed on the fly
  //! beta_n for n < kCachedValences, built once per process and shared (the scheme is
  //! made several times per request).
  static const std::vector<double>& cached_beta();
  const std::vector<double>& beta_;
};

//! Delta of curve vertex p between its curve neighbours (the curve part of the rule above).
inline Vec3 curve_displacement(const Vec3& before, const Vec3& p, const Vec3& after) {
  return (4.0 / 27.0) * (before - 2.0 * p + after);
}

//! Kobbelt's boundary rule for the new curve points (the cubic B-spline at 1/3 and 2/3 of
//! the middle edge of window = {P_i-1, P_i, P_i+1, P_i+2}):
//!   (P_i-1 + 16 P_i + 10 P_i+1)/27   and   (10 P_i + 16 P_i+1 + P_i+2)/27.
std::array<Vec3, 2> bspline_trisection(const std::array<Vec3, 4>& window);

//! Kobbelt's approximating sqrt3 ("sqrt3-Subdivision", SIGGRAPH 2000): face points are
//! centroids, old vertices move by Delta, sharp curves follow the cubic B-spline.
//! Equal to sqrt3-unified with alpha 0.
class KobbeltStencil final : public Sqrt3Stencil {
 public:
  bool interpolating() const override { return false; }
  void points(const Sqrt3Step& step, Sqrt3Points out) const override;
  Vec3 face_point(const Sqrt3Step& step, FaceId f) const override;
  Vec3 vertex_point(const Sqrt3Step& step, VertexId v) const override;
  std::array<Vec3, 2> curve_points(const Sqrt3Step& step, HalfedgeId h) const override;

 private:
  KobbeltRelaxation relaxation_;
};

}  // namespace stlrefine
