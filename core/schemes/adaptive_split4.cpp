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
  edges_.resize(m.num_edges());
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    edges_[e].v = {m.from(h).idx, m.to(h).idx};
    edges_[e].sharp = coarse.features.is_sharp(EdgeId(e));
  }
  leaves_.resize(m.num_faces());
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const HalfedgeId h(3 * f + k);
      leaves_[f].v[k] = m.from(h).idx;
      leaves_[f].e[k] = m.edge(h).idx;
    }
  }
  build_level();
}

std::uint32_t AdaptiveSplit4::add_edge(std::uint32_t a, std::uint32_t b, bool sharp,
                                       std::uint32_t parent) {
  Edge edge;
  edge.v = {a, b};
  edge.sharp = sharp;
  edge.parent = parent;
  edges_.push_back(edge);
  return static_cast<std::uint32_t>(edges_.size() - 1);
}

void AdaptiveSplit4::build_level() {
  // Conforming triangles, each side known by an edge key: an entry of edges_, or
  // edges_.size() + g for the bisector of the g-th green leaf.
  const std::uint32_t num_edges = static_cast<std::uint32_t>(edges_.size());
  BigVector<VertexId> corner_vertex;
  std::vector<std::uint32_t> key;
  corner_vertex.reserve(3 * (leaves_.size() + leaves_.size() / 4));
  key.reserve(corner_vertex.capacity());
  owner_.clear();
  owner_.reserve(corner_vertex.capacity() / 3);
  leaf_halfedge_.assign(leaves_.size(), {HalfedgeId(), HalfedgeId(), HalfedgeId()});
  std::uint32_t greens = 0;
  auto add_triangle = [&](std::uint32_t leaf, std::array<std::uint32_t, 3> v,
                          std::array<std::uint32_t, 3> keys) {
    for (int j = 0; j < 3; ++j) corner_vertex.push_back(VertexId(v[j])), key.push_back(keys[j]);
    owner_.push_back(leaf);
  };
  for (std::uint32_t f = 0; f < leaves_.size(); ++f) {
    const Leaf& leaf = leaves_[f];
    std::uint32_t split = 3;
    for (std::uint32_t k = 0; k < 3; ++k) {
      if (edges_[leaf.e[k]].mid == kNone) continue;
      if (split != 3)
        throw Error(ErrorCode::Internal, "adaptive_topology",
                    "adaptive refinement left two hanging midpoints on one triangle");
      split = k;
    }
    const std::uint32_t first = static_cast<std::uint32_t>(key.size());
    if (split == 3) {
      add_triangle(f, leaf.v, leaf.e);
      for (std::uint32_t k = 0; k < 3; ++k) leaf_halfedge_[f][k] = HalfedgeId(first + k);
      continue;
    }
    // Green: bisect the split edge v_k -> v_k+1 towards the opposite corner.
    const std::uint32_t k1 = (split + 1) % 3, k2 = (split + 2) % 3;
    const std::uint32_t a = leaf.v[split], b = leaf.v[k1], c = leaf.v[k2];
    const std::uint32_t split_edge = leaf.e[split], mid = edges_[split_edge].mid;
    const std::array<std::uint32_t, 2> halves = edges_[split_edge].half;
    if (edges_[halves[0]].mid != kNone || edges_[halves[1]].mid != kNone)
      throw Error(ErrorCode::Internal, "adaptive_topology",
                  "adaptive refinement left a level jump of two across an edge");
    const std::uint32_t bisector = num_edges + greens++;
    add_triangle(f, {a, mid, c}, {half_at(split_edge, a), bisector, leaf.e[k2]});
    add_triangle(f, {mid, b, c}, {half_at(split_edge, b), leaf.e[k1], bisector});
    leaf_halfedge_[f][k2] = HalfedgeId(first + 2);
    leaf_halfedge_[f][k1] = HalfedgeId(first + 4);
  }

  // Twins: the two half-edges with the same key.
  BigVector<HalfedgeId> twin(key.size());
  std::vector<HalfedgeId> first_of(num_edges + greens);
  for (std::uint32_t h = 0; h < key.size(); ++h) {
    HalfedgeId& other = first_of[key[h]];
    if (!other.valid()) {
      other = HalfedgeId(h);
      continue;
    }
    const VertexId from = corner_vertex[h], to = corner_vertex[Mesh::next(HalfedgeId(h)).idx];
    if (twin[other.idx].valid() || corner_vertex[other.idx] != to ||
        corner_vertex[Mesh::next(other).idx] != from)
      throw Error(ErrorCode::Internal, "adaptive_topology",
                  "adaptive refinement produced an edge that is not shared by two opposite "
                  "half-edges");
    twin[h] = other;
    twin[other.idx] = HalfedgeId(h);
  }
  BigVector<Vec3> positions(positions_.size());
  std::copy(positions_.begin(), positions_.end(), positions.begin());
  level_.mesh = Mesh::from_parts(std::move(positions), std::move(corner_vertex), std::move(twin));
  const Mesh& m = level_.mesh;
  BigVector<std::uint8_t> sharp(m.num_edges());  // BigVector does not zero its elements
  for (std::uint32_t h = 0; h < key.size(); ++h)
    sharp[m.edge(HalfedgeId(h)).idx] = key[h] < num_edges && edges_[key[h]].sharp;
  level_.features = Features(m, std::move(sharp));
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
  std::vector<std::uint8_t> red(leaves_.size(), 0);
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h)
    if (marked[m.edge(HalfedgeId(h)).idx]) red[owner_[h / 3]] = 1;
  step.red_by_tolerance = static_cast<std::size_t>(std::count(red.begin(), red.end(), 1));

  // Closure: every edge of a red leaf gets a midpoint; a leaf that would then carry two
  // hanging midpoints, or one on a half of its already split edge (a level jump of two),
  // turns red as well. A worklist holds the leaves next to edges that just got marked:
  // those on the edge, and those on the edge it is a half of.
  std::vector<std::array<std::uint32_t, 2>> leaves_of(edges_.size(), {kNone, kNone});
  for (std::uint32_t f = 0; f < leaves_.size(); ++f)
    for (const std::uint32_t e : leaves_[f].e) leaves_of[e][leaves_of[e][0] == kNone ? 0 : 1] = f;
  std::vector<std::uint8_t> will_split(edges_.size(), 0);
  std::vector<std::uint32_t> todo;
  auto mark_edges = [&](std::uint32_t f) {
    for (const std::uint32_t e : leaves_[f].e) {
      if (edges_[e].mid != kNone || will_split[e]) continue;
      will_split[e] = 1;
      for (const std::uint32_t g : leaves_of[e])
        if (g != kNone && !red[g]) todo.push_back(g);
      if (edges_[e].parent != kNone)
        for (const std::uint32_t g : leaves_of[edges_[e].parent])
          if (g != kNone && !red[g]) todo.push_back(g);
    }
  };
  auto split_after = [&](std::uint32_t e) { return edges_[e].mid != kNone || will_split[e]; };
  for (std::uint32_t f = 0; f < leaves_.size(); ++f)
    if (red[f]) mark_edges(f);
  while (!todo.empty()) {
    const std::uint32_t f = todo.back();
    todo.pop_back();
    if (red[f]) continue;
    int hanging = 0;
    bool level_jump = false;
    for (const std::uint32_t e : leaves_[f].e) {
      hanging += split_after(e);
      if (edges_[e].mid != kNone)
        level_jump = level_jump || will_split[edges_[e].half[0]] || will_split[edges_[e].half[1]];
    }
    if (hanging >= 2 || level_jump) {
      red[f] = 1;
      ++step.red_by_closure;
      mark_edges(f);
    }
  }
  step.red_faces = step.red_by_tolerance + step.red_by_closure;

  // The conforming face count of the next level, before anything is changed. A kept leaf
  // is green when one of its edges is split; of a red leaf's four children only a corner
  // child can be, when its half of an edge that was already split is split now.
  std::uint64_t faces = 0;
  step.green_faces = 0;
  auto count = [&](bool green) {
    faces += green ? 2 : 1;
    step.green_faces += green;
  };
  for (std::uint32_t f = 0; f < leaves_.size(); ++f) {
    const Leaf& leaf = leaves_[f];
    if (!red[f]) {
      count(split_after(leaf.e[0]) || split_after(leaf.e[1]) || split_after(leaf.e[2]));
      continue;
    }
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t before = leaf.e[(k + 2) % 3], after = leaf.e[k];
      const bool green = (edges_[after].mid != kNone && will_split[half_at(after, leaf.v[k])]) ||
                         (edges_[before].mid != kNone && will_split[half_at(before, leaf.v[k])]);
      count(green);
    }
    count(false);  // the middle child
  }
  if (faces > max_faces) {
    throw Error(ErrorCode::BudgetExceeded, "face_budget",
                "the next adaptive level would make " + std::to_string(faces) +
                    " faces; the limit is max_faces = " + std::to_string(max_faces))
        .with_field("max_faces");
  }

  // Commit. New vertices at the stencil's edge points; halves of sharp edges stay sharp.
  for (std::uint32_t f = 0; f < leaves_.size(); ++f) {
    if (!red[f]) continue;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t e = leaves_[f].e[k];
      if (edges_[e].mid != kNone) continue;
      const std::uint32_t mid = static_cast<std::uint32_t>(positions_.size());
      positions_.push_back(pos[nv + m.edge(leaf_halfedge_[f][k]).idx]);
      const auto [a, b] = edges_[e].v;
      const bool sharp = edges_[e].sharp;
      const std::uint32_t first = add_edge(a, mid, sharp, e);
      const std::uint32_t second = add_edge(mid, b, sharp, e);
      edges_[e].mid = mid;
      edges_[e].half = {first, second};
    }
  }
  std::vector<Leaf> next;
  next.reserve(leaves_.size() + 3 * step.red_faces);
  for (std::uint32_t f = 0; f < leaves_.size(); ++f) {
    const Leaf& leaf = leaves_[f];
    if (!red[f]) {
      next.push_back(leaf);
      continue;
    }
    std::array<std::uint32_t, 3> mid, inner;
    for (std::uint32_t k = 0; k < 3; ++k) mid[k] = edges_[leaf.e[k]].mid;
    // Inner edge k joins mid_k and mid_k-1, opposite corner k.
    for (std::uint32_t k = 0; k < 3; ++k)
      inner[k] = add_edge(mid[k], mid[(k + 2) % 3], false, kNone);
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t km1 = (k + 2) % 3;
      next.push_back({{leaf.v[k], mid[k], mid[km1]},
                      {half_at(leaf.e[k], leaf.v[k]), inner[k], half_at(leaf.e[km1], leaf.v[k])}});
    }
    next.push_back({{mid[0], mid[1], mid[2]}, {inner[1], inner[2], inner[0]}});
  }
  leaves_ = std::move(next);
  build_level();
  return true;
}

}  // namespace stlrefine
