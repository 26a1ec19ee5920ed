// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/plan.h"

#include <utility>

#include "api/pipeline.h"
#include "api/problem.h"
#include "core/error.h"
#include "core/refine.h"

namespace stlrefine::api {

RefinePlan plan_refine(RefineRequest request) {
  RefinePlan plan;
  plan.scheme = make_scheme(request.refine);  // validates, then makes it: once per request
  plan.request = std::move(request);
  return plan;
}

RefinePlan plan_body(RefinePlan plan, std::span<const std::uint8_t> bytes, ResultSink sink) {
  plan.shape = stl_shape(bytes);
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
  const StlShape shape = stl_shape(bytes);
  MemoryEstimate memory = estimate_slice_memory(bytes, shape, request);
  return SlicePlan(std::move(request), shape, std::move(memory));
}

InfoPlan plan_info(const RawParams& raw, std::span<const std::uint8_t> bytes) {
  return plan_info(parse_info_params(raw), bytes);
}

InfoPlan plan_info(InfoRequest request, std::span<const std::uint8_t> bytes) {
  const StlShape shape = stl_shape(bytes);
  MemoryEstimate memory = estimate_info_memory(shape, request.repair);
  return InfoPlan(std::move(request), shape, std::move(memory));
}

}  // namespace stlrefine::api
