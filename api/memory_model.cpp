// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/memory_model.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string_view>
#include <vector>

#include "core/io/stl.h"
#include "core/refine.h"
#include "core/schemes/registry.h"

namespace stlrefine::api {

namespace {

// --- coefficients (bytes); the calibration is at the end of this file

struct Coefficients {
  double fixed;             // per request: thread stacks, report, small buffers, rounding
  double input_face;        // ingest: soup, welding, the input mesh and its features
  double output_face;       // per output face of a uniform refinement: the refined mesh and
                            // its features next to the STL being written (either host)
  double adaptive4_face;    // per output face (the bound) of the adaptive 1-to-4 host
  double adaptive3_face;    // per output face (the bound) of the adaptive sqrt3 host
  double slice_face;        // per sliced face: the slicer's per-face and per-vertex arrays
  double slice_input_face;  // a slice of the input: ingest and the slicer's arrays
  double info_face;         // per input face of an info report (features, curvatures)
  double contour_growth;    // the contour string while it grows (capacity doubling)
  double zip_growth;        // the zip archive while it grows
  double text_compression;  // deflate ratio of text contours in the zip (at least)
  double repair_face;       // repair=fill_holes: the CGAL Surface_mesh copy, the soup and the
                            // rebuilt mesh next to the input mesh (per input face)
};

constexpr Coefficients kC{
    .fixed = 8.0 * (1 << 20),
    .input_face = 160,
    .output_face = 140,
    .adaptive4_face = 420,
    .adaptive3_face = 300,
    .slice_face = 10,
    .slice_input_face = 100,
    .info_face = 160,
    .contour_growth = 2,
    .zip_growth = 2,
    .text_compression = 3,
    // Estimated, not calibrated: Surface_mesh ~64 B a face (3 half-edge pairs of 2 x 12 B,
    // a face, half a vertex of 24 B point + 4 B), the soup 24 B, the rebuilt mesh ~100 B.
    .repair_face = 200,
};

// What repair=fill_holes adds while it runs, on top of ingest: the copies of the input, and
// the faces refining holes may add at most (HoleFillOptions::max_added_faces; the flat
// triangulations add fewer faces than the rims have edges, within the input's 3F).
double repair_bytes(repair::RepairMode mode, std::uint64_t faces) {
  if (mode != repair::RepairMode::FillHoles) return 0.0;
  const double added = double(repair::HoleFillOptions{}.max_added_faces) + 3.0 * double(faces);
  return kC.repair_face * (double(faces) + added);
}

// Bytes of one contour point in each format (measured 40-43, 38-41, 37-41 and 8.0-8.4).
double point_bytes(slicer::SliceFormat format) {
  switch (format) {
    case slicer::SliceFormat::Json:
      return 44;
    case slicer::SliceFormat::Svg:
      return 42;
    case slicer::SliceFormat::CliAscii:
      return 42;
    case slicer::SliceFormat::CliBinary:
      return 9;
  }
  return 44;
}

constexpr std::uint64_t kPreamble = 84;
constexpr std::uint64_t kFacet = 50;

//! Planes at or below z, for the plan of `params` over [lo, hi].
struct Planes {
  std::vector<double> heights;  // explicit, ascending
  double lo = 0, h = 1;
  std::uint64_t n = 0;  // uniform
  std::uint64_t at_or_below(double z) const {
    if (!heights.empty())
      return std::uint64_t(std::upper_bound(heights.begin(), heights.end(), z) - heights.begin());
    const double k = std::floor((z - lo) / h - 0.5) + 1;  // planes lo + (k + 1/2) h <= z
    if (!(k > 0)) return 0;
    return std::min<std::uint64_t>(n, std::uint64_t(std::min(k, 1e18)));
  }
};

// The faces an adaptive request is admitted for: its first level, as if every face were
// refined (the hosts' per-face coefficients cover the hierarchy they keep besides).
std::uint64_t admission_faces(const RefineParams& p, const Scheme& scheme, std::uint64_t faces) {
  return std::min<std::uint64_t>(scheme.predict_faces(faces, 1), p.max_faces);
}

// Contour points of a slice after the faces grew by `growth` (crossings grow like one over
// the edge length: the square root of the face count).
std::uint64_t grown_points(std::span<const std::uint8_t> bytes, const StlShape& shape,
                           const slicer::SliceParams& params, double growth) {
  const double crossings = double(count_crossings(bytes, shape, params)) * growth;
  return std::min<std::uint64_t>(std::uint64_t(std::min(crossings, 1e18)), params.max_points);
}

// The slice's point estimate, capped by the point budget (over it the slicer refuses).
std::uint64_t contour_points(std::uint64_t crossings, const slicer::SliceParams& params) {
  return std::min<std::uint64_t>(crossings, params.max_points);
}

}  // namespace

std::uint64_t count_crossings(std::span<const std::uint8_t> bytes, const StlShape& shape,
                              const slicer::SliceParams& params) {
  Planes planes;
  if (!params.heights.empty()) {
    planes.heights = params.heights;
    std::sort(planes.heights.begin(), planes.heights.end());
  } else {
    if (!shape.has_z && !(params.z_min && params.z_max)) return 0;
    planes.lo = params.z_min.value_or(shape.z_min);
    const double hi = params.z_max.value_or(shape.z_max);
    planes.h = params.layer_height;
    if (!(planes.h > 0) || !(hi >= planes.lo)) return 0;
    const double span = (hi - planes.lo) / planes.h;
    // Over max_layers the plan is refused before any work: nothing to estimate.
    if (!(span <= double(params.max_layers) + 1)) return 0;
    planes.n = std::uint64_t(std::floor(span + 0.5)) + 1;
  }
  std::uint64_t crossings = 0;
  for_each_facet_z(bytes, shape, [&](double a, double b, double c) {
    if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c)) return;
    crossings += planes.at_or_below(std::max({a, b, c})) - planes.at_or_below(std::min({a, b, c}));
  });
  return crossings;
}

MemoryEstimate estimate_refine_memory(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                      const RefineRequest& request, ResultSink sink) {
  return estimate_refine_memory(bytes, shape, request, *make_scheme(request.refine.scheme), sink);
}

MemoryEstimate estimate_refine_memory(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                      const RefineRequest& request, const Scheme& scheme,
                                      ResultSink sink) {
  const RefineParams& p = request.refine;
  MemoryEstimate e;
  const std::uint64_t faces = shape.faces;
  e.output_faces = predict_faces(faces, scheme, p);
  // Over the face budget, run_refine refuses right after ingest: that is all it needs.
  if (!p.adaptive() && e.output_faces > p.max_faces) {
    e.peak_bytes = std::uint64_t(kC.fixed + double(shape.bytes) + kC.input_face * double(faces));
    e.field = "max_faces";
    return e;
  }
  const bool sqrt3 = adaptive_sqrt3_scheme(scheme) != nullptr;
  const double per_face =
      p.adaptive() ? (sqrt3 ? kC.adaptive3_face : kC.adaptive4_face) : kC.output_face;
  // The faces the memory is predicted for: the output, or the first adaptive level.
  const std::uint64_t held_faces =
      p.adaptive() ? admission_faces(p, scheme, faces) : e.output_faces;
  const double stl = double(stl_bytes(held_faces, request.output_format));
  const double base = kC.fixed + double(shape.bytes);
  // The per-face coefficients include a binary STL record (50 bytes) next to the mesh.
  double peak = base + kC.input_face * double(faces) +
                std::max(repair_bytes(request.repair, faces),
                         (per_face - double(kFacet)) * double(held_faces) + stl);
  double contours = 0;
  if (request.slice) {
    // Faces crossing a plane grow like 1 / edge length: x2 per 1-to-4 step, x sqrt(3) per
    // sqrt3 step.
    const double step = sqrt3 ? std::sqrt(3.0) : 2.0;
    const slicer::SliceParams& params = request.slice->params;
    e.contour_points =
        grown_points(bytes, shape, params, std::pow(step, p.adaptive() ? p.max_level : p.levels));
    const std::uint64_t points =
        p.adaptive() ? grown_points(bytes, shape, params, step) : e.contour_points;
    const slicer::SliceFormat format = request.slice->format;
    contours = point_bytes(format) * double(points);
    // Slicing: the refined mesh and its STL are still there.
    peak += kC.slice_face * double(held_faces) + kC.contour_growth * contours;
    if (sink == ResultSink::Answer) {
      // Then the zip is built from the STL and the contours (the mesh is gone by then).
      const double zipped =
          stl +
          (format == slicer::SliceFormat::CliBinary ? contours : contours / kC.text_compression);
      peak = std::max(peak, base + stl + contours + kC.zip_growth * zipped);
      e.answer_bytes = std::uint64_t(zipped);
    }
  } else if (sink == ResultSink::Answer && request.report_in_zip) {
    // report=zip: the STL string, then the zip made from it (growing by doubling).
    peak = std::max(peak, base + stl + kC.zip_growth * stl);
    e.answer_bytes = std::uint64_t(stl);
  } else if (sink == ResultSink::Answer) {
    e.answer_bytes = std::uint64_t(stl);
  }
  e.peak_bytes = std::uint64_t(peak);
  if (request.slice && kC.contour_growth * contours > 0.5 * peak)
    e.field = request.slice->layer_height_name;
  else if (p.adaptive())
    e.field = "max_level";
  else if (p.levels > 0)
    e.field = "levels";
  return e;
}

std::uint64_t stl_bytes(std::uint64_t faces, StlFormat format) {
  // core/io/stl_writer.cpp sizes its buffer up front: 50 bytes a facet, or in ASCII the
  // longest facet text (284 bytes: 15 floats of at most 16 characters) and the solid name
  // (at most 1024 bytes) twice.
  constexpr std::uint64_t kAsciiFacet = 284, kAsciiFrame = 2 * (1024 + 16);
  if (format == StlFormat::Ascii)
    return faces > (UINT64_MAX - kAsciiFrame) / kAsciiFacet ? UINT64_MAX
                                                            : kAsciiFrame + kAsciiFacet * faces;
  return faces > (UINT64_MAX - kPreamble) / kFacet ? UINT64_MAX : kPreamble + kFacet * faces;
}

std::uint64_t refined_memory_bytes(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                   const RefineRequest& request, std::uint64_t input_faces,
                                   std::uint64_t output_faces, std::uint64_t mesh_bytes) {
  double peak = kC.fixed + double(bytes.size()) + double(mesh_bytes) +
                double(stl_bytes(output_faces, request.output_format));
  if (request.slice) {
    const double growth =
        input_faces > 0 ? std::sqrt(double(output_faces) / double(input_faces)) : 1.0;
    const std::uint64_t points = grown_points(bytes, shape, request.slice->params, growth);
    peak += kC.slice_face * double(output_faces) +
            kC.contour_growth * point_bytes(request.slice->format) * double(points);
  }
  return std::uint64_t(std::min(peak, 1.8e19));
}

Problem memory_budget_problem(const MemoryBudgetError& error, std::uint64_t capacity) {
  MemoryEstimate e;
  e.peak_bytes = error.needed_bytes();
  e.field = error.field();
  return memory_budget_problem(e, capacity);
}

MemoryEstimate estimate_slice_memory(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                     const SliceRequest& request) {
  MemoryEstimate e;
  const slicer::SliceParams& params = request.slice.params;
  e.contour_points = contour_points(count_crossings(bytes, shape, params), params);
  const double contours = point_bytes(request.slice.format) * double(e.contour_points);
  e.answer_bytes = std::uint64_t(contours);
  // report=zip: the contours, then the zip made from them.
  const double answer =
      request.report_in_zip ? (1 + kC.zip_growth) * contours : kC.contour_growth * contours;
  e.peak_bytes =
      std::uint64_t(kC.fixed + double(shape.bytes) + kC.slice_input_face * double(shape.faces) +
                    std::max(repair_bytes(request.repair, shape.faces), answer));
  if (kC.contour_growth * contours > 0.5 * double(e.peak_bytes))
    e.field = params.heights.empty() ? "layer_height" : "heights";
  return e;
}

MemoryEstimate estimate_info_memory(const StlShape& shape, repair::RepairMode repair) {
  MemoryEstimate e;
  e.peak_bytes = std::uint64_t(kC.fixed + double(shape.bytes) + kC.info_face * double(shape.faces) +
                               repair_bytes(repair, shape.faces));
  return e;
}

Problem memory_budget_problem(const MemoryEstimate& estimate, std::uint64_t capacity) {
  const auto mib = [](std::uint64_t bytes) {
    return std::to_string((bytes + (1 << 20) - 1) >> 20);
  };
  std::string advice = ".";
  if (estimate.field == "levels") advice = "; use fewer levels or a smaller part.";
  if (estimate.field == "max_level") advice = "; lower max_level or max_faces.";
  if (estimate.field == "slice" || estimate.field == "layer_height")
    advice = "; slice with thicker layers or refine less.";
  if (estimate.field == "layer_height" || estimate.field == "heights")
    advice = "; slice with fewer layers.";
  Problem p = make_problem(422, "budget-exceeded",
                           "this request would need about " + mib(estimate.peak_bytes) +
                               " MiB of memory; this server gives one request at most " +
                               mib(capacity) + " MiB" + advice);
  p.title = "Memory budget exceeded";
  p.field = estimate.field;
  p.extensions["reason"] = "memory_budget";
  p.extensions["predicted_bytes"] = estimate.peak_bytes;
  p.extensions["memory_budget_bytes"] = capacity;
  return p;
}

}  // namespace stlrefine::api

// --- calibration
//
// bench/reliability/memory_calibration.cpp (stlrefine_memory_calibration) measured the
// peak RSS one request adds to an idle stlrefined (fresh daemon per case, warm-up request,
// VmHWM after clear_refs minus VmRSS before) for 173 requests: gearwheel (2,444 faces,
// binary and ASCII), fandisk (12,946), armadillo (29,170), cycloidal_nonmanifold (43,368),
// bunny (69,451) and dragon_full (871,414) from ../shared/meshes; every scheme on fandisk
// and bunny, butterfly and sqrt3-interp on the others, levels 0 up to 3.5 M output faces;
// info; slices in every format at two layer heights; refine + slice as zip (json,
// cli-binary); jobs with and without a slice; adaptive butterfly, lsf and sqrt3-interp.
//
// Least squares on the uniform rows gave 111.5 bytes per output face for both hosts (the
// refined mesh with its features, ~62 bytes, next to its 50-byte STL record), 75-150 per
// input face and 2-4 MiB fixed; lsf and butterfly-g1 take up to 10 % more than butterfly.
// Contour points cost 40-43 bytes in json, 37-41 in svg and cli, 8.0-8.4 in cli-binary, and
// the contour string and the zip grow by doubling, so each may hold up to twice its size.
// The points themselves are predicted within 1.5 % (count_crossings x growth^levels).
// The coefficients above are that fit rounded up (140, 160, 8 MiB, 2x growth), so the
// prediction is an upper bound: predicted / measured over the 97 non-adaptive rows above
// 20 MiB is 1.05 .. 2.21 (median 1.29); over all 158 non-adaptive rows 1.05 .. 16 (small
// requests, where the fixed 8 MiB dominates). The adaptive rows were predicted at their
// bound (the uniform count at max_level, or max_faces if lower), 2-137 times what they
// used; per face actually made they took <= 383 (1-to-4) and <= 274 (sqrt3) bytes. Run
// 2026-11-23 on the 2-core development machine (Release, THP madvise, glibc malloc).
//
// Issue 16 item 4: that bound was no bound for adaptive sqrt3, whose hierarchy measures two
// levels below each triangle (fandisk, sqrt3-interp, adaptive_tol=1e-9, max_level=6:
// predicted 2.7 GiB, peak RSS 7.1 GiB for 6.7 M faces). Adaptive requests are now predicted
// for their first level only (admission_faces), and run_refine's MemoryGrowFn reserves the
// rest as it grows, from exact array sizes (core/refine.h; the figures measured 1.07 to 1.3
// times the peak RSS they bound, bench/RESULTS.md "Adaptive memory admission").
