// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "slicer/slice.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "tests/slicer/slicer_test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

using slicer::Layer;
using slicer::LoopKind;
using slicer::slice_all;

constexpr double kPi = std::numbers::pi;

// ------------------------------------------------------------------ simple solids

TEST(Slice, CubeGivesOneCounterClockwiseSquarePerLayer) {
  const Mesh cube = to_mesh(cube_soup(10.0));
  slicer::SliceStats stats;
  const std::vector<Layer> layers = slice_all(cube, uniform(1.0), &stats);
  ASSERT_EQ(layers.size(), 10u);
  EXPECT_EQ(stats.outer_loops, 10u);
  EXPECT_EQ(stats.holes + stats.open_polylines + stats.degenerate_loops + stats.reversed_loops, 0u);
  for (std::size_t k = 0; k < layers.size(); ++k) {
    const Layer& l = layers[k];
    EXPECT_EQ(l.index, k);
    EXPECT_DOUBLE_EQ(l.z, 0.5 + double(k));
    ASSERT_EQ(l.loops.size(), 1u) << "z = " << l.z;
    EXPECT_TRUE(l.open.empty());
    const auto& loop = l.loops[0];
    EXPECT_EQ(loop.kind, LoopKind::Outer);
    EXPECT_EQ(loop.parent, -1);
    EXPECT_EQ(loop.depth, 0);
    EXPECT_NEAR(loop.area, 100.0, 1e-12);  // > 0: counter-clockwise seen from +z
    EXPECT_NEAR(l.area, 100.0, 1e-12);
    EXPECT_TRUE(no_zero_length_edges(loop));
    for (const auto& p : loop.points) {
      EXPECT_TRUE(p.x == 0 || p.x == 10 || p.y == 0 || p.y == 10) << p.x << ", " << p.y;
    }
  }
}

TEST(Slice, UniformLayersFollowTheRangeAndTheMidLayerRule) {
  const Mesh cube = to_mesh(cube_soup(10.0));
  slicer::SliceParams p = uniform(3.0);
  EXPECT_EQ(slicer::plan_layers(cube, p).heights, (std::vector<double>{1.5, 4.5, 7.5}));
  p.z_min = 2.0;
  p.z_max = 4.0;
  EXPECT_EQ(slicer::plan_layers(cube, p).heights, (std::vector<double>{3.5}));
  p.z_max = 3.5;  // a plane exactly at z_max is kept
  EXPECT_EQ(slicer::plan_layers(cube, p).heights, (std::vector<double>{3.5}));
  // No plane in the range: an error naming the layer height, never an empty slice (issue 19).
  p.z_max = 3.4;
  try {
    slicer::plan_layers(cube, p);
    ADD_FAILURE() << "a plan without a layer";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::NothingToMake);
    EXPECT_EQ(e.field(), "layer_height");
    EXPECT_NE(std::string(e.what()).find("the z range is 1.4 mm tall"), std::string::npos)
        << e.what();
  }
  // Explicit heights come out sorted; planes outside the part give empty layers.
  const auto layers = slice_all(cube, at({20.0, 5.0, -1.0}));
  ASSERT_EQ(layers.size(), 3u);
  EXPECT_EQ(layers[0].z, -1.0);
  EXPECT_EQ(layers[1].z, 5.0);
  EXPECT_EQ(layers[2].z, 20.0);
  EXPECT_TRUE(layers[0].loops.empty());
  EXPECT_EQ(layers[1].loops.size(), 1u);
  EXPECT_TRUE(layers[2].loops.empty());
}

TEST(Slice, NestedBoxesGiveOuterAndClockwiseHoleWithParent) {
  // A 10 mm box with a 4 mm cavity (an inverted inner shell).
  const Mesh mesh =
      to_mesh(merged(cube_soup(10.0), translated(inverted(cube_soup(4.0)), {3, 3, 3})));
  for (const Layer& l : slice_all(mesh, uniform(0.5))) {
    const bool through_cavity = l.z > 3 && l.z < 7;
    ASSERT_EQ(l.loops.size(), through_cavity ? 2u : 1u) << "z = " << l.z;
    EXPECT_EQ(l.loops[0].kind, LoopKind::Outer);
    EXPECT_NEAR(l.loops[0].area, 100.0, 1e-12);
    EXPECT_EQ(l.reversed_loops, 0u);
    if (!through_cavity) continue;
    const auto& hole = l.loops[1];
    EXPECT_EQ(hole.kind, LoopKind::Hole);
    EXPECT_EQ(hole.parent, 0);
    EXPECT_EQ(hole.depth, 1);
    EXPECT_NEAR(hole.area, -16.0, 1e-12);  // < 0: clockwise
    EXPECT_NEAR(l.area, 84.0, 1e-12);
  }
}

TEST(Slice, IslandInsideAHoleIsOuterAgain) {
  const Mesh mesh =
      to_mesh(merged(merged(cube_soup(10.0), translated(inverted(cube_soup(6.0)), {2, 2, 2})),
                     translated(cube_soup(2.0), {4, 4, 4})));
  const auto layers = slice_all(mesh, at({5.0}));
  ASSERT_EQ(layers[0].loops.size(), 3u);
  const auto& loops = layers[0].loops;
  EXPECT_EQ(loops[0].kind, LoopKind::Outer);
  EXPECT_EQ(loops[1].kind, LoopKind::Hole);
  EXPECT_EQ(loops[1].parent, 0);
  EXPECT_EQ(loops[2].kind, LoopKind::Outer);
  EXPECT_EQ(loops[2].parent, 1);
  EXPECT_EQ(loops[2].depth, 2);
  EXPECT_NEAR(loops[2].area, 4.0, 1e-12);
  EXPECT_NEAR(layers[0].area, 100.0 - 36.0 + 4.0, 1e-12);
}

TEST(Slice, InsideOutShellIsReorientedByNesting) {
  // Nesting, not the mesh's winding, decides: an inverted cube still gives a ccw outer loop,
  // and the reversal is reported.
  const Mesh mesh = to_mesh(inverted(cube_soup(10.0)));
  const auto layers = slice_all(mesh, at({5.0}));
  ASSERT_EQ(layers[0].loops.size(), 1u);
  EXPECT_EQ(layers[0].loops[0].kind, LoopKind::Outer);
  EXPECT_NEAR(layers[0].loops[0].area, 100.0, 1e-12);
  EXPECT_EQ(layers[0].reversed_loops, 1u);
}

TEST(Slice, BoxWithThroughHoleFromExamples) {
  const TriangleSoup soup = read_stl_file(STLREFINE_SOURCE_DIR "/examples/box_with_hole.stl");
  const Mesh mesh = build_mesh(weld(soup)).mesh;
  for (const Layer& l : slice_all(mesh, uniform(1.0))) {
    ASSERT_EQ(l.loops.size(), 2u) << "z = " << l.z;
    EXPECT_EQ(l.loops[0].kind, LoopKind::Outer);
    EXPECT_EQ(l.loops[1].kind, LoopKind::Hole);
    EXPECT_EQ(l.loops[1].parent, 0);
    EXPECT_NEAR(l.loops[0].area, 600.0, 1e-3);
    // A 32-gon inscribed in r = 5: (32/2) r^2 sin(2 pi/32).
    EXPECT_NEAR(l.loops[1].area, -16 * 25 * std::sin(2 * kPi / 32), 1e-3);
    // 32 wall quads, each split by a diagonal: a (collinear) point on every edge crossed.
    EXPECT_EQ(l.loops[1].points.size(), 64u);
  }
}

TEST(Slice, TorusThroughItsMiddleGivesOuterAndHole) {
  const double R = 15, r = 5;
  const Mesh torus = to_mesh(torus_soup(48, 24, R, r));
  // z = 0 passes (up to rounding) through the vertices of the torus' equator rings.
  for (double z : {0.0, 1e-9, 0.3, -2.0}) {
    const auto layers = slice_all(torus, at({z}));
    const auto& loops = layers[0].loops;
    ASSERT_EQ(loops.size(), 2u) << "z = " << z;
    EXPECT_EQ(loops[0].kind, LoopKind::Outer);
    EXPECT_EQ(loops[1].kind, LoopKind::Hole);
    EXPECT_EQ(loops[1].parent, 0);
    const double half_width = std::sqrt(r * r - z * z);
    // Inscribed 48-gons: between cos(pi/48)^2 and 1 times the circles' areas.
    const double shrink = std::pow(std::cos(kPi / 48), 2) * 0.99;
    EXPECT_LT(loops[0].area, kPi * std::pow(R + half_width, 2));
    EXPECT_GT(loops[0].area, shrink * kPi * std::pow(R + half_width, 2));
    EXPECT_GT(-loops[1].area, shrink * kPi * std::pow(R - half_width, 2));
    EXPECT_LT(-loops[1].area, kPi * std::pow(R - half_width, 2) / shrink);
    EXPECT_TRUE(layers[0].open.empty());
  }
}

// ------------------------------------------------------------------ degenerate planes

TEST(Slice, PlanesThroughCubeFacesUseTheAboveRule) {
  // A vertex on the plane counts as above it: the bottom face is not cut, the top face is
  // cut just below (its full square, with exactly its four corners).
  const Mesh cube = to_mesh(cube_soup(10.0));
  const auto layers = slice_all(cube, at({0.0, 10.0}));
  EXPECT_TRUE(layers[0].loops.empty());
  EXPECT_EQ(layers[0].degenerate_loops, 0u);
  ASSERT_EQ(layers[1].loops.size(), 1u);
  EXPECT_EQ(layers[1].loops[0].points.size(), 4u);
  EXPECT_NEAR(layers[1].loops[0].area, 100.0, 0);
  EXPECT_TRUE(no_zero_length_edges(layers[1].loops[0]));
}

TEST(Slice, PlaneThroughVerticesGivesOnePointPerVertex) {
  // Octahedron: z = 0 runs through the four equator vertices (the square of area 2);
  // z = 1 only touches the top apex (a degenerate loop, reported, not output).
  const Mesh octa = to_mesh(octahedron_soup());
  const auto layers = slice_all(octa, at({-1.0, 0.0, 1.0}));
  EXPECT_TRUE(layers[0].loops.empty());
  ASSERT_EQ(layers[1].loops.size(), 1u);
  EXPECT_EQ(layers[1].loops[0].points.size(), 4u);
  EXPECT_DOUBLE_EQ(layers[1].loops[0].area, 2.0);
  EXPECT_TRUE(no_zero_length_edges(layers[1].loops[0]));
  EXPECT_TRUE(layers[2].loops.empty());
  EXPECT_EQ(layers[2].degenerate_loops, 1u);
  EXPECT_EQ(layers[0].degenerate_loops, 0u);
}

TEST(Slice, PlaneThroughHorizontalEdges) {
  // Diamond prism: z = 0 holds its two side edges (the loop is exactly their four ends),
  // z = 1 only touches its top ridge (degenerate), z = 0.5 is a generic rectangle.
  const Mesh prism = to_mesh(diamond_prism_soup(4.0));
  const auto layers = slice_all(prism, at({0.0, 0.5, 1.0}));
  ASSERT_EQ(layers[0].loops.size(), 1u);
  EXPECT_EQ(layers[0].loops[0].points.size(), 4u);
  EXPECT_DOUBLE_EQ(layers[0].loops[0].area, 8.0);
  ASSERT_EQ(layers[1].loops.size(), 1u);
  EXPECT_NEAR(layers[1].loops[0].area, 4.0, 1e-12);
  EXPECT_TRUE(layers[2].loops.empty());
  EXPECT_EQ(layers[2].degenerate_loops, 1u);
}

TEST(Slice, CoplanarFacesOfTwoStackedBoxes) {
  // A 5 mm box standing on a 10 mm box: at z = 5 the lower box's top and the upper box's
  // bottom are both in the plane. The rule counts both as above: the lower box is cut
  // (100), the upper is not; just above, only the upper (25).
  const Mesh mesh = to_mesh(merged(cube_soup(10.0), translated(cube_soup(5.0), {2, 2, 10})));
  const auto layers = slice_all(mesh, at({10.0, std::nextafter(10.0, 11.0)}));
  ASSERT_EQ(layers[0].loops.size(), 1u);
  EXPECT_DOUBLE_EQ(layers[0].loops[0].area, 100.0);
  ASSERT_EQ(layers[1].loops.size(), 1u);
  EXPECT_DOUBLE_EQ(layers[1].loops[0].area, 25.0);
}

// ------------------------------------------------------------------ open meshes

TEST(Slice, OpenMeshGivesOpenPolylinesNeverClosedOrDropped) {
  const Mesh box = to_mesh(open_box_soup(10.0));
  slicer::SliceStats stats;
  const auto layers = slice_all(box, uniform(2.5), &stats);
  ASSERT_EQ(layers.size(), 4u);
  EXPECT_EQ(stats.open_polylines, 4u);
  for (const Layer& l : layers) {
    EXPECT_TRUE(l.loops.empty());
    ASSERT_EQ(l.open.size(), 1u);
    const auto& pts = l.open[0].points;
    ASSERT_GE(pts.size(), 4u);  // around three sides, from one cut edge to the other
    EXPECT_EQ(pts.front().x, 0.0);
    EXPECT_EQ(pts.back().x, 0.0);
    EXPECT_NE(pts.front().y, pts.back().y);
  }
}

// ------------------------------------------------------------------ refined and curved

TEST(Slice, EveryLayerOfARefinedCylinderIsOneClosedLoop) {
  RefineParams rp;
  rp.levels = 2;
  const Mesh mesh = refine(to_mesh(cylinder_soup(24, 10.0, 20.0)), rp).mesh;
  slicer::SliceStats stats;
  const auto layers = slice_all(mesh, uniform(0.25), &stats);
  ASSERT_EQ(layers.size(), 80u);
  EXPECT_EQ(stats.open_polylines, 0u);
  EXPECT_EQ(stats.degenerate_loops, 0u);
  for (const Layer& l : layers) {
    ASSERT_EQ(l.loops.size(), 1u) << "z = " << l.z;
    EXPECT_TRUE(l.open.empty());
    EXPECT_TRUE(no_zero_length_edges(l.loops[0]));
    EXPECT_NEAR(l.area, kPi * 100.0, 0.02 * kPi * 100.0) << "z = " << l.z;
  }
}

TEST(Slice, SphereAreasMatchTheCircleWithinTheTessellation) {
  const double r = 10;
  const Mesh sphere = to_mesh(icosphere_soup(4, r));
  // The mesh lies between the sphere and the sphere of radius r_in (its closest face
  // plane), so each section lies between the two circles.
  double r_in = r;
  for (std::size_t f = 0; f < sphere.num_faces(); ++f) {
    const auto v = sphere.face_vertices(FaceId(std::uint32_t(f)));
    const Vec3 n = normalized(sphere.face_normal(FaceId(std::uint32_t(f))));
    r_in = std::min(r_in, std::fabs(dot(n, sphere.position(v[0]))));
  }
  ASSERT_GT(r_in, 0.99 * r);
  const auto layers = slice_all(sphere, uniform(0.5));
  ASSERT_EQ(layers.size(), 40u);
  for (const Layer& l : layers) {
    ASSERT_EQ(l.loops.size(), 1u) << "z = " << l.z;
    EXPECT_LE(l.area, kPi * (r * r - l.z * l.z)) << "z = " << l.z;
    if (std::fabs(l.z) < r_in) {
      EXPECT_GE(l.area, kPi * (r_in * r_in - l.z * l.z)) << "z = " << l.z;
    }
  }
}

// ------------------------------------------------------------------ threads and streaming

TEST(Slice, ParallelAndSingleThreadedLayersAreIdentical) {
  RefineParams rp;
  rp.levels = 3;
  const Mesh mesh = refine(to_mesh(torus_soup(24, 12, 15, 5)), rp).mesh;
  slicer::SliceParams p = uniform(0.05);
  p.threads = 1;
  const auto one = slice_all(mesh, p);
  p.threads = 2;
  const auto two = slice_all(mesh, p);
  ASSERT_EQ(one.size(), two.size());
  ASSERT_EQ(one.size(), 200u);
  for (std::size_t k = 0; k < one.size(); ++k) {
    ASSERT_EQ(one[k].loops.size(), two[k].loops.size());
    for (std::size_t i = 0; i < one[k].loops.size(); ++i) {
      EXPECT_EQ(one[k].loops[i].points, two[k].loops[i].points);
      EXPECT_EQ(one[k].loops[i].area, two[k].loops[i].area);
      EXPECT_EQ(one[k].loops[i].parent, two[k].loops[i].parent);
    }
  }
}

TEST(Slice, LayersArriveInOrderOneAtATimeWhileLaterOnesAreNotYetBuilt) {
  const Mesh mesh = to_mesh(icosphere_soup(3, 10.0));
  std::atomic<bool> cancel{false};
  std::atomic<int> inside{0};
  std::size_t expected = 0;
  slicer::SliceParams p = uniform(0.01);  // 2000 layers
  p.threads = 2;
  const auto run = [&] {
    slicer::slice(
        mesh, p,
        [&](Layer&& l) {
          EXPECT_EQ(inside.fetch_add(1), 0) << "called concurrently";
          EXPECT_EQ(l.index, expected++);
          if (l.index == 10) cancel = true;  // stop early: the rest must never be built
          inside.fetch_sub(1);
        },
        {}, &cancel);
  };
  EXPECT_EQ(error_of(run), "cancelled:");
  EXPECT_GE(expected, 11u);
  // Only the layers already in flight (a few per thread) may still arrive.
  EXPECT_LT(expected, 11u + 64u);
}

// ------------------------------------------------------------------ parameters

TEST(SliceParams, BadValuesNameTheField) {
  const Mesh cube = to_mesh(cube_soup(10.0));
  const auto plan = [&](slicer::SliceParams p) {
    return [&cube, p] { slicer::plan_layers(cube, p); };
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double h : {0.0, -0.1, nan, inf, 1e-9, 1e5})
    EXPECT_EQ(error_of(plan(uniform(h))), "invalid_parameter:layer_height") << h;
  slicer::SliceParams p = uniform(0.1);
  p.z_min = 5;
  p.z_max = 4;
  EXPECT_EQ(error_of(plan(p)), "invalid_parameter:z_min");
  p = uniform(0.1);
  p.z_max = nan;
  EXPECT_EQ(error_of(plan(p)), "invalid_parameter:z_max");
  p = uniform(0.1);
  p.z_min = 50;  // above the part's top
  EXPECT_EQ(error_of(plan(p)), "invalid_parameter:z_min");
  EXPECT_EQ(error_of(plan(at({1.0, nan}))), "invalid_parameter:heights");
  EXPECT_EQ(error_of(plan(at({1.0, 2.0, 1.0}))), "invalid_parameter:heights");
  p = at({1.0});
  p.z_min = 0;
  EXPECT_EQ(error_of(plan(p)), "invalid_parameter:heights");
  p = uniform(0.1);
  p.threads = 300;
  EXPECT_EQ(error_of(plan(p)), "invalid_parameter:threads");
  p = uniform(0.1);
  p.max_layers = 0;
  EXPECT_EQ(error_of(plan(p)), "invalid_parameter:max_layers");
}

TEST(SliceParams, AbsurdLayerCountsAndOutputsAreRefusedBeforeWork) {
  const Mesh cube = to_mesh(cube_soup(10.0));
  slicer::SliceParams p = uniform(1e-4);
  p.z_max = 1e6;  // ten billion layers: refused from the arithmetic, nothing allocated
  EXPECT_EQ(error_of([&] { slicer::slice_all(cube, p); }), "budget_exceeded:max_layers");
  p = uniform(1.0);
  p.max_layers = 9;
  EXPECT_EQ(error_of([&] { slicer::slice_all(cube, p); }), "budget_exceeded:max_layers");
  p.max_layers = 10;
  EXPECT_EQ(slicer::slice_all(cube, p).size(), 10u);
  p.max_points = 20;  // each of the 10 layers crosses 8 triangles
  bool called = false;
  EXPECT_EQ(error_of([&] { slicer::slice(cube, p, [&](Layer&&) { called = true; }); }),
            "budget_exceeded:max_points");
  EXPECT_FALSE(called);
}

}  // namespace
}  // namespace stlrefine::test
