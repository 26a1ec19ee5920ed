// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// GoogleTest helpers for the core suite: vector comparisons that print all three
// coordinates, and a one-call "refine one level" for a scheme name.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <string_view>

#include "core/schemes/registry.h"
#include "core/schemes/sqrt3_host.h"
#include "tests/support/mesh_queries.h"

namespace stlrefine::test {

inline std::string str(const Vec3& p) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "(%.17g, %.17g, %.17g)", p.x, p.y, p.z);
  return buf;
}

inline ::testing::AssertionResult vec_near(const char* a_expr, const char* b_expr,
                                           const char* /*tol_expr*/, const Vec3& a, const Vec3& b,
                                           double tol) {
  const double d = std::max({std::abs(a.x - b.x), std::abs(a.y - b.y), std::abs(a.z - b.z)});
  if (d <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << a_expr << " = " << str(a) << "\n"
                                       << b_expr << " = " << str(b) << "\n"
                                       << "max coordinate difference " << d << " > " << tol;
}

#define EXPECT_VEC_NEAR(a, b, tol) EXPECT_PRED_FORMAT3(::stlrefine::test::vec_near, a, b, tol)
#define ASSERT_VEC_NEAR(a, b, tol) ASSERT_PRED_FORMAT3(::stlrefine::test::vec_near, a, b, tol)

//! One step of the named scheme; the StepStats are returned through `stats`.
inline Level refine_level(std::string_view scheme, const Level& coarse,
                          StepStats* stats = nullptr) {
  StepStats local;
  auto s = make_scheme(scheme);
  Level fine = s->refine_once(coarse, stats ? *stats : local);
  return fine;
}

//! `levels` steps of the named scheme from `coarse`, accumulating the fold fallbacks.
inline Level refine_levels(std::string_view scheme, Level level, int levels,
                           std::size_t* fold_fallbacks = nullptr) {
  auto s = make_scheme(scheme);
  StepStats stats;
  for (int i = 0; i < levels; ++i) level = s->refine_once(level, stats);
  if (fold_fallbacks) *fold_fallbacks = stats.fold_fallbacks;
  return level;
}

//! A sqrt3 stencil's rules without the host's fold guard: for tests that read the linear
//! rules alone (weights off a lifted vertex) or compare with the adaptive sqrt3 host run
//! with FoldGuard::Off.
class UnguardedSqrt3 final : public Sqrt3Stencil {
 public:
  explicit UnguardedSqrt3(const Sqrt3Stencil& s) : s_(s) {}
  bool interpolating() const override { return s_.interpolating(); }
  bool guards_folds() const override { return false; }
  BigVector<double> initial_alpha(const Level& l) const override { return s_.initial_alpha(l); }
  void points(const Sqrt3Step& st, Sqrt3Points out) const override { s_.points(st, out); }
  Vec3 face_point(const Sqrt3Step& st, FaceId f) const override { return s_.face_point(st, f); }
  Vec3 vertex_point(const Sqrt3Step& st, VertexId v) const override {
    return s_.vertex_point(st, v);
  }
  std::array<Vec3, 2> curve_points(const Sqrt3Step& st, HalfedgeId h) const override {
    return s_.curve_points(st, h);
  }

 private:
  const Sqrt3Stencil& s_;
};

//! `levels` steps of the named scheme without a fold guard (refine_levels for others).
inline Level refine_levels_unguarded(std::string_view scheme, Level level, int levels) {
  const auto s = make_scheme(scheme);
  const auto* sqrt3 = dynamic_cast<const HostScheme<Sqrt3Stencil>*>(s.get());
  if (!sqrt3) return refine_levels(scheme, std::move(level), levels);
  const UnguardedSqrt3 stencil(sqrt3->stencil());
  StepStats stats;
  for (int i = 0; i < levels; ++i) level = sqrt3_refine(level, stencil, stats);
  return level;
}

}  // namespace stlrefine::test
