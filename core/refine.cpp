// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/refine.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "core/error.h"

namespace stlrefine {

void RefineParams::validate() const {
  make_scheme(scheme);  // throws InvalidParameter naming "scheme"
  require_in_range("levels", levels, 0, 8);
  features.validate();
  require_in_range<std::uint64_t>("max_faces", max_faces, 1, (std::uint64_t{1} << 31) - 1);
  require_in_range("threads", threads, 0, 256);
}

std::uint64_t check_face_budget(std::size_t faces, const RefineParams& params) {
  const std::uint64_t predicted = make_scheme(params.scheme)->predict_faces(faces, params.levels);
  if (predicted > params.max_faces) {
    throw Error(ErrorCode::BudgetExceeded, "face_budget",
                params.scheme + " with " + std::to_string(params.levels) + " levels would make " +
                    std::to_string(predicted) + " faces from " + std::to_string(faces) +
                    "; the limit is max_faces = " + std::to_string(params.max_faces))
        .with_field("max_faces");
  }
  return predicted;
}

namespace {

void throw_if_cancelled(const std::atomic<bool>* cancel) {
  if (cancel && cancel->load(std::memory_order_relaxed))
    throw Error(ErrorCode::Cancelled, "cancelled", "refinement cancelled");
}

RefineResult run_levels(Mesh mesh, const RefineParams& params, const Scheme& scheme,
                        const ProgressFn& progress, const std::atomic<bool>* cancel) {
  const auto start = std::chrono::steady_clock::now();
  RefineResult result;
  RefineReport& r = result.report;
  r.scheme = params.scheme;
  r.levels = params.levels;
  r.input_vertices = mesh.num_vertices();
  r.input_faces = mesh.num_faces();
  const std::size_t input_faces = mesh.num_faces();
  // Old vertices keep their ids at every level, so input vertex v is output vertex v.
  const BigVector<Vec3> input_positions(mesh.positions().begin(), mesh.positions().end());

  Features features = detect_features(mesh, params.features);
  Level level{std::move(mesh), std::move(features)};
  r.sharp_edges_in = level.features.num_sharp_edges();
  r.corners = level.features.count(VertexKind::Corner);
  r.creases = level.features.count(VertexKind::Crease);
  r.darts = level.features.count(VertexKind::Dart);

  StepStats stats;
  // Work per level grows 4x (3x for sqrt3), so weight progress by output faces.
  std::uint64_t total = 0;
  for (int i = 1; i <= params.levels; ++i) total += scheme.predict_faces(input_faces, i);
  std::uint64_t done = 0;
  for (int i = 1; i <= params.levels; ++i) {
    throw_if_cancelled(cancel);
    if (progress)
      progress(total ? double(done) / double(total) : 0.0,
               "level " + std::to_string(i) + "/" + std::to_string(params.levels));
    level = scheme.refine_once(level, stats);
    done += level.mesh.num_faces();
  }
  throw_if_cancelled(cancel);

  for (std::size_t v = 0; v < input_positions.size(); ++v) {
    r.max_input_displacement = std::max(
        r.max_input_displacement,
        distance(input_positions[v], level.mesh.position(VertexId(static_cast<std::uint32_t>(v)))));
  }
  r.output_vertices = level.mesh.num_vertices();
  r.output_faces = level.mesh.num_faces();
  r.sharp_edges_out = level.features.num_sharp_edges();
  r.fold_fallbacks = stats.fold_fallbacks;
  result.mesh = std::move(level.mesh);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress) progress(1.0, "done");
  return result;
}

}  // namespace

RefineResult refine(Mesh mesh, const RefineParams& params, const ProgressFn& progress,
                    const std::atomic<bool>* cancel) {
  params.validate();
  check_face_budget(mesh.num_faces(), params);
  const auto scheme = make_scheme(params.scheme);
  if (params.threads == 0) return run_levels(std::move(mesh), params, *scheme, progress, cancel);
  // A dedicated arena caps this request's threads without touching the global pool.
  tbb::task_arena arena(params.threads);
  return arena.execute(
      [&] { return run_levels(std::move(mesh), params, *scheme, progress, cancel); });
}

}  // namespace stlrefine
