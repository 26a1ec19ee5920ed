// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf_curvature.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"
#include "core/schemes/lsf.h"

namespace stlrefine {

namespace {

VertexCurvature curvature_of(const QuadricFit& fit) {
  VertexCurvature k;
  if (!fit.valid) return k;
  const Vec3 &su = fit.c[0], &sv = fit.c[1];
  const double E = dot(su, su), F = dot(su, sv), G = dot(sv, sv);
  const double det_first = E * G - F * F;
  const Vec3 n_raw = cross(su, sv);
  const double n_len = norm(n_raw);
  // A (nearly) singular first fundamental form: the fit has no tangent plane.
  if (!(det_first > 1e-24 * (E * G)) || !(n_len > 0)) return k;
  const Vec3 n = (1.0 / n_len) * n_raw;
  const double L = dot(fit.c[2], n), M = dot(fit.c[3], n), N = dot(fit.c[4], n);
  k.gaussian = (L * N - M * M) / det_first;
  k.mean = (E * N - 2.0 * F * M + G * L) / (2.0 * det_first);
  const double disc = std::sqrt(std::max(0.0, k.mean * k.mean - k.gaussian));
  k.k1 = k.mean + disc;
  k.k2 = k.mean - disc;
  k.valid = std::isfinite(k.gaussian) && std::isfinite(k.mean);
  return k;
}

Distribution distribution_of(std::vector<double> values) {
  Distribution d;
  if (values.empty()) return d;
  std::sort(values.begin(), values.end());
  auto at = [&](double q) {
    return values[static_cast<std::size_t>(std::lround(q * double(values.size() - 1)))];
  };
  d = {values.front(), at(0.05), at(0.5), at(0.95), values.back()};
  return d;
}

}  // namespace

std::vector<VertexCurvature> vertex_curvatures(const Mesh& mesh, const Features& features) {
  std::vector<VertexCurvature> out(mesh.num_vertices());
  parallel_for_each_index(mesh.num_vertices(), [&](std::size_t v) {
    out[v] = curvature_of(vertex_fit(mesh, features, VertexId(static_cast<std::uint32_t>(v))));
  });
  return out;
}

CurvatureSummary summarize(std::span<const VertexCurvature> curvatures) {
  CurvatureSummary s;
  std::vector<double> gaussian, mean, k1, k2, abs_max;
  for (const VertexCurvature& k : curvatures) {
    if (!k.valid) {
      ++s.invalid;
      continue;
    }
    ++s.valid;
    gaussian.push_back(k.gaussian);
    mean.push_back(k.mean);
    k1.push_back(k.k1);
    k2.push_back(k.k2);
    abs_max.push_back(std::max(std::abs(k.k1), std::abs(k.k2)));
  }
  s.gaussian = distribution_of(std::move(gaussian));
  s.mean = distribution_of(std::move(mean));
  s.k1 = distribution_of(std::move(k1));
  s.k2 = distribution_of(std::move(k2));
  s.abs_max = distribution_of(std::move(abs_max));
  return s;
}

}  // namespace stlrefine
