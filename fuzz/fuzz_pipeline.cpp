// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors

// libFuzzer harness: the whole request path on one STL input, as the daemon runs it:
// read -> weld -> ingest/repair (api::ingest_stl), `info` (stats, features, curvature and
// its CSV), `slice` of the input, then for every scheme in the registry one level of
// `refine` (api::run_refine: face budget, refine, write_stl, report), the adaptive modes
// (1-to-4 and sqrt3) once each, and each refined STL read back by our own reader and
// sliced (every writer in turn) at heights through its vertices and in between.
//
// Inputs above kMaxInputFaces faces are skipped, and refinements run under a face budget
// of kMaxOutputFaces, so one input stays fast (milliseconds, not seconds).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "api/ingest.h"
#include "api/pipeline.h"
#include "core/schemes/registry.h"
#include "fuzz/fuzz_check.h"

using namespace stlrefine;

namespace {

constexpr std::size_t kMaxInputFaces = 512;
constexpr std::uint64_t kMaxOutputFaces = 2048;  // one level of 512 faces (682 for sqrt3)

std::span<const std::uint8_t> as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// Planes at both ends of the part, through a few vertices (the slicer's degenerate cases)
// and in between: at most 16 distinct heights, whatever the coordinates.
std::vector<double> heights_for(const Mesh& mesh) {
  const slicer::Bounds b = slicer::mesh_bounds(mesh);
  std::vector<double> h{b.min.z, b.max.z};
  for (int k = 1; k < 8; ++k) h.push_back(b.min.z + (b.max.z - b.min.z) * k / 8.0);
  for (std::size_t v = 0; v < std::min<std::size_t>(mesh.num_vertices(), 5); ++v)
    h.push_back(mesh.position(VertexId(static_cast<std::uint32_t>(v))).z);
  std::sort(h.begin(), h.end());
  h.erase(std::unique(h.begin(), h.end()), h.end());
  return h;
}

api::SliceOptions slice_options(const Mesh& mesh, slicer::SliceFormat format) {
  api::SliceOptions o;
  o.params.heights = heights_for(mesh);
  o.params.threads = 1;
  o.format = format;
  return o;
}

// Slicing a mesh that ingest accepted, at valid heights: nothing may refuse.
void slice_checked(const Mesh& mesh, slicer::SliceFormat format) {
  slicer::SliceStats stats;
  const std::string out = api::slice_to_string(mesh, slice_options(mesh, format), &stats);
  fuzz::check(stats.layers == heights_for(mesh).size(), "a layer went missing");
  fuzz::check(!out.empty(), "empty slice output");
}

// One scheme, one level (or the adaptive mode), then our own output read back and sliced.
void refine_checked(std::span<const std::uint8_t> bytes, api::RefineRequest request,
                    slicer::SliceFormat format) {
  const auto scheme = make_scheme(request.refine.scheme, request.refine.scheme_options);
  api::RefineOutcome out;
  try {
    out = api::run_refine(bytes, request);
  } catch (const Error& e) {
    fuzz::check_refusal(e);
    // The budget; welding within a tolerance collapsed every facet of a tiny part; or the
    // adaptive mode met a mesh that is not simple (AdaptiveSplit4 refuses those).
    fuzz::check(e.code() == ErrorCode::BudgetExceeded ||
                    (e.code() == ErrorCode::NotTriangleMesh && request.weld_tolerance > 0) ||
                    (e.reason() == "adaptive_non_simple" && request.refine.adaptive()),
                "refine refused an ingested mesh:", e.what());
    return;
  }
  (void)out.report.dump(-1, ' ', true);  // as the daemon's report header
  const std::uint64_t faces = out.report["output"].value("faces", std::uint64_t{0});
  fuzz::check(faces <= request.refine.max_faces, "output over the face budget");
  if (!request.refine.adaptive()) {
    const std::uint64_t in_faces = out.report["input"].value("faces", std::uint64_t{0});
    fuzz::check(faces == scheme->predict_faces(in_faces, request.refine.levels),
                "output face count differs from the prediction");
  }
  if (scheme->interpolating())
    fuzz::check(out.report.value("max_input_displacement", -1.0) == 0.0,
                "an interpolating scheme moved an input vertex:", request.refine.scheme.c_str());

  // Our own output must read back: same facet count, same format.
  api::Ingested back;
  try {
    back = api::ingest_stl(as_bytes(out.stl), 0.0);
  } catch (const Error& e) {
    fuzz::check_refusal(e);
    // Refinement may move a point just past the reader's 1e9 coordinate limit, and
    // float rounding may collapse every facet of a tiny part (NotTriangleMesh).
    fuzz::check(e.reason() == "coordinate_out_of_range" || e.code() == ErrorCode::NotTriangleMesh,
                "our own output does not read back:", e.what());
    return;
  }
  fuzz::check(back.triangles == faces, "the written STL has another facet count");
  fuzz::check(back.format == request.output_format, "the written STL has another format");
  slice_checked(back.result.mesh, format);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  api::Ingested in;
  try {
    in = api::ingest_stl(bytes, 0.0);
  } catch (const Error& e) {
    fuzz::check_refusal(e);
    return 0;
  }
  const Mesh& mesh = in.result.mesh;
  if (mesh.num_faces() > kMaxInputFaces) return 0;

  // info, with the curvature table.
  const api::InfoOutcome info = api::run_info(bytes, api::InfoRequest{}, true);
  (void)info.report.dump(2, ' ', true);
  fuzz::check(info.curvature_csv.has_value(), "no curvature table");

  // info after repair=fill_holes: CGAL's hole filling on whatever rims the input has.
  api::InfoRequest repaired;
  repaired.repair = repair::RepairMode::FillHoles;
  const nlohmann::ordered_json fixed = api::run_info(bytes, repaired);
  const auto& r = fixed["input"]["repair"];
  if (r.contains("holes"))
    fuzz::check(r["holes"].get<std::size_t>() ==
                    r["filled"].get<std::size_t>() + r["left_open"].get<std::size_t>(),
                "repair: holes != filled + left_open");

  // slice of the input.
  api::SliceRequest slice;
  slice.slice = slice_options(mesh, slicer::SliceFormat::Json);
  const api::SliceOutcome sliced = api::run_slice(bytes, slice);
  (void)sliced.report.dump(-1, ' ', true);

  // One level of every registered scheme, with some variety in the other parameters.
  constexpr std::array<slicer::SliceFormat, 4> kFormats = {
      slicer::SliceFormat::Json, slicer::SliceFormat::Svg, slicer::SliceFormat::CliAscii,
      slicer::SliceFormat::CliBinary};
  constexpr std::array<double, 4> kCreaseAngles = {35.0, 0.0, 90.0, 180.0};
  const auto names = scheme_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    api::RefineRequest request;
    request.refine.scheme = std::string(names[i]);
    request.refine.levels = 1;
    request.refine.max_faces = kMaxOutputFaces;
    request.refine.threads = 1;
    request.refine.features.crease_angle_deg = kCreaseAngles[i % kCreaseAngles.size()];
    request.refine.scheme_options.set("alpha", 0.5);  // sqrt3-unified: half-way, exact on features
    request.output_format = i % 2 ? StlFormat::Ascii : StlFormat::Binary;
    if (i == 1) request.weld_tolerance = 1e-3;
    refine_checked(bytes, request, kFormats[i % kFormats.size()]);
  }

  // The adaptive modes, two steps each: the 1-to-4 host at a tolerance relative to the
  // part's size, and the sqrt3 host with the dihedral criterion as well.
  const slicer::Bounds b = slicer::mesh_bounds(mesh);
  const double diagonal = std::hypot(b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z);
  for (const char* scheme : {"butterfly", "sqrt3-interp"}) {
    api::RefineRequest adaptive;
    adaptive.refine.scheme = scheme;
    adaptive.refine.adaptive_tol = std::clamp(diagonal * 1e-3, 1e-9, 1e6);
    if (adaptive.refine.scheme != "butterfly") adaptive.refine.adaptive_angle = 20;
    adaptive.refine.max_level = 2;
    adaptive.refine.max_faces = 2 * kMaxOutputFaces;
    adaptive.refine.threads = 1;
    refine_checked(bytes, adaptive, slicer::SliceFormat::Json);
  }
  return 0;
}
