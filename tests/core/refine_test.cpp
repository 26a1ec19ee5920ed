// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/refine.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

RefineParams params(const std::string& scheme, int levels, double crease = 35.0) {
  RefineParams p;
  p.scheme = scheme;
  p.levels = levels;
  p.features.crease_angle_deg = crease;
  p.features.crease_mode = CreaseMode::Angle;  // a given angle is the user's override
  return p;
}

// Calls p.validate() and returns the field of the InvalidParameter it throws ("" if none).
std::string invalid_field(const RefineParams& p) {
  try {
    p.validate();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    return e.field().empty() ? "<empty field>" : e.field();
  }
  return "";
}

TEST(RefineParams, DefaultsAreValid) {
  EXPECT_NO_THROW(RefineParams{}.validate());
  EXPECT_EQ(RefineParams{}.features.crease_angle_deg, 35.0);
}

TEST(RefineParams, ValidateNamesTheField) {
  for (int levels : {-1, 9, 100, std::numeric_limits<int>::min()}) {
    RefineParams p;
    p.levels = levels;
    EXPECT_EQ(invalid_field(p), "levels") << levels;
  }
  for (int levels : {0, 1, 8}) {
    RefineParams p;
    p.levels = levels;
    EXPECT_EQ(invalid_field(p), "") << levels;
  }
  for (double angle : {-1.0, 181.0, std::numeric_limits<double>::quiet_NaN(),
                       -std::numeric_limits<double>::infinity()}) {
    RefineParams p;
    p.features.crease_angle_deg = angle;
    EXPECT_NE(invalid_field(p).find("crease_angle"), std::string::npos) << angle;
  }
  {
    RefineParams p;
    p.max_faces = 0;
    EXPECT_EQ(invalid_field(p), "max_faces");
    p.max_faces = std::uint64_t{1} << 31;
    EXPECT_EQ(invalid_field(p), "max_faces");
    p.max_faces = (std::uint64_t{1} << 31) - 1;
    EXPECT_EQ(invalid_field(p), "");
  }
  for (int threads : {-1, 257}) {
    RefineParams p;
    p.threads = threads;
    EXPECT_EQ(invalid_field(p), "threads") << threads;
  }
  {
    RefineParams p;
    p.scheme = "catmull-clark";
    EXPECT_EQ(invalid_field(p), "scheme");
  }
}

TEST(Refine, RejectsInvalidParametersBeforeWork) {
  RefineParams p = params("butterfly", 9);
  try {
    refine(to_mesh(icosahedron_soup()), p);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    EXPECT_EQ(e.field(), "levels");
  }
}

TEST(Refine, LevelsZeroReturnsTheInputUnchanged) {
  for (const char* scheme : {"loop", "butterfly"}) {
    const Mesh input = to_mesh(cube_soup(2.0));
    const RefineResult r = refine(input, params(scheme, 0));
    ASSERT_EQ(r.mesh.num_vertices(), input.num_vertices());
    ASSERT_EQ(r.mesh.num_faces(), input.num_faces());
    for (std::uint32_t v = 0; v < input.num_vertices(); ++v)
      EXPECT_EQ(r.mesh.position(VertexId(v)), input.position(VertexId(v)));
    for (std::uint32_t h = 0; h < input.num_halfedges(); ++h)
      EXPECT_EQ(r.mesh.from(HalfedgeId(h)), input.from(HalfedgeId(h)));
    EXPECT_EQ(r.report.output_faces, 12u);
    EXPECT_EQ(r.report.levels, 0);
    EXPECT_EQ(r.report.max_input_displacement, 0.0);
  }
}

TEST(Refine, MatchesRepeatedSingleSteps) {
  for (const char* scheme : {"loop", "butterfly"}) {
    const Mesh input = to_mesh(cylinder_soup(12, 5, 8));
    const RefineResult r = refine(input, params(scheme, 2));
    const Level manual = refine_levels(scheme, make_level(input, 35.0), 2);
    ASSERT_EQ(r.mesh.num_vertices(), manual.mesh.num_vertices());
    for (std::uint32_t v = 0; v < manual.mesh.num_vertices(); ++v)
      EXPECT_VEC_NEAR(r.mesh.position(VertexId(v)), manual.mesh.position(VertexId(v)), 1e-12);
    EXPECT_EQ(r.mesh.check_invariants(), "");
  }
}

TEST(Refine, ReportCounts) {
  const Mesh input = to_mesh(cube_soup(1.0));
  const RefineResult r = refine(input, params("butterfly", 3));
  EXPECT_EQ(r.report.scheme, "butterfly");
  EXPECT_EQ(r.report.levels, 3);
  EXPECT_EQ(r.report.input_vertices, 8u);
  EXPECT_EQ(r.report.input_faces, 12u);
  EXPECT_EQ(r.report.output_faces, 12u * 64u);
  EXPECT_EQ(r.report.output_vertices, r.mesh.num_vertices());
  EXPECT_EQ(r.report.output_faces, r.mesh.num_faces());
  EXPECT_EQ(r.report.sharp_edges_in, 12u);
  EXPECT_EQ(r.report.sharp_edges_out, 12u * 8u);
  EXPECT_EQ(r.report.corners, 8u);
  EXPECT_EQ(r.report.darts, 0u);
  EXPECT_GE(r.report.seconds, 0.0);
}

TEST(Refine, MaxInputDisplacement) {
  const Mesh ico = to_mesh(icosahedron_soup());
  EXPECT_EQ(refine(ico, params("butterfly", 2, 180)).report.max_input_displacement, 0.0);
  EXPECT_EQ(refine(to_mesh(cube_soup(1.0)), params("butterfly", 1)).report.max_input_displacement,
            0.0);
  // Loop pulls each icosahedron vertex from radius 1 to 0.7675720593 in the first step.
  const double one = refine(ico, params("loop", 1, 180)).report.max_input_displacement;
  EXPECT_NEAR(one, 1.0 - 0.7675720593359079, 1e-12);
  EXPECT_GT(refine(ico, params("loop", 2, 180)).report.max_input_displacement, one);
}

TEST(Refine, FaceBudgetPrediction) {
  RefineParams p = params("butterfly", 3);
  EXPECT_EQ(check_face_budget(20, p), 1280u);
  p.max_faces = 1280;
  EXPECT_EQ(check_face_budget(20, p), 1280u);  // at the limit is fine
  p.max_faces = 1279;
  try {
    check_face_budget(20, p);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded);
    EXPECT_EQ(e.field(), "max_faces");
    EXPECT_NE(std::string(e.what()).find("1280"), std::string::npos) << e.what();
  }
}

TEST(Refine, BudgetExceededBeforeAnyWork) {
  // 20480 faces * 4^8 = 1.34e9 faces: refusing must be instant, and no progress reported.
  const Mesh sphere = to_mesh(icosphere_soup(5));
  ASSERT_EQ(sphere.num_faces(), 20480u);
  RefineParams p = params("loop", 8);
  int progress_calls = 0;
  const auto start = std::chrono::steady_clock::now();
  try {
    refine(sphere, p, [&](double, std::string_view) { ++progress_calls; });
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded);
    EXPECT_NE(std::string(e.what()).find("1342177280"), std::string::npos) << e.what();
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 0.5);
  // A level of work would have reported progress first.
  EXPECT_EQ(progress_calls, 0);
}

TEST(Refine, CancelledBeforeStart) {
  std::atomic<bool> cancel{true};
  try {
    refine(to_mesh(icosphere_soup(2)), params("butterfly", 3), {}, &cancel);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Cancelled);
  }
}

TEST(Refine, ProgressIsMonotoneInUnitRange) {
  std::vector<double> seen;
  refine(to_mesh(icosphere_soup(2)), params("loop", 3),
         [&](double f, std::string_view) { seen.push_back(f); });
  ASSERT_FALSE(seen.empty());
  for (std::size_t i = 0; i < seen.size(); ++i) {
    EXPECT_GE(seen[i], 0.0);
    EXPECT_LE(seen[i], 1.0);
    if (i > 0) {
      EXPECT_GE(seen[i], seen[i - 1]);
    }
  }
}

TEST(Refine, ThreadCountDoesNotChangeTheResult) {
  const Mesh input = to_mesh(icosphere_soup(3));
  RefineParams p1 = params("butterfly", 2, 180);
  p1.threads = 1;
  RefineParams p2 = p1;
  p2.threads = 2;
  const RefineResult a = refine(input, p1), b = refine(input, p2);
  ASSERT_EQ(a.mesh.num_vertices(), b.mesh.num_vertices());
  for (std::uint32_t v = 0; v < a.mesh.num_vertices(); ++v)
    EXPECT_EQ(a.mesh.position(VertexId(v)), b.mesh.position(VertexId(v)));
}

TEST(Refine, ReportsFoldFallbacksOfTheSteps) {
  const Mesh cyl = to_mesh(cylinder_soup(8, 10, 100));
  std::size_t steps = 0;
  refine_levels("butterfly", make_level(cyl, 180), 2, &steps);
  EXPECT_EQ(refine(cyl, params("butterfly", 2, 180)).report.fold_fallbacks, steps);
}

TEST(Refine, CancelInsideALevelStopsTheParallelLoops) {
  // Raised from another thread while a level runs: the loops skip their remaining chunks
  // and refine() throws Cancelled long before the level would have finished.
  std::atomic<bool> cancel{false};
  std::atomic<std::size_t> visited{0};
  const CancelScope scope(&cancel);
  EXPECT_THROW(parallel_for_each_index(1u << 22,
                                       [&](std::size_t i) {
                                         if (i == 5000) cancel = true;
                                         ++visited;
                                       }),
               Error);
  EXPECT_LT(visited.load(), std::size_t{1} << 21);
  cancel = false;
  visited = 0;
  parallel_for_each_index(1u << 16, [&](std::size_t) { ++visited; });  // not raised: all run
  EXPECT_EQ(visited.load(), std::size_t{1} << 16);
}

}  // namespace
}  // namespace stlrefine::test
