// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/smooth_pull.h"

#include <algorithm>
#include <cmath>
#include <queue>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/parallel.h"

namespace stlrefine::primitives {

void SmoothPullParams::validate() const {
  if (!(slope > 0 && slope <= 1))
    throw Error(ErrorCode::InvalidParameter, "pull_slope", "pull slope must be in (0, 1]");
  if (rounds < 1 || rounds > 16)
    throw Error(ErrorCode::InvalidParameter, "pull_rounds", "pull rounds must be in [1, 16]");
}

std::uint64_t smooth_pull_bytes(std::uint64_t vertices) {
  return (2 * sizeof(Vec3) + sizeof(double) + 2 * 2 * sizeof(std::uint32_t) +
          2 * 2 * sizeof(std::pair<double, std::uint32_t>)) *
         vertices;
}

namespace {

// The point just inside the bound on the way from p to its closest input point.
Vec3 pulled_back(const Vec3& p, const Nearest& n, double bound, double diagonal) {
  return n.point + (p - n.point) * (just_inside(bound, diagonal) / n.distance);
}

}  // namespace

SmoothPullReport smooth_pull(
    Mesh& mesh, const std::vector<std::uint8_t>& movable, std::vector<Nearest>& nearest,
    const std::function<double(const Nearest& at)>& bound,
    const std::function<Nearest(const Vec3& p, std::uint32_t hint)>& locate, double diagonal,
    const SmoothPullParams& params) {
  params.validate();
  SmoothPullReport report;
  const std::size_t nv = mesh.num_vertices();
  BigVector<Vec3>& positions = mesh.mutable_positions();
  auto past = [&](std::size_t i) { return movable[i] && nearest[i].distance > bound(nearest[i]); };
  std::vector<std::uint32_t> seeds;
  for (std::size_t i = 0; i < nv; ++i)
    if (past(i)) seeds.push_back(static_cast<std::uint32_t>(i));
  report.violators = seeds.size();
  if (seeds.empty()) return report;

  // Each vertex's total move, for the report.
  std::vector<Vec3> start(positions.begin(), positions.end());
  // Per vertex, this round: how far it is pulled (0: not reached) and by what.
  std::vector<double> reach(nv, 0.0);
  std::vector<Vec3> pull(nv);
  std::vector<std::uint32_t> touched;
  while (!seeds.empty() && report.rounds < params.rounds) {
    ++report.rounds;
    // The largest cone a - slope * s over the pulled vertices, s along the edges (Dijkstra
    // from the largest pulls down): every edge changes its pull by at most slope times its
    // length, so the surface moves as a sheet, not as spikes.
    std::priority_queue<std::pair<double, std::uint32_t>> heap;
    for (std::uint32_t i : seeds) {
      pull[i] = pulled_back(positions[i], nearest[i], bound(nearest[i]), diagonal) - positions[i];
      reach[i] = norm(pull[i]);
      if (!(reach[i] > 0)) continue;
      touched.push_back(i);
      heap.emplace(reach[i], i);
    }
    while (!heap.empty()) {
      const auto [r, j] = heap.top();
      heap.pop();
      if (r < reach[j]) continue;  // reached farther by another pulled vertex since
      const Vec3 direction = pull[j] * (1.0 / r);
      for_each_outgoing(mesh, VertexId(j), [&](HalfedgeId h) {
        const std::uint32_t k = mesh.to(h).idx;
        if (!movable[k]) return;
        const double next = r - params.slope * distance(positions[j], positions[k]);
        if (next <= reach[k]) return;
        if (reach[k] == 0) touched.push_back(k);
        reach[k] = next;
        pull[k] = direction * next;
        heap.emplace(next, k);
      });
    }
    parallel_for_each_range(touched.size(), [&](std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t != end; ++t) {
        const std::uint32_t k = touched[t];
        positions[k] = positions[k] + pull[k];
        nearest[k] = locate(positions[k], nearest[k].face);
        reach[k] = 0;
        pull[k] = Vec3{};
      }
    });
    seeds.clear();
    for (std::uint32_t k : touched)
      if (past(k)) seeds.push_back(k);
    touched.clear();
  }
  // Past the rounds: pulled alone, so that the bound holds.
  report.pulled_alone = seeds.size();
  for (std::uint32_t i : seeds) {
    positions[i] = pulled_back(positions[i], nearest[i], bound(nearest[i]), diagonal);
    nearest[i] = locate(positions[i], nearest[i].face);
  }
  for (std::size_t i = 0; i < nv; ++i) {
    if (positions[i] == start[i]) continue;
    ++report.moved;
    report.max_move = std::max(report.max_move, distance(positions[i], start[i]));
  }
  return report;
}

}  // namespace stlrefine::primitives
