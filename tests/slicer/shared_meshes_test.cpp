// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Every mesh of ../shared/meshes that is closed after ingest (no boundary half-edge), sliced
// at 0.1 mm in millimetres (finer for small parts: 300+ layers each), gives closed contours, outer
// counter-clockwise and holes clockwise, nested as a containment count says, never crossing, every
// edge a face's own segment in the face's direction (tests/slicer/contour_check.h). Where the
// surface passes through itself (the cow) loops may cross or run against their faces, but only
// there. The large dragon is checked by bench/slicer's stlrefine_contour_check (too slow for
// ctest).

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "slicer/slice.h"
#include "tests/slicer/contour_check.h"
#include "tests/slicer/slicer_test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

namespace fs = std::filesystem;

//! How far (mm) from a self-intersecting face pair a finding may lie: none so far.
constexpr double kFoldMargin = 0.0;

// The checker itself: it passes a clean part and catches what it is meant to catch.

TEST(ContourCheck, PassesACleanBoxWithAHole) {
  const Mesh mesh =
      to_mesh(merged(cube_soup(10.0), translated(inverted(cube_soup(4.0)), {3, 3, 3})));
  const ContourCheck c = check_contours(mesh, uniform(0.5));
  EXPECT_TRUE(c.ok()) << c.first_problem;
  EXPECT_EQ(c.layers, 20u);
  EXPECT_EQ(c.holes, 8u);
}

TEST(ContourCheck, FlagsALoopTurnedAgainstItsFaces) {
  // An inside-out cube: the slicer makes its loops ccw outers by nesting, against the faces.
  const Mesh mesh = to_mesh(inverted(cube_soup(10.0)));
  const ContourCheck c = check_contours(mesh, uniform(1.0));
  EXPECT_EQ(c.against_mesh, 10u);
  EXPECT_EQ(c.reversed, 10u);
  EXPECT_EQ(c.area_mismatch_layers, 10u);
  EXPECT_EQ(c.wrong_sign + c.wrong_nesting + c.unmatched + c.crossing_layers, 0u);
  ASSERT_FALSE(c.findings.empty());
  EXPECT_EQ(c.findings[0].kind, Finding::AgainstMesh);
  EXPECT_TRUE(self_intersection_boxes(mesh).empty());  // so nothing explains it
}

TEST(ContourCheck, FlagsCrossingLoopsAndLocatesThemAtTheSelfIntersection) {
  // Two overlapping cubes in one mesh: their sections cross, where their faces intersect.
  const Mesh mesh = to_mesh(merged(cube_soup(10.0), translated(cube_soup(10.0), {5, 5, 0.5})));
  const ContourCheck c = check_contours(mesh, uniform(1.0));
  EXPECT_GT(c.crossing_layers, 0u);
  EXPECT_EQ(c.open + c.short_loops + c.unmatched, 0u);
  // Whether a corner of one square lies inside the other has no single answer once they
  // cross: such disagreements are crossing findings, never nesting faults.
  EXPECT_EQ(c.wrong_nesting, 0u);
  EXPECT_TRUE(c.only_crossings_and_against_mesh()) << c.first_problem;
  const std::vector<Box3> boxes = self_intersection_boxes(mesh);
  ASSERT_FALSE(boxes.empty());
  for (const Finding& f : c.findings)
    if (f.kind == Finding::Crossing) {
      EXPECT_TRUE(explained_by(f, boxes, 0.0)) << f.what;
    }
  // A crossing placed away from the intersections is not explained.
  Finding far{Finding::Crossing, 5.0, 100, 100, 101, 101, "far away"};
  EXPECT_FALSE(explained_by(far, boxes, 0.0));
}

TEST(ContourCheck, FlagsTamperedNestingOrientationAndChaining) {
  const Mesh mesh =
      to_mesh(merged(cube_soup(10.0), translated(inverted(cube_soup(4.0)), {3, 3, 3})));
  const slicer::SliceParams params = at({5.0});
  const std::vector<double> heights = slicer::plan_layers(mesh, params).heights;
  const std::vector<slicer::Layer> layers = slice_all(mesh, params);
  ASSERT_EQ(layers.size(), 1u);
  ASSERT_EQ(layers[0].loops.size(), 2u);
  const auto check = [&](const slicer::Layer& layer) {
    ContourChecker checker(mesh, heights);
    checker.add(layer);
    return checker.result();
  };
  EXPECT_TRUE(check(layers[0]).ok());

  slicer::Layer orphan = layers[0];  // the hole claimed as a second outer, turned ccw
  slicer::Loop& hole = orphan.loops[1];
  hole.parent = -1, hole.depth = 0, hole.kind = slicer::LoopKind::Outer, hole.area = -hole.area;
  std::reverse(hole.points.begin(), hole.points.end());
  const ContourCheck o = check(orphan);
  EXPECT_EQ(o.wrong_nesting, 1u);
  EXPECT_EQ(o.against_mesh, 1u);
  EXPECT_FALSE(o.only_crossings_and_against_mesh());

  slicer::Layer cw = layers[0];  // the outer left clockwise
  std::reverse(cw.loops[0].points.begin(), cw.loops[0].points.end());
  EXPECT_EQ(check(cw).wrong_sign, 1u);

  slicer::Layer shortcut = layers[0];  // a corner cut off: an edge no face gives
  shortcut.loops[0].points.erase(shortcut.loops[0].points.begin() + 1);
  EXPECT_EQ(check(shortcut).unmatched, 1u);
}

TEST(SharedMeshes, EveryClosedMeshGivesClosedCorrectlyOrientedNestedContours) {
  const fs::path dir = STLREFINE_SHARED_MESHES_DIR;
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " is absent";
  std::set<std::string> checked;
  std::string flagged;
  for (const char* folder : {"cad", "generated", "organic", "malformed"}) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(dir / folder))
      if (entry.path().extension() == ".stl") files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    for (const fs::path& path : files) {
      const std::string name = std::string(folder) + "/" + path.filename().string();
      Mesh mesh;
      try {
        mesh = build_mesh(weld(read_stl_file(path))).mesh;
      } catch (const Error&) {
        continue;  // unreadable on purpose (malformed/): nothing to slice
      }
      if (std::any_of(mesh.twins().begin(), mesh.twins().end(),
                      [](HalfedgeId t) { return !t.valid(); }))
        continue;  // open after ingest: open polylines are expected there
      const double scale = shared_mesh_scale(name);
      for (Vec3& p : mesh.mutable_positions()) p *= scale;
      // 0.1 mm, or finer for the parts under 30 mm tall, so each gets 300+ layers.
      const slicer::Bounds b = slicer::mesh_bounds(mesh);
      const double h = std::min(0.1, (b.max.z - b.min.z) / 300);
      const ContourCheck c = check_contours(mesh, uniform(h));
      EXPECT_GE(c.layers, 300u) << name;
      EXPECT_EQ(c.empty_layers, 0u) << name;  // every plane inside a closed part cuts it
      EXPECT_GE(c.outer, c.layers) << name;
      if (!c.ok()) {
        // Only where the surface passes through itself (the cow: 101 intersecting face
        // pairs around its neck): loops cross there, or run against their faces.
        EXPECT_TRUE(c.only_crossings_and_against_mesh()) << name << ": " << c.first_problem;
        const std::vector<Box3> boxes = self_intersection_boxes(mesh);
        for (const Finding& f : c.findings)
          EXPECT_TRUE(explained_by(f, boxes, kFoldMargin)) << name << ": " << f.what;
        EXPECT_FALSE(boxes.empty()) << name << ": " << c.first_problem;
      }
      flagged += c.ok() ? "" : name + " ";
      checked.insert(name);
    }
  }
  // Every mesh the shared README calls watertight (and the repaired malformed ones) was
  // checked, none skipped silently.
  for (const char* name : {"cad/fandisk.stl",
                           "cad/gearwheel.stl",
                           "cad/round.stl",
                           "cad/tray_bottom.stl",
                           "cad/xyz_cube_20mm.stl",
                           "generated/box_with_hole.stl",
                           "generated/bracket.stl",
                           "generated/cylinder_fn24.stl",
                           "generated/sphere_fn16.stl",
                           "generated/torus.stl",
                           "organic/armadillo.stl",
                           "organic/bunny_low.stl",
                           "organic/cow.stl",
                           "organic/spot.stl",
                           "malformed/degenerate_tjunction.stl",
                           "malformed/flipped_facets.stl",
                           "malformed/gearwheel_ascii.stl",
                           "malformed/issue945e_zero_area.stl",
                           "malformed/solid_header_binary.stl",
                           "malformed/two_cubes_shared_edge.stl"})
    EXPECT_TRUE(checked.count(name)) << name << " was not checked";
  // The one shared mesh that passes through itself; everything else is clean.
  EXPECT_EQ(flagged, "organic/cow.stl ");
}

}  // namespace
}  // namespace stlrefine::test
