// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// api/memory_model (what it reads from STL bytes, how its prediction moves with the
// parameters) and server/memory_budget (sizes, reservations).

#include "api/memory_model.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "api/ingest.h"
#include "api/params.h"
#include "api/pipeline.h"
#include "core/error.h"
#include "core/refine.h"
#include "server/memory_budget.h"
#include "slicer/slice.h"
#include "test_stl.h"

namespace stlrefine {
namespace {

namespace fs = std::filesystem;

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

using test::read_file;

const std::string& fandisk() {
  static const std::string bytes = read_file(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl");
  return bytes;
}

api::RefineRequest refine(const std::string& query) {
  return api::parse_refine_params(api::parse_query(query), api::RequestLimits{});
}

TEST(StlShape, BinaryCountsFacetsAndZRange) {
  const std::string stl = test::binary_stl(test::octahedron_triangles());
  const api::StlShape s = api::stl_shape(bytes_of(stl));
  EXPECT_TRUE(s.binary);
  EXPECT_EQ(s.faces, 8u);
  EXPECT_EQ(s.bytes, stl.size());
  ASSERT_TRUE(s.has_z);
  EXPECT_EQ(s.z_min, -1.0);
  EXPECT_EQ(s.z_max, 1.0);
}

TEST(StlShape, AsciiCountsEndfacetsAndReadsVertices) {
  const std::string stl = test::ascii_stl(test::octahedron_triangles());
  const api::StlShape s = api::stl_shape(bytes_of(stl));
  EXPECT_FALSE(s.binary);
  EXPECT_EQ(s.faces, 8u);
  ASSERT_TRUE(s.has_z);
  EXPECT_EQ(s.z_min, -1.0);
  EXPECT_EQ(s.z_max, 1.0);
}

TEST(StlShape, LyingCountsAndForeignBytesGiveNoFaces) {
  // A header that claims 2^32 - 1 facets is no binary file by the size rule: no faces, so no
  // memory is predicted for it (the reader refuses it).
  const std::string lying = test::binary_stl(test::octahedron_triangles(), 0xFFFFFFFFu);
  EXPECT_EQ(api::stl_shape(bytes_of(lying)).faces, 0u);
  EXPECT_EQ(api::stl_shape(bytes_of(std::string("ply\nformat ascii 1.0\n"))).faces, 0u);
  EXPECT_EQ(api::stl_shape(bytes_of(std::string())).faces, 0u);
}

TEST(StlShape, CrossingsAreTheSlicersOnAWatertightPart) {
  // The estimate reads raw corners; the slicer counts on the welded mesh. On a clean part
  // they agree up to planes through vertices.
  const api::StlShape shape = api::stl_shape(bytes_of(fandisk()));
  const api::Ingested in = api::ingest_stl(bytes_of(fandisk()), 0);
  for (const double h : {0.05, 0.013, 0.003}) {
    slicer::SliceParams params;
    params.layer_height = h;
    slicer::SliceStats stats;
    slicer::slice_all(in.result.mesh, params, &stats);
    const std::uint64_t estimate = api::count_crossings(bytes_of(fandisk()), shape, params);
    EXPECT_NEAR(double(estimate), double(stats.crossings), 0.01 * double(stats.crossings))
        << "layer height " << h;
  }
  slicer::SliceParams explicit_planes;
  explicit_planes.heights = {0.1, -0.2, 0.3};
  slicer::SliceStats stats;
  slicer::slice_all(in.result.mesh, explicit_planes, &stats);
  EXPECT_NEAR(double(api::count_crossings(bytes_of(fandisk()), shape, explicit_planes)),
              double(stats.crossings), 0.01 * double(stats.crossings));
}

TEST(MemoryModel, GrowsWithLevelsAndNamesTheField) {
  const api::StlShape shape = api::stl_shape(bytes_of(fandisk()));
  std::uint64_t previous = 0;
  for (int levels = 0; levels <= 4; ++levels) {
    const api::MemoryEstimate e = api::estimate_refine_memory(
        bytes_of(fandisk()), shape, refine("levels=" + std::to_string(levels)));
    EXPECT_GT(e.peak_bytes, previous);
    // At least the body and the output STL, which are held at the same time.
    EXPECT_GT(e.peak_bytes, fandisk().size() + 50 * e.output_faces);
    EXPECT_EQ(e.output_faces, 12946u << (2 * levels));
    EXPECT_EQ(e.field, levels > 0 ? "levels" : "");
    previous = e.peak_bytes;
  }
  const api::MemoryEstimate adaptive = api::estimate_refine_memory(
      bytes_of(fandisk()), shape, refine("adaptive_angle=10&max_level=3"));
  EXPECT_EQ(adaptive.field, "max_level");
  EXPECT_EQ(adaptive.output_faces, 12946u * 64);  // the uniform bound at the level cap
}

TEST(MemoryModel, SlicingAddsItsContoursAndTheZip) {
  const api::StlShape shape = api::stl_shape(bytes_of(fandisk()));
  const auto plain = api::estimate_refine_memory(bytes_of(fandisk()), shape, refine("levels=2"));
  const auto sliced =
      api::estimate_refine_memory(bytes_of(fandisk()), shape, refine("levels=2&slice=0.01"));
  const auto job = api::estimate_refine_memory(
      bytes_of(fandisk()), shape, refine("levels=2&slice=0.01"), api::ResultSink::JobFiles);
  EXPECT_GT(sliced.contour_points, 0u);
  // The zip is built in memory (after the mesh is gone): at least as much as the job.
  EXPECT_GE(sliced.peak_bytes, job.peak_bytes);
  EXPECT_GT(sliced.answer_bytes, plain.answer_bytes);
  EXPECT_EQ(job.answer_bytes, 0u);
  EXPECT_GT(job.peak_bytes, plain.peak_bytes);
  // Thin layers: the contours dominate and the field says so.
  const auto thin = api::estimate_slice_memory(
      bytes_of(fandisk()), shape,
      api::parse_slice_params(api::parse_query("layer_height=0.0001"), api::RequestLimits{}));
  EXPECT_EQ(thin.field, "layer_height");
}

TEST(MemoryModel, OverTheFaceBudgetOnlyIngestIsPredicted) {
  const api::StlShape shape = api::stl_shape(bytes_of(fandisk()));
  const auto e =
      api::estimate_refine_memory(bytes_of(fandisk()), shape, refine("levels=8&max_faces=1000"));
  EXPECT_EQ(e.field, "max_faces");
  EXPECT_LT(e.peak_bytes, std::uint64_t{64} << 20);
}

TEST(MemoryModel, ProblemNamesFieldAndNumbers) {
  api::MemoryEstimate e;
  e.peak_bytes = std::uint64_t{3} << 30;
  e.field = "levels";
  const api::Problem p = api::memory_budget_problem(e, std::uint64_t{1} << 30);
  EXPECT_EQ(p.status, 422);
  EXPECT_EQ(p.slug, "budget-exceeded");
  EXPECT_EQ(p.field, "levels");
  EXPECT_EQ(p.extensions["predicted_bytes"], e.peak_bytes);
  EXPECT_EQ(p.extensions["memory_budget_bytes"], std::uint64_t{1} << 30);
  EXPECT_NE(p.detail.find("3072 MiB"), std::string::npos) << p.detail;
}

// Issue 16 item 4: sqrt3-interp with adaptive_tol=1e-9&max_level=6 was predicted at its
// worst case (9.4 M faces, 2.7 GiB) and peaked at 7.1 GiB. The prediction is now what the
// first level needs; the rest is reserved while it grows (run_refine's MemoryGrowFn). The
// bound on the output stays for disk space.
TEST(MemoryModel, AdaptiveIsAdmittedForItsFirstLevel) {
  const api::StlShape shape = api::stl_shape(bytes_of(fandisk()));
  const auto e = api::estimate_refine_memory(
      bytes_of(fandisk()), shape, refine("scheme=sqrt3-interp&adaptive_tol=1e-9&max_level=6"));
  EXPECT_EQ(e.output_faces, 12946u * 729);
  EXPECT_EQ(e.field, "max_level");
  EXPECT_LT(e.peak_bytes, std::uint64_t{64} << 20);
  EXPECT_GT(e.peak_bytes, fandisk().size() + 50 * 3 * 12946u);  // the first level's STL
  for (const char* scheme : {"lsf", "butterfly", "sqrt3"}) {
    const std::string query = std::string("scheme=") + scheme + "&adaptive_tol=1e-9&max_level=";
    EXPECT_EQ(
        api::estimate_refine_memory(bytes_of(fandisk()), shape, refine(query + "8")).peak_bytes,
        api::estimate_refine_memory(bytes_of(fandisk()), shape, refine(query + "1")).peak_bytes)
        << scheme;
  }
}

// run_refine hands whole-request figures to its callback: the body in every one, the mesh
// next to its STL in the last; refused, the request stops with the figure it asked for, and
// memory_budget_problem makes the 422 of a request that can never fit.
TEST(MemoryModel, RunRefineGrowsWholeRequestFiguresAndStopsWhenRefused) {
  const api::RefineRequest request = refine("scheme=sqrt3-interp&adaptive_tol=1e-9&max_level=2");
  std::vector<std::uint64_t> figures;
  const api::RefineOutcome out =
      api::run_refine(bytes_of(fandisk()), request, {}, nullptr, [&](std::uint64_t bytes) {
        figures.push_back(bytes);
        return true;
      });
  ASSERT_GE(figures.size(), 2u);
  // (the first is the deviation bound's surface, asked for before refine's own figures)
  EXPECT_GE(figures.front(), fandisk().size());
  EXPECT_GE(*std::max_element(figures.begin(), figures.end()),
            fandisk().size() + kRefineSlackBytes);
  EXPECT_GE(figures.back(), fandisk().size() + out.stl.size());
  const std::uint64_t peak = *std::max_element(figures.begin(), figures.end());
  const std::uint64_t capacity = peak / 2;
  try {
    api::run_refine(bytes_of(fandisk()), request, {}, nullptr,
                    [&](std::uint64_t bytes) { return bytes <= capacity; });
    ADD_FAILURE() << "not stopped";
  } catch (const MemoryBudgetError& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded);
    EXPECT_EQ(e.reason(), "memory_budget");
    EXPECT_EQ(e.field(), "max_level");
    EXPECT_GT(e.needed_bytes(), capacity);
    EXPECT_NE(std::find(figures.begin(), figures.end(), e.needed_bytes()), figures.end());
    const api::Problem p = api::memory_budget_problem(e, capacity);
    EXPECT_EQ(p.status, 422);
    EXPECT_EQ(p.field, "max_level");
    EXPECT_EQ(p.extensions["reason"], "memory_budget");
    EXPECT_EQ(p.extensions["predicted_bytes"], e.needed_bytes());
  }
}

TEST(ByteSize, SuffixesAreBinary) {
  using server::parse_byte_size;
  EXPECT_EQ(parse_byte_size("1073741824"), 1073741824u);
  EXPECT_EQ(parse_byte_size("512M"), 512u << 20);
  EXPECT_EQ(parse_byte_size("512MiB"), 512u << 20);
  EXPECT_EQ(parse_byte_size("512mb"), 512u << 20);
  EXPECT_EQ(parse_byte_size("2G"), std::uint64_t{2} << 30);
  EXPECT_EQ(parse_byte_size("1.5g"), std::uint64_t{3} << 29);
  EXPECT_EQ(parse_byte_size("64k"), 65536u);
  EXPECT_EQ(parse_byte_size("1T"), std::uint64_t{1} << 40);
  EXPECT_EQ(parse_byte_size(" 7 B "), 7u);
  for (const char* bad : {"", "M", "12X", "-1G", "1e400", "nan", "5 GB extra", "1iB", "9e18T"})
    EXPECT_THROW(parse_byte_size(bad), std::invalid_argument) << bad;
}

TEST(ByteSize, DefaultBudgetIsHalfTheMachineAtMost) {
  const std::uint64_t budget = server::default_memory_budget();
  EXPECT_GT(budget, 0u);
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  EXPECT_LE(budget, std::uint64_t(pages) * std::uint64_t(page) / 2);
}

TEST(MemoryBudget, ReservesGrowsShrinksAndGivesBack) {
  server::MemoryBudget budget(1000, 200);
  EXPECT_EQ(budget.capacity(), 800u);
  auto a = budget.try_reserve(500);
  ASSERT_TRUE(a);
  EXPECT_FALSE(budget.try_reserve(301));
  auto b = budget.try_reserve(300);
  ASSERT_TRUE(b);
  EXPECT_EQ(budget.reserved(), 800u);
  EXPECT_FALSE(b->grow_to(301));
  EXPECT_EQ(b->bytes(), 300u);
  a->shrink_to(100);
  EXPECT_TRUE(b->grow_to(700));
  EXPECT_EQ(budget.reserved(), 800u);
  server::MemoryBudget::Reservation moved = std::move(*b);
  EXPECT_EQ(b->bytes(), 0u);
  b.reset();
  EXPECT_EQ(budget.reserved(), 800u);
  moved.release();
  a.reset();
  EXPECT_EQ(budget.reserved(), 0u);
  EXPECT_FALSE(budget.try_reserve(801));
}

}  // namespace
}  // namespace stlrefine
