// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/plan.h"

#include <charconv>
#include <string_view>
#include <utility>

#include "api/pipeline.h"
#include "api/problem.h"
#include "core/error.h"
#include "core/io/mesh_formats.h"
#include "core/refine.h"

namespace stlrefine::api {

namespace {

// The body's shape: stl_shape for an STL; for the other formats read_mesh takes, the
// triangles they will make, counted without reading them, so that the face budget and the
// memory estimate see them before any work: OBJ exactly (each `f` line fans into its
// corners - 2), PLY from its header's face count (a lower bound: polygons fan into more),
// a 3MF not at all (it would have to be inflated; refine's own metering still holds it).
StlShape body_shape(std::span<const std::uint8_t> bytes) {
  StlShape shape = stl_shape(bytes);
  const MeshFormat format = sniff_mesh_format(bytes);
  if (format == MeshFormat::Stl || format == MeshFormat::ThreeMf) return shape;
  shape = StlShape{};
  shape.bytes = bytes.size();
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find_first_of("\r\n", pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    const std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string_view::npos) continue;
    line.remove_prefix(start);
    if (format == MeshFormat::Ply) {
      if (line.starts_with("end_header")) break;
      std::uint64_t count = 0;
      if (line.starts_with("element face ")) {
        const std::string_view n = line.substr(13);
        std::from_chars(n.data(), n.data() + n.size(), count);
        shape.faces = count;
      }
    } else if (line.size() > 1 && line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
      std::uint64_t corners = 0;
      bool in_word = false;
      for (const char c : line.substr(1)) {
        const bool blank = c == ' ' || c == '\t';
        corners += !blank && !in_word;
        in_word = !blank;
      }
      if (corners >= 3) shape.faces += corners - 2;
    }
  }
  return shape;
}

}  // namespace

RefinePlan plan_refine(RefineRequest request) {
  RefinePlan plan;
  plan.scheme = make_scheme(request.refine);  // validates, then makes it: once per request
  plan.request = std::move(request);
  return plan;
}

RefinePlan plan_body(RefinePlan plan, std::span<const std::uint8_t> bytes, ResultSink sink) {
  plan.shape = body_shape(bytes);
  plan.predicted_faces = predict_faces(plan.shape.faces, *plan.scheme, plan.request.refine);
  plan.memory = estimate_refine_memory(bytes, plan.shape, plan.request, *plan.scheme, sink);
  return plan;
}

RefinePlan plan_refine(const RawParams& raw, const RequestLimits& limits,
                       std::span<const std::uint8_t> bytes, ResultSink sink) {
  return plan_body(plan_refine(parse_refine_fields(raw, limits)), bytes, sink);
}

RefinePlan plan_refine(RefineRequest request, std::span<const std::uint8_t> bytes,
                       ResultSink sink) {
  return plan_body(plan_refine(std::move(request)), bytes, sink);
}

void refuse_over_face_budget(const RefinePlan& plan) {
  refuse_over_face_budget(plan.shape.faces, *plan.scheme, plan.request.refine);
}

SlicePlan plan_slice(const RawParams& raw, const RequestLimits& limits,
                     std::span<const std::uint8_t> bytes) {
  return plan_slice(parse_slice_params(raw, limits), bytes);
}

SlicePlan plan_slice(SliceRequest request, std::span<const std::uint8_t> bytes) {
  const StlShape shape = body_shape(bytes);
  MemoryEstimate memory = estimate_slice_memory(bytes, shape, request);
  return SlicePlan(std::move(request), shape, std::move(memory));
}

InfoPlan plan_info(const RawParams& raw, std::span<const std::uint8_t> bytes) {
  return plan_info(parse_info_params(raw), bytes);
}

InfoPlan plan_info(InfoRequest request, std::span<const std::uint8_t> bytes) {
  const StlShape shape = body_shape(bytes);
  MemoryEstimate memory = estimate_info_memory(shape, request.repair);
  return InfoPlan(std::move(request), shape, std::move(memory));
}

}  // namespace stlrefine::api
