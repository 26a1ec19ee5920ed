// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/smooth_pull.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
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
  if (!(unturn_degrees > 0 && unturn_degrees <= 90))
    throw Error(ErrorCode::InvalidParameter, "pull_unturn_degrees",
                "pull unturn angle must be in (0, 90] degrees");
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
// Faces per reachable vertex the unturn phase checks at most (six around each moved vertex,
// and the pull moves a third of the vertices it may reach at most: 5,700 of a 13,500 cap on
// a hull refined 6 steps; past this the faces are not checked).
constexpr std::size_t kFacesPerVertex = 3;
// A face the unturn phase checks: its normal before the pull, and whether it is queued.
struct Checked {
  Vec3 before;
  bool queued = false;
  std::uint8_t fixes = 0;
};
// Times one face is set right at most: two faces that share a corner and want it in two
// places would set each other right and turn each other again for ever.
constexpr std::uint8_t kFixesPerFace = 32;
// Bytes per reachable vertex, the larger of the two phases. The pull: its Reached, its index
// entry (a hash node and its bucket, with the allocator's overhead), the heap entries (in a
// vector that may double), the lists of reached and seed vertices (likewise). The unturn
// phase (the pull's state freed): its start (a hash node) and its faces' entries (a hash
// node and a queue slot, in a vector that may double, each); its start is made while the
// pull's Reached and index are still held.
constexpr std::uint64_t kPullBytes =
    sizeof(Reached) + 48 + 2 * kPushesPerVertex * sizeof(std::pair<double, std::uint32_t>) +
    2 * 2 * sizeof(std::uint32_t);
constexpr std::uint64_t kUnturnBytes =
    std::max<std::uint64_t>(sizeof(Reached) + 48,
                            kFacesPerVertex*(sizeof(Checked) + 48 + 2 * sizeof(std::uint32_t))) +
    sizeof(Vec3) + 48;
constexpr std::uint64_t kBytesPerReachable = std::max(kPullBytes, kUnturnBytes);

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

// The cosine between triangle p's normal and the unit `reference`; -2 without a normal.
double cosine_to(const std::array<Vec3, 3>& p, const Vec3& reference) {
  const Vec3 n = cross(p[1] - p[0], p[2] - p[0]);
  const double len = norm(n);
  return len > 0 ? dot(n, reference) / len : -2;
}

// The unturn phase (see smooth_pull): `start` holds where every moved vertex was before the
// pull, and gets the vertices this moves. Returns the faces set right and those left turned.
std::pair<std::size_t, std::size_t> unturn(
    Mesh& mesh, const std::vector<std::uint8_t>& movable, std::vector<Nearest>& nearest,
    std::unordered_map<std::uint32_t, Vec3>& start,
    const std::function<double(const Nearest& at)>& bound,
    const std::function<Nearest(const Vec3& p, std::uint32_t hint)>& locate, std::size_t cap,
    double degrees) {
  BigVector<Vec3>& positions = mesh.mutable_positions();
  const double cos_ok = std::cos(degrees * std::numbers::pi / 180);
  // A face set right is turned at most half as far: set just to the limit, the next move of
  // a neighbour's corner turned it again and the fixes chased each other over a region.
  const double cos_set = std::cos(0.5 * degrees * std::numbers::pi / 180);
  auto before = [&](std::uint32_t v) {
    const auto it = start.find(v);
    return it == start.end() ? positions[v] : it->second;
  };
  std::unordered_map<std::uint32_t, Checked> checked;
  std::vector<std::uint32_t> queue;
  auto enqueue_faces = [&](std::uint32_t v) {
    for_each_outgoing(mesh, VertexId(v), [&](HalfedgeId h) {
      const std::uint32_t f = Mesh::face(h).idx;
      auto it = checked.find(f);
      if (it == checked.end()) {
        if (checked.size() >= kFacesPerVertex * cap) return;
        const auto vs = mesh.face_vertices(FaceId(f));
        const Vec3 n =
            cross(before(vs[1].idx) - before(vs[0].idx), before(vs[2].idx) - before(vs[0].idx));
        it = checked.emplace(f, Checked{norm(n) > 0 ? normalized(n) : Vec3{}, false}).first;
      }
      if (it->second.queued || it->second.before == Vec3{}) return;
      it->second.queued = true;
      queue.push_back(f);
    });
  };
  for (const auto& [v, at] : start)
    if (!(positions[v] == at)) enqueue_faces(v);
  // Each fix moves a few vertices and checks their faces again; this caps the work where
  // fixes chase each other over a region (kFixesPerFace caps it per face).
  std::size_t budget = 4 * queue.size() + 64;
  std::size_t fixed = 0;
  while (!queue.empty() && budget > 0) {
    const std::uint32_t f = queue.back();
    queue.pop_back();
    Checked& face = checked.at(f);
    face.queued = false;
    const auto vs = mesh.face_vertices(FaceId(f));
    const std::array<Vec3, 3> p{positions[vs[0].idx], positions[vs[1].idx], positions[vs[2].idx]};
    if (cosine_to(p, face.before) >= cos_ok || face.fixes >= kFixesPerFace) continue;
    // Ways to set a face right, tried in this order, the first where the bound holds taken
    // (each the least fraction of its way that sets the face right):
    // - a corner's move applied to the other corners (those that may move): a translation of
    //   the face as it was; the farthest pulled corner's first (a further pull), the others'
    //   after (an input vertex's is none);
    // - a corner moved onto the plane through the other two that is nearest the face's
    //   normal before: the face gets that plane's normal;
    // - in that plane, towards the other two's edge, then towards the one of them nearer the
    //   input (nearer the input there, when their corners are input vertices: a corner
    //   pulled back must not stay where it was); short of it, so that the face keeps its side.
    std::array<bool, 3> may_move{};
    std::array<Vec3, 3> moved{}, onto{}, foot{}, end{};
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t v = vs[k].idx;
      may_move[k] = movable[v] && (start.count(v) || start.size() < cap);
      moved[k] = p[k] - before(v);
      const Vec3 &u = p[(k + 1) % 3], &w = p[(k + 2) % 3];
      const double len = distance(u, w);
      onto[k] = foot[k] = end[k] = p[k];
      if (!(len > 0)) continue;
      const Vec3 t = (w - u) * (1.0 / len);
      const Vec3 n = face.before - t * dot(face.before, t);
      if (norm(n) > 0) onto[k] = p[k] - normalized(n) * dot(p[k] - u, normalized(n));
      foot[k] = onto[k] + (u + t * dot(onto[k] - u, t) - onto[k]) * 0.9;
      const bool u_nearer =
          nearest[vs[(k + 1) % 3].idx].distance < nearest[vs[(k + 2) % 3].idx].distance;
      end[k] = onto[k] + ((u_nearer ? u : w) - onto[k]) * 0.9;
    }
    std::array<std::size_t, 3> order{0, 1, 2};
    std::sort(order.begin(), order.end(),
              [&](std::size_t i, std::size_t j) { return norm(moved[i]) > norm(moved[j]); });
    std::array<Vec3, 3> q = p;
    std::array<Nearest, 3> at;
    auto holds = [&](const std::array<Vec3, 3>& r) {
      for (std::size_t k = 0; k < 3; ++k) {
        at[k] = nearest[vs[k].idx];
        if (r[k] == p[k]) continue;
        at[k] = locate(r[k], at[k].face);
        if (at[k].distance > bound(at[k])) return false;
      }
      return true;
    };
    bool set_right = false;
    for (std::size_t way = 0; way < 12 && !set_right; ++way) {
      const std::size_t c = order[way % 3];
      if (way >= 3 && !may_move[c]) continue;
      auto towards = [&](double lambda) {
        std::array<Vec3, 3> r = p;
        if (way < 3) {
          for (std::size_t k = 0; k < 3; ++k)
            if (may_move[k] && k != c) r[k] = p[k] + (moved[c] - moved[k]) * lambda;
        } else if (way < 6) {
          r[c] = p[c] + (onto[c] - p[c]) * lambda;
        } else {
          r[c] = onto[c] + ((way < 9 ? foot[c] : end[c]) - onto[c]) * lambda;
        }
        return r;
      };
      if (way >= 6) {
        // Every point of the way keeps the plane's normal: the least fraction where the
        // bound holds (bisection on the bound, a few steps: each locates the corner).
        if (cosine_to(towards(0), face.before) < cos_set || !holds(towards(1))) continue;
        double lo = 0, hi = 1;
        for (int i = 0; i < 8; ++i) {
          const double mid = 0.5 * (lo + hi);
          (holds(towards(mid)) ? hi : lo) = mid;
        }
        q = towards(hi);
        set_right = holds(q);
        continue;
      }
      if (cosine_to(towards(1), face.before) < cos_set) continue;
      // Bisection (the cosine is not monotone in the fraction: this finds one that does).
      double lo = 0, hi = 1;
      for (int i = 0; i < 30; ++i) {
        const double mid = 0.5 * (lo + hi);
        (cosine_to(towards(mid), face.before) >= cos_set ? hi : lo) = mid;
      }
      q = towards(hi);
      set_right = holds(q);
    }
    if (!set_right) continue;  // counted below
    --budget;
    ++fixed;
    ++face.fixes;
    for (std::size_t k = 0; k < 3; ++k) {
      if (q[k] == p[k]) continue;
      const std::uint32_t v = vs[k].idx;
      start.emplace(v, p[k]);  // kept when it moved before
      positions[v] = q[k];
      nearest[v] = at[k];
      enqueue_faces(v);
    }
  }
  std::size_t left = 0;
  for (const auto& [f, face] : checked) {
    if (face.before == Vec3{}) continue;
    const auto vs = mesh.face_vertices(FaceId(f));
    left += cosine_to({positions[vs[0].idx], positions[vs[1].idx], positions[vs[2].idx]},
                      face.before) < cos_ok;
  }
  return {fixed, left};
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
  // Where each moved vertex started, for the unturn phase and the report.
  std::unordered_map<std::uint32_t, Vec3> start;
  start.reserve(std::min(cap, index.size() + seeds.size()));
  for (const auto& [v, at] : index)
    if (!(positions[v] == reached[at].start)) start.emplace(v, reached[at].start);
  for (std::uint32_t i : seeds) {
    const Vec3 was = positions[i];
    if (start.size() < cap) start.emplace(i, was);
    positions[i] = pulled_back(positions[i], nearest[i], bound(nearest[i]), diagonal);
    nearest[i] = locate(positions[i], nearest[i].face);
    if (start.count(i)) continue;  // counted below, from its start
    ++report.moved;
    report.max_move = std::max(report.max_move, distance(positions[i], was));
  }
  // The pull's state is done with.
  std::unordered_map<std::uint32_t, std::uint32_t>().swap(index);
  std::vector<Reached>().swap(reached);
  if (seeds.size() <= cap) {
    const auto [fixed, left] =
        unturn(mesh, movable, nearest, start, bound, locate, cap, params.unturn_degrees);
    report.unturned = fixed;
    report.still_turned = left;
    // unturn keeps every vertex it moves within its bound; this only makes sure of it.
    for (const auto& [v, at] : start)
      if (past(v)) {
        positions[v] = pulled_back(positions[v], nearest[v], bound(nearest[v]), diagonal);
        nearest[v] = locate(positions[v], nearest[v].face);
      }
  }
  for (const auto& [v, at] : start) {
    if (positions[v] == at) continue;
    ++report.moved;
    report.max_move = std::max(report.max_move, distance(positions[v], at));
  }
  return report;
}

}  // namespace stlrefine::primitives
