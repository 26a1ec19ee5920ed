// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/smooth_pull.h"

#include <algorithm>
#include <cmath>
#include <queue>
#include <string>
#include <unordered_map>
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

namespace {

// One vertex the pull has reached: where it started (for the report), and this round's pull.
struct Reached {
  Vec3 start;
  Vec3 pull;
  double reach = 0;  // this round's pull length (0: not reached this round)
};

// Heap entries allowed per reachable vertex (Dijkstra with lazy deletion pushes a vertex
// again each time a larger pull reaches it; past the allowance the sheet stops spreading).
constexpr std::size_t kPushesPerVertex = 4;
// Bytes per reachable vertex: its Reached, its index entry (a hash node and its bucket, with
// the allocator's overhead), the heap entries (in a vector that may double), the lists of
// reached and seed vertices (likewise).
constexpr std::uint64_t kBytesPerReachable =
    sizeof(Reached) + 48 + 2 * kPushesPerVertex * sizeof(std::pair<double, std::uint32_t>) +
    2 * 2 * sizeof(std::uint32_t);

}  // namespace

std::size_t smooth_pull_reach_cap(std::uint64_t vertices) {
  return static_cast<std::size_t>(
      std::min<std::uint64_t>(vertices, std::max<std::uint64_t>(4096, vertices / 16)));
}

std::uint64_t smooth_pull_bytes(std::uint64_t vertices) {
  return kBytesPerReachable * smooth_pull_reach_cap(vertices);
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

  // The vertices reached, sparse: a bound deviates in a few places (645 of the bunny's
  // 280k output vertices at 2 levels), and the state stays within smooth_pull_bytes: at most
  // `cap` vertices are reached; past that, or when the violators alone are more, the rest
  // are pulled alone below.
  const std::size_t cap = smooth_pull_reach_cap(nv);
  std::unordered_map<std::uint32_t, std::uint32_t> index;
  std::vector<Reached> reached;
  if (seeds.size() <= cap) {
    index.reserve(cap);
    reached.reserve(cap);
  }
  auto slot = [&](std::uint32_t v) -> Reached* {
    if (const auto it = index.find(v); it != index.end()) return &reached[it->second];
    if (reached.size() >= cap) return nullptr;
    index.emplace(v, static_cast<std::uint32_t>(reached.size()));
    reached.push_back({positions[v], Vec3{}, 0.0});
    return &reached.back();
  };
  std::vector<std::uint32_t> touched;
  // Violators the cap left out of a round: pulled alone at the end.
  std::vector<std::uint32_t> stranded;
  while (!seeds.empty() && seeds.size() <= cap && report.rounds < params.rounds) {
    ++report.rounds;
    // The largest cone a - slope * s over the pulled vertices, s along the edges (Dijkstra
    // from the largest pulls down): every edge changes its pull by at most slope times its
    // length, so the surface moves as a sheet, not as spikes.
    std::priority_queue<std::pair<double, std::uint32_t>> heap;
    std::size_t pushes = 0;
    for (std::uint32_t i : seeds) {
      Reached* r = slot(i);
      if (!r) {
        stranded.push_back(i);
        continue;
      }
      r->pull = pulled_back(positions[i], nearest[i], bound(nearest[i]), diagonal) - positions[i];
      r->reach = norm(r->pull);
      if (!(r->reach > 0)) continue;
      touched.push_back(i);
      heap.emplace(r->reach, i);
      ++pushes;
    }
    while (!heap.empty()) {
      // Not a structured binding: clang 14 (the asan preset) cannot capture one.
      const double r = heap.top().first;
      const std::uint32_t j = heap.top().second;
      heap.pop();
      const Reached& from = reached[index.at(j)];
      if (r < from.reach) continue;  // reached farther by another pulled vertex since
      const Vec3 direction = from.pull * (1.0 / r);
      const Vec3 at = positions[j];
      for_each_outgoing(mesh, VertexId(j), [&](HalfedgeId h) {
        const std::uint32_t k = mesh.to(h).idx;
        if (!movable[k] || pushes >= kPushesPerVertex * cap) return;
        const double next = r - params.slope * distance(at, positions[k]);
        if (next <= 0) return;
        Reached* to = slot(k);
        if (!to || next <= to->reach) return;
        if (to->reach == 0) touched.push_back(k);
        to->reach = next;
        to->pull = direction * next;
        heap.emplace(next, k);
        ++pushes;
      });
    }
    parallel_for_each_range(touched.size(), [&](std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t != end; ++t) {
        const std::uint32_t k = touched[t];
        Reached& r = reached[index.find(k)->second];
        positions[k] = positions[k] + r.pull;
        nearest[k] = locate(positions[k], nearest[k].face);
        r.reach = 0;
        r.pull = Vec3{};
      }
    });
    seeds.clear();
    for (std::uint32_t k : touched)
      if (past(k)) seeds.push_back(k);
    touched.clear();
  }
  // Past the rounds (or the cap): pulled alone, so that the bound holds.
  seeds.insert(seeds.end(), stranded.begin(), stranded.end());
  report.pulled_alone = seeds.size();
  for (std::uint32_t i : seeds) {
    const Vec3 before = positions[i];
    positions[i] = pulled_back(positions[i], nearest[i], bound(nearest[i]), diagonal);
    nearest[i] = locate(positions[i], nearest[i].face);
    if (index.count(i)) continue;  // counted below, from its start
    ++report.moved;
    report.max_move = std::max(report.max_move, distance(positions[i], before));
  }
  for (const auto& [v, at] : index) {
    if (positions[v] == reached[at].start) continue;
    ++report.moved;
    report.max_move = std::max(report.max_move, distance(positions[v], reached[at].start));
  }
  return report;
}

}  // namespace stlrefine::primitives
