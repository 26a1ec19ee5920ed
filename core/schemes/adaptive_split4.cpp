// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/adaptive_split4.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "core/error.h"
#include "core/parallel.h"

namespace stlrefine {

namespace {

constexpr std::uint32_t kNoVertex = std::numeric_limits<std::uint32_t>::max();

std::uint64_t vertex_pair(std::uint32_t a, std::uint32_t b) {
  const std::uint64_t lo = std::min(a, b), hi = std::max(a, b);
  return (hi << 32) | lo;
}

// Coarse vertices then one candidate point per edge (V + e), fold-guarded like the uniform
// host, so an adaptive step places exactly the points a uniform step would.
BigVector<Vec3> candidate_points(const Level& level, const Split4Stencil& stencil,
                                 StepStats& stats) {
  const Mesh& m = level.mesh;
  const std::size_t nv = m.num_vertices();
  BigVector<Vec3> pos(nv + m.num_edges());
  stencil.vertex_points(level, std::span<Vec3>(pos.data(), nv));
  stencil.edge_points(level, std::span<Vec3>(pos.data() + nv, m.num_edges()));
  stats.fold_fallbacks += guard_folds(m, level.features, pos);
  return pos;
}

std::vector<std::uint8_t> over_tolerance(const Level& level, const BigVector<Vec3>& pos,
                                         double tolerance, double angle_deg) {
  const Mesh& m = level.mesh;
  const std::size_t nv = m.num_vertices();
  const double cos_limit = std::cos(angle_deg * std::numbers::pi / 180.0);
  std::vector<std::uint8_t> marked(m.num_edges(), 0);
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const HalfedgeId h = m.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    const Vec3 mid = 0.5 * (pos[m.from(h).idx] + pos[m.to(h).idx]);
    bool over = tolerance > 0 && distance(pos[nv + e], mid) > tolerance;
    // The dihedral criterion of Labsik-Greiner's comparison; creases are meant to be sharp.
    const HalfedgeId t = m.twin(h);
    if (!over && angle_deg > 0 && t.valid() && !level.features.is_sharp(EdgeId(e))) {
      const Vec3 n1 = m.face_normal(Mesh::face(h)), n2 = m.face_normal(Mesh::face(t));
      const double scale = std::sqrt(dot(n1, n1) * dot(n2, n2));
      over = scale > 0 && dot(n1, n2) < cos_limit * scale;
    }
    marked[e] = over;
  });
  return marked;
}

// A mesh from oriented triangles whose vertex ids must be kept (ingest would renumber):
// twins are the reversed directed edges.
Mesh assemble(const std::vector<Vec3>& points,
              const std::vector<std::array<std::uint32_t, 3>>& tris) {
  BigVector<Vec3> positions(points.size());
  std::copy(points.begin(), points.end(), positions.begin());
  BigVector<VertexId> corner_vertex(3 * tris.size());
  for (std::size_t t = 0; t < tris.size(); ++t)
    for (std::size_t k = 0; k < 3; ++k) corner_vertex[3 * t + k] = VertexId(tris[t][k]);
  auto directed_key = [&](std::uint32_t h) {
    return (static_cast<std::uint64_t>(corner_vertex[h].idx) << 32) |
           corner_vertex[Mesh::next(HalfedgeId(h)).idx].idx;
  };
  std::unordered_map<std::uint64_t, std::uint32_t> directed;
  directed.reserve(corner_vertex.size());
  for (std::uint32_t h = 0; h < corner_vertex.size(); ++h)
    if (!directed.emplace(directed_key(h), h).second)
      throw Error(ErrorCode::Internal, "adaptive_topology",
                  "adaptive refinement produced a repeated directed edge");
  BigVector<HalfedgeId> twin(corner_vertex.size());
  for (std::uint32_t h = 0; h < corner_vertex.size(); ++h) {
    const std::uint64_t key = directed_key(h);
    const auto it = directed.find((key << 32) | (key >> 32));
    if (it != directed.end()) twin[h] = HalfedgeId(it->second);
  }
  return Mesh::from_parts(std::move(positions), std::move(corner_vertex), std::move(twin));
}

}  // namespace

std::size_t count_edges_over_tolerance(const Level& level, const Split4Stencil& stencil,
                                       double tolerance, double angle_deg) {
  StepStats ignored;
  const auto marked =
      over_tolerance(level, candidate_points(level, stencil, ignored), tolerance, angle_deg);
  return static_cast<std::size_t>(std::count(marked.begin(), marked.end(), 1));
}

AdaptiveSplit4::AdaptiveSplit4(const Level& coarse) {
  const Mesh& m = coarse.mesh;
  positions_.assign(m.positions().begin(), m.positions().end());
  red_.resize(m.num_faces());
  for (std::uint32_t f = 0; f < m.num_faces(); ++f)
    for (std::uint32_t k = 0; k < 3; ++k) red_[f][k] = m.from(HalfedgeId(3 * f + k)).idx;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    if (!coarse.features.is_sharp(EdgeId(e))) continue;
    const HalfedgeId h = m.halfedge(EdgeId(e));
    sharp_.insert(vertex_pair(m.from(h).idx, m.to(h).idx));
  }
  build_level();
}

std::uint32_t AdaptiveSplit4::midpoint(std::uint32_t a, std::uint32_t b) const {
  const auto it = midpoint_.find(vertex_pair(a, b));
  return it == midpoint_.end() ? kNoVertex : it->second;
}

void AdaptiveSplit4::build_level() {
  std::vector<Triangle> tris;
  tris.reserve(red_.size() + red_.size() / 4);
  owner_.clear();
  owner_.reserve(tris.capacity());
  for (std::uint32_t f = 0; f < red_.size(); ++f) {
    const Triangle& v = red_[f];
    std::uint32_t split = 3, mid = 0;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t m = midpoint(v[k], v[(k + 1) % 3]);
      if (m != kNoVertex) split = k, mid = m;
    }
    if (split == 3) {
      tris.push_back(v);
      owner_.push_back(f);
      continue;
    }
    // Green: bisect the split edge v_k -> v_k+1 towards the opposite corner.
    const std::uint32_t a = v[split], b = v[(split + 1) % 3], c = v[(split + 2) % 3];
    tris.push_back({a, mid, c});
    tris.push_back({mid, b, c});
    owner_.insert(owner_.end(), {f, f});
  }
  level_.mesh = assemble(positions_, tris);
  const Mesh& m = level_.mesh;
  BigVector<std::uint8_t> sharp(m.num_edges());
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    sharp[e] = sharp_.count(vertex_pair(m.from(h).idx, m.to(h).idx)) != 0;
  }
  level_.features = Features(m, std::move(sharp));

  // Which half-edge of the conforming mesh is each unsplit leaf edge.
  leaf_halfedge_.assign(red_.size(), {HalfedgeId(), HalfedgeId(), HalfedgeId()});
  for (std::uint32_t t = 0; t < m.num_faces(); ++t) {
    const Triangle& v = red_[owner_[t]];
    for (std::uint32_t j = 0; j < 3; ++j) {
      const HalfedgeId h(3 * t + j);
      for (std::uint32_t k = 0; k < 3; ++k)
        if (m.from(h).idx == v[k] && m.to(h).idx == v[(k + 1) % 3])
          leaf_halfedge_[owner_[t]][k] = h;
    }
  }
}

bool AdaptiveSplit4::step(const Split4Stencil& stencil, double tolerance, std::uint64_t max_faces,
                          StepStats& stats, AdaptiveStepStats& step, double angle_deg) {
  const Mesh& m = level_.mesh;
  const std::size_t nv = m.num_vertices();
  const BigVector<Vec3> pos = candidate_points(level_, stencil, stats);
  const std::vector<std::uint8_t> marked = over_tolerance(level_, pos, tolerance, angle_deg);
  step.marked_by_tolerance = static_cast<std::size_t>(std::count(marked.begin(), marked.end(), 1));
  if (step.marked_by_tolerance == 0) return false;

  // A leaf is split red when any edge of its conforming faces is over tolerance; that
  // includes a green's bisector and the halves of a split edge (the finer neighbour
  // needs refining, which needs this leaf at its level first).
  std::vector<std::uint8_t> red(red_.size(), 0);
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h)
    if (marked[m.edge(HalfedgeId(h)).idx]) red[owner_[h / 3]] = 1;
  step.red_by_tolerance = static_cast<std::size_t>(std::count(red.begin(), red.end(), 1));

  // Closure to a fixpoint: every edge of a red leaf gets a midpoint; a leaf that would
  // then carry two hanging midpoints, or one on a half of its already split edge (a level
  // jump of two), turns red as well. Marking only grows, so this terminates.
  std::unordered_set<std::uint64_t> will_split;
  auto add_edges = [&](std::uint32_t f) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t a = red_[f][k], b = red_[f][(k + 1) % 3];
      if (midpoint(a, b) == kNoVertex) will_split.insert(vertex_pair(a, b));
    }
  };
  for (std::uint32_t f = 0; f < red_.size(); ++f)
    if (red[f]) add_edges(f);
  auto split_after = [&](std::uint32_t a, std::uint32_t b) {
    return midpoint(a, b) != kNoVertex || will_split.count(vertex_pair(a, b)) != 0;
  };
  for (bool changed = true; changed;) {
    changed = false;
    for (std::uint32_t f = 0; f < red_.size(); ++f) {
      if (red[f]) continue;
      int hanging = 0;
      bool level_jump = false;
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t a = red_[f][k], b = red_[f][(k + 1) % 3];
        hanging += split_after(a, b);
        const std::uint32_t mid = midpoint(a, b);
        if (mid != kNoVertex)
          level_jump = level_jump || will_split.count(vertex_pair(a, mid)) != 0 ||
                       will_split.count(vertex_pair(mid, b)) != 0;
      }
      if (hanging >= 2 || level_jump) {
        red[f] = 1;
        add_edges(f);
        ++step.red_by_closure;
        changed = true;
      }
    }
  }
  step.red_faces = step.red_by_tolerance + step.red_by_closure;

  // The next leaves, and their conforming face count, before anything big is built.
  std::vector<std::uint32_t> new_mid(red_.size() * 3, kNoVertex);
  std::uint32_t next_vertex = static_cast<std::uint32_t>(positions_.size());
  std::unordered_map<std::uint64_t, std::uint32_t> created;
  for (std::uint32_t f = 0; f < red_.size(); ++f) {
    if (!red[f]) continue;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t a = red_[f][k], b = red_[f][(k + 1) % 3];
      std::uint32_t mid = midpoint(a, b);
      if (mid == kNoVertex) {
        const auto [it, fresh] = created.emplace(vertex_pair(a, b), next_vertex);
        next_vertex += fresh;
        mid = it->second;
      }
      new_mid[3 * f + k] = mid;
    }
  }
  std::vector<Triangle> next;
  next.reserve(red_.size() + 3 * step.red_faces);
  for (std::uint32_t f = 0; f < red_.size(); ++f) {
    if (!red[f]) {
      next.push_back(red_[f]);
      continue;
    }
    const Triangle& v = red_[f];
    const std::uint32_t* mid = &new_mid[3 * f];
    for (std::uint32_t k = 0; k < 3; ++k) next.push_back({v[k], mid[k], mid[(k + 2) % 3]});
    next.push_back({mid[0], mid[1], mid[2]});
  }
  auto split_next = [&](std::uint32_t a, std::uint32_t b) {
    return midpoint(a, b) != kNoVertex || created.count(vertex_pair(a, b)) != 0;
  };
  std::uint64_t faces = 0;
  step.green_faces = 0;
  for (const Triangle& v : next) {
    const bool green = split_next(v[0], v[1]) || split_next(v[1], v[2]) || split_next(v[2], v[0]);
    faces += green ? 2 : 1;
    step.green_faces += green;
  }
  if (faces > max_faces) {
    throw Error(ErrorCode::BudgetExceeded, "face_budget",
                "the next adaptive level would make " + std::to_string(faces) +
                    " faces; the limit is max_faces = " + std::to_string(max_faces))
        .with_field("max_faces");
  }

  // Commit: new vertices at the stencil's edge points, halves of sharp edges stay sharp.
  positions_.resize(next_vertex);
  for (std::uint32_t f = 0; f < red_.size(); ++f) {
    if (!red[f]) continue;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t a = red_[f][k], b = red_[f][(k + 1) % 3];
      const std::uint64_t key = vertex_pair(a, b);
      const auto it = created.find(key);
      if (it == created.end() || midpoint_.count(key)) continue;
      const HalfedgeId h = leaf_halfedge_[f][k];
      positions_[it->second] = pos[nv + m.edge(h).idx];
      midpoint_.emplace(key, it->second);
      if (sharp_.count(key)) {
        sharp_.insert(vertex_pair(a, it->second));
        sharp_.insert(vertex_pair(it->second, b));
      }
    }
  }
  red_ = std::move(next);
  build_level();
  return true;
}

}  // namespace stlrefine
