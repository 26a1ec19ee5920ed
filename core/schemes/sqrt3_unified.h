// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include "core/schemes/sqrt3_kobbelt.h"

namespace stlrefine {

//! Lin and Luo's unified interpolatory / approximating sqrt3 ("A Unified Interpolatory and
//! Approximation sqrt3 Subdivision Scheme", 2007) with a per-vertex alpha in [0, 1]
//! (spec 4): 1 interpolates, 0 is Kobbelt's sqrt3. With Delta(P) Kobbelt's displacement:
//! - face point of (Pi, Pj, Pk): sum of (P - alpha_P Delta(P))/3 (eq. 8-10, sign errata per spec);
//! - old vertex: P + (1 - alpha_P) Delta(P) (eq. 11);
//! - curve point at 1/3: B-spline point - (2/3 alpha_i Delta_i + 1/3 alpha_i+1 Delta_i+1)
//!   (spec 4's unified curve rule: LG eqs. 17/19 at alpha 1, Kobbelt's rule at alpha 0).
//! The host gives a face point alpha (ai + aj + ak)/3 (eq. 7) and a curve point at 1/3
//! (2 ai + ai+1)/3.
class LinLuoStencil final : public Sqrt3Stencil {
 public:
  //! `alpha` for smooth and dart input vertices, `alpha_features` for crease and corner
  //! ones (boundaries included), both in [0, 1].
  LinLuoStencil(double alpha, double alpha_features)
      : alpha_(alpha), alpha_features_(alpha_features) {}
  bool interpolating() const override { return alpha_ == 1.0 && alpha_features_ == 1.0; }
  BigVector<double> initial_alpha(const Level& input) const override;
  void points(const Sqrt3Step& step, Sqrt3Points out) const override;
  Vec3 face_point(const Sqrt3Step& step, FaceId f) const override;
  Vec3 vertex_point(const Sqrt3Step& step, VertexId v) const override;
  std::array<Vec3, 2> curve_points(const Sqrt3Step& step, HalfedgeId h) const override;

 private:
  double alpha_, alpha_features_;
  KobbeltRelaxation relaxation_;
};

}  // namespace stlrefine
