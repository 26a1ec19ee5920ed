// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/runs.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

#include "bench/fidelity/openmesh_butterfly.h"
#include "core/refine.h"

namespace stlrefine::fidelity {
namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::string fmt_tol(double tol) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", tol);
  return buf;
}

}  // namespace

std::string Variant::label() const {
  switch (kind) {
    case Kind::Ours:
      return scheme;
    case Kind::OursAdaptive:
      return scheme + " adaptive tol=" + fmt_tol(adaptive_tol);
    case Kind::OpenMeshButterfly:
      return "OpenMesh ModifiedButterflyT";
    case Kind::OpenMeshSqrt3LG:
      return "OpenMesh InterpolatingSqrt3LGT";
  }
  return {};
}

RunOutput run_variant(const Variant& variant, const Mesh& input, const RunSettings& settings) {
  RunOutput out;
  std::vector<double> times;
  for (int rep = 0; rep < std::max(1, settings.reps); ++rep) {
    if (variant.kind == Variant::Kind::OpenMeshButterfly) {
      double seconds = 0;
      out.mesh = openmesh_butterfly(input, variant.level, seconds);
      times.push_back(seconds);
      continue;
    }
    if (variant.kind == Variant::Kind::OpenMeshSqrt3LG) {
      double seconds = 0;
      out.mesh = openmesh_sqrt3_lg(input, variant.level, seconds);
      times.push_back(seconds);
      continue;
    }
    RefineParams params;
    params.scheme = variant.scheme;
    params.levels = variant.level;
    params.features.crease_angle_deg = settings.crease_angle_deg;
    params.features.crease_mode = CreaseMode::Angle;  // --crease-angle is the user's angle
    params.threads = settings.threads;
    if (variant.kind == Variant::Kind::OursAdaptive) {
      params.adaptive_tol = variant.adaptive_tol;  // curvature-adaptive, red-green closed
      params.max_level = variant.level;
    }
    Mesh copy = input;  // refine takes its mesh by value; the copy is not timed
    const auto t0 = std::chrono::steady_clock::now();
    RefineResult result = refine(std::move(copy), params);
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    out.mesh = std::move(result.mesh);
    out.fold_fallbacks = result.report.fold_fallbacks;
  }
  out.seconds = median(times);
  return out;
}

}  // namespace stlrefine::fidelity
