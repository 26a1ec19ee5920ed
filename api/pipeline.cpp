// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/pipeline.h"

#include <chrono>
#include <utility>

#include "api/ingest.h"
#include "api/problem.h"
#include "api/report.h"
#include "core/error.h"
#include "core/features/features.h"
#include "core/io/stl.h"
#include "core/mesh/mesh_stats.h"
#include "core/schemes/scheme.h"

namespace stlrefine::api {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The core's budget check, rethrown with its numbers for the 422 body.
void check_budget(std::size_t faces, const RefineParams& params) {
  try {
    check_face_budget(faces, params);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::BudgetExceeded) throw;
    const std::uint64_t predicted = make_scheme(params.scheme)->predict_faces(faces, params.levels);
    throw FaceBudgetError(e, predicted, params.max_faces);
  }
}

}  // namespace

nlohmann::ordered_json run_info(std::span<const std::uint8_t> bytes, const InfoRequest& request) {
  request.features.validate();
  const Ingested in = ingest_stl(bytes, request.weld_tolerance);
  const Mesh& mesh = in.result.mesh;
  return info_report(in, compute_stats(mesh), detect_features(mesh, request.features), request);
}

RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const ProgressFn& progress, const std::atomic<bool>* cancel) {
  const auto start = Clock::now();
  request.refine.validate();  // a bad parameter is reported before the file is read
  RefineTimes times;

  Ingested in = ingest_stl(bytes, request.weld_tolerance);
  times.ingest = in.seconds;
  check_budget(in.result.mesh.num_faces(), request.refine);

  auto phase = Clock::now();
  // The input mesh is not needed afterwards (the report only uses counters): move it in.
  RefineResult refined = refine(std::move(in.result.mesh), request.refine, progress, cancel);
  times.refine = seconds_since(phase);

  phase = Clock::now();
  RefineOutcome out;
  out.stl = write_stl(refined.mesh, request.output_format);
  times.write = seconds_since(phase);
  times.total = seconds_since(start);
  out.report = refine_report(in, refined.report, request, out.stl.size(), times);
  return out;
}

}  // namespace stlrefine::api
