// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

#include "api/params.h"
#include "api/pipeline.h"
#include "api/problem.h"
#include "core/error.h"
#include "slicer/writers.h"
#include "test_stl.h"

namespace stlrefine::api {
namespace {

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

RefineRequest butterfly(int levels) {
  RefineRequest r;
  r.refine.scheme = "butterfly";
  r.refine.levels = levels;
  return r;
}

TEST(ApiPipeline, RefineQuadruplesFacesAndKeepsInputVertices) {
  const auto input = test::octahedron_triangles();
  for (int levels : {0, 1, 2}) {
    const RefineOutcome out = run_refine(bytes_of(test::binary_stl(input)), butterfly(levels));
    const auto output = test::read_binary_stl(out.stl);
    EXPECT_EQ(output.size(), input.size() << (2 * levels));
    EXPECT_TRUE(test::corners_preserved(input, output));
    EXPECT_EQ(out.report.at("input").at("faces"), input.size());
    EXPECT_EQ(out.report.at("output").at("faces"), output.size());
    EXPECT_EQ(out.report.at("output").at("bytes"), out.stl.size());
    EXPECT_EQ(out.report.at("max_input_displacement"), 0.0);
    EXPECT_EQ(out.report.at("scheme"), "butterfly");
  }
}

// The report says why an adaptive refinement stopped: at its tolerance, or at max_level with
// how far off (mm) and where the worst remaining edge is.
TEST(ApiPipeline, AdaptiveReportSaysWhyItStopped) {
  const std::string in = test::binary_stl(test::octahedron_triangles());
  // Creases off: the octahedron is a coarse smooth surface, so butterfly bends every edge.
  const auto adaptive = [](const std::string& tol, const std::string& max_level) {
    return parse_refine_params({{"scheme", "butterfly"},
                                {"crease_angle", "180"},
                                {"adaptive_tol", tol},
                                {"max_level", max_level}},
                               RequestLimits{});
  };
  const RefineOutcome reached = run_refine(bytes_of(in), adaptive("1000", "4"));
  EXPECT_EQ(reached.report.at("adaptive_stop").at("reason"), "tolerance");
  EXPECT_FALSE(reached.report.at("adaptive_stop").contains("max_over_tolerance_mm"));

  const RefineOutcome capped = run_refine(bytes_of(in), adaptive("0.000001", "1"));
  const auto& stop = capped.report.at("adaptive_stop");
  EXPECT_EQ(stop.at("reason"), "max_level");
  EXPECT_GT(capped.report.at("edges_over_tolerance").get<double>(), 0);
  EXPECT_GT(stop.value("max_over_tolerance_mm", 0.0), 1e-6);
  EXPECT_EQ(stop.value("worst_at", nlohmann::ordered_json::array()).size(), 3u);

  EXPECT_FALSE(run_refine(bytes_of(in), butterfly(1)).report.contains("adaptive_stop"));
}

TEST(ApiPipeline, RefineIsDeterministic) {
  const std::string in = test::binary_stl(test::octahedron_triangles());
  EXPECT_EQ(run_refine(bytes_of(in), butterfly(2)).stl, run_refine(bytes_of(in), butterfly(2)).stl);
}

TEST(ApiPipeline, AsciiInAsciiOut) {
  RefineRequest r = butterfly(1);
  r.output_format = StlFormat::Ascii;
  const RefineOutcome out = run_refine(bytes_of(test::ascii_stl(test::octahedron_triangles())), r);
  EXPECT_EQ(out.report.at("input").at("format"), "ascii");
  EXPECT_EQ(out.report.at("output").at("format"), "ascii");
  EXPECT_EQ(out.stl.rfind("solid", 0), 0u);
}

TEST(ApiPipeline, BudgetIsCheckedWithThePrediction) {
  RefineRequest r = butterfly(3);
  r.refine.max_faces = 100;  // 8 * 4^3 = 512
  try {
    run_refine(bytes_of(test::binary_stl(test::octahedron_triangles())), r);
    FAIL() << "no budget error";
  } catch (const FaceBudgetError& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded);
    EXPECT_EQ(e.predicted_faces(), 512u);
    EXPECT_EQ(e.max_faces(), 100u);
  }
}

TEST(ApiPipeline, BadParametersBeforeTheFile) {
  RefineRequest r = butterfly(1);
  r.refine.scheme = "nope";
  try {
    run_refine(bytes_of(std::string("not an stl")), r);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    EXPECT_EQ(e.field(), "scheme");
  }
}

TEST(ApiPipeline, MalformedStlHasAByteOffset) {
  auto tris = test::octahedron_triangles();
  tris[1][0][1] = std::numeric_limits<float>::quiet_NaN();
  try {
    run_refine(bytes_of(test::binary_stl(tris)), butterfly(1));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::MalformedStl);
    ASSERT_TRUE(e.byte_offset().has_value());
    EXPECT_EQ(*e.byte_offset(), 84u + 50u + 12u + 4u);  // facet 1, corner 0, y
  }
}

TEST(ApiPipeline, InfoReport) {
  const auto j = run_info(bytes_of(test::binary_stl(test::octahedron_triangles())), {});
  EXPECT_EQ(j.at("input").at("format"), "binary");
  EXPECT_EQ(j.at("input").at("triangles"), 8);
  EXPECT_EQ(j.at("input").at("vertices_before_weld"), 24);
  EXPECT_EQ(j.at("input").at("vertices_after_weld"), 6);
  EXPECT_EQ(j.at("mesh").at("faces"), 8);
  EXPECT_EQ(j.at("mesh").at("edges"), 12);
  EXPECT_EQ(j.at("mesh").at("watertight"), true);
  EXPECT_EQ(j.at("mesh").at("genus"), 0);
  EXPECT_EQ(j.at("mesh").at("boundary_edges"), 0);
  EXPECT_NEAR(j.at("mesh").at("volume").get<double>(), 4.0 / 3.0, 1e-6);
  EXPECT_EQ(j.at("mesh").at("bbox").at("min"), nlohmann::ordered_json::array({-1.0, -1.0, -1.0}));
  EXPECT_EQ(j.at("ingest").at("faces_reoriented"), 0);
  // The octahedron's dihedral angle is 109.47 deg, so every edge turns 70.5 deg: all sharp
  // at 35, none at 80.
  EXPECT_EQ(j.at("features").at("sharp_edges"), 12);
  EXPECT_EQ(j.at("features").at("corners"), 6);
  InfoRequest flat;
  flat.features.crease_angle_deg = 80;
  flat.features.crease_mode = CreaseMode::Angle;  // what the parser makes of crease_angle=80
  const auto k = run_info(bytes_of(test::binary_stl(test::octahedron_triangles())), flat);
  EXPECT_EQ(k.at("features").at("sharp_edges"), 0);
  EXPECT_EQ(k.at("features").at("crease_angle_deg"), 80.0);
}

TEST(ApiPipeline, InfoCountsFlippedFacets) {
  auto tris = test::octahedron_triangles();
  std::swap(tris[3][1], tris[3][2]);
  const auto j = run_info(bytes_of(test::binary_stl(tris)), {});
  EXPECT_EQ(j.at("ingest").at("faces_reoriented"), 1);
  EXPECT_EQ(j.at("mesh").at("watertight"), true);
}

TEST(ApiPipeline, InfoOfAnOpenMesh) {
  auto tris = test::octahedron_triangles();
  tris.pop_back();
  const auto j = run_info(bytes_of(test::binary_stl(tris)), {});
  EXPECT_EQ(j.at("mesh").at("watertight"), false);
  EXPECT_TRUE(j.at("mesh").at("genus").is_null());
  EXPECT_EQ(j.at("mesh").at("boundary_edges"), 3);
  EXPECT_EQ(j.at("mesh").at("boundary_loops"), 1);
}

// --- issue 16, item 8

// A refinement or a slice must not start: progress is the first sign of work.
const ProgressFn kNoWork = [](double, std::string_view stage) {
  throw std::runtime_error("work started (" + std::string(stage) + ")");
};

RequestLimits daemon_limits() {
  RequestLimits l;
  l.max_slice_points = 20'000'000;  // stlrefined's --max-slice-points default
  return l;
}

TEST(ApiPipeline, WeldToleranceThatMergesEveryTriangleIs422NamingIt) {
  const std::string octahedron = test::binary_stl(test::octahedron_triangles());
  InfoRequest info;
  info.weld_tolerance = 1e308;  // every corner welds into the first
  try {
    run_info(bytes_of(octahedron), info);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::NotTriangleMesh);
    EXPECT_EQ(e.reason(), "weld_collapsed");
    EXPECT_EQ(problem_from_error(e).field, "weld_tolerance");
    EXPECT_NE(std::string(e.what()).find("every one of the 8 triangles (the part is 2 across)"),
              std::string::npos)
        << e.what();
  }
  // A file whose facets are all degenerate as stored is the file's fault, not the
  // tolerance's: build_mesh's no_faces, as without a tolerance.
  auto flat = test::octahedron_triangles();
  for (auto& t : flat) t[1] = t[0];
  info.weld_tolerance = 0.5;
  try {
    run_info(bytes_of(test::binary_stl(flat)), info);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.reason(), "no_faces") << e.what();
    EXPECT_EQ(e.field(), "");
  }
}

TEST(ApiPipeline, EmptyLayersOfA134ByteTriangleAreRefusedBeforeAnyLayer) {
  // A flat triangle, 134 bytes as a binary STL; a million planes between 0 and 100 mm: 140
  // MB of empty SVG groups until empty layers counted against the point cap.
  const test::Triangle flat = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  const std::string triangle = test::binary_stl({flat});
  ASSERT_EQ(triangle.size(), 134u);
  const SliceRequest r = parse_slice_params(
      {{"layer_height", "0.0001"}, {"z_min", "0"}, {"z_max", "100"}, {"format", "svg"}},
      daemon_limits());
  try {
    run_slice(bytes_of(triangle), r, kNoWork);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded) << e.what();
    const Problem p = problem_from_error(e);
    EXPECT_EQ(p.status, 422);
    EXPECT_EQ(p.field, "max_points");
    EXPECT_EQ(p.title, "Point budget exceeded");
  }
  // Binary CLI layers are 6 bytes each: the same million fits the cap.
  const SliceRequest cli = parse_slice_params(
      {{"layer_height", "0.0001"}, {"z_min", "0"}, {"z_max", "100"}, {"format", "cli-binary"}},
      daemon_limits());
  EXPECT_EQ(cli.slice.params.points_per_layer, 1u);
  EXPECT_EQ(r.slice.params.points_per_layer, slicer::empty_layer_points(slicer::SliceFormat::Svg));
}

TEST(ApiPipeline, RefineAndSliceRefusesEmptyLayerCostBeforeRefining) {
  // A 100 mm tall triangle sliced at 0.1 um after a refinement: refused on the input's
  // bounds, before any refinement work.
  const test::Triangle facet = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 100}}};
  const std::string tall = test::binary_stl({facet});
  const RefineRequest r = parse_refine_params(
      {{"scheme", "loop"}, {"levels", "1"}, {"slice", "0.0001"}, {"slice_format", "svg"}},
      daemon_limits());
  try {
    run_refine(bytes_of(tall), r, kNoWork);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded) << e.what();
    EXPECT_EQ(e.field(), "max_points");
  }
}

}  // namespace
}  // namespace stlrefine::api
