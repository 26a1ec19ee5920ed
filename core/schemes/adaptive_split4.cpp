// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/adaptive_split4.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/refine.h"
#include "core/schemes/adaptive_split4_detail.h"

namespace stlrefine {

namespace adaptive_split4_detail {

std::uint64_t marking_bytes(const Level& level, const Split4Stencil& stencil) {
  const Mesh& m = level.mesh;
  return big_vector_bytes<Vec3>(m.num_vertices() + m.num_edges()) + stencil.scratch_bytes(level) +
         2 * std::uint64_t(m.num_edges()) + m.num_faces() + keep_dominant_planes_bytes(m);
}

}  // namespace adaptive_split4_detail

using adaptive_split4_detail::marking_bytes;

namespace {

// Coarse vertices then one candidate point per edge (V + e), through the plane rule and the
// fold guard like the uniform host. Used on the conforming mesh only (meshes that are not
// simple, and edges_over_tolerance): the guard's smooth normals are the sector normals of
// this level there, while the uniform regions (update_uniform) carry the input's as the
// uniform host does. `guard_reserve` gets the fold guard's work bytes when it needs them.
BigVector<Vec3> candidate_points(const Level& level, const Split4Stencil& stencil, StepStats& stats,
                                 const std::function<void(std::uint64_t)>& guard_reserve) {
  const Mesh& m = level.mesh;
  const std::size_t nv = m.num_vertices();
  BigVector<Vec3> pos(nv + m.num_edges());
  stencil.vertex_points(level, std::span<Vec3>(pos.data(), nv));
  stencil.edge_points(level, std::span<Vec3>(pos.data() + nv, m.num_edges()));
  keep_dominant_planes(m, level.features, pos);
  stats.fold_fallbacks += guard_folds(m, level.features, pos, guard_reserve);
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
      over = turned_past(n1, n2, cos_limit);
    }
    marked[e] = over;
  });
  return marked;
}

}  // namespace

EdgesOverTolerance edges_over_tolerance(const Level& level, const Split4Stencil& stencil,
                                        double tolerance, double angle_deg,
                                        const std::function<void(std::uint64_t)>& reserve) {
  StepStats ignored;
  const std::uint64_t marking = marking_bytes(level, stencil);
  if (reserve) reserve(marking);
  std::function<void(std::uint64_t)> guard_reserve;
  if (reserve) guard_reserve = [&](std::uint64_t work) { reserve(marking + work); };
  const BigVector<Vec3> pos = candidate_points(level, stencil, ignored, guard_reserve);
  const auto marked = over_tolerance(level, pos, tolerance, angle_deg);
  const Mesh& m = level.mesh;
  const std::size_t nv = m.num_vertices();
  EdgesOverTolerance out;
  for (std::size_t e = 0; e < marked.size(); ++e) {
    if (!marked[e]) continue;
    ++out.count;
    const HalfedgeId h = m.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    const Vec3 mid = 0.5 * (pos[m.from(h).idx] + pos[m.to(h).idx]);
    const double d = distance(pos[nv + e], mid);
    if (d > out.max_distance) {
      out.max_distance = d;
      out.worst_at = mid;
    }
  }
  return out;
}

std::size_t count_edges_over_tolerance(const Level& level, const Split4Stencil& stencil,
                                       double tolerance, double angle_deg,
                                       const std::function<void(std::uint64_t)>& reserve) {
  return edges_over_tolerance(level, stencil, tolerance, angle_deg, reserve).count;
}

AdaptiveSplit4::AdaptiveSplit4(const Level& coarse, std::function<void(std::uint64_t)> reserve)
    : reserve_(std::move(reserve)) {
  const Mesh& m = coarse.mesh;
  const std::size_t nv = m.num_vertices(), ne = m.num_edges(), nf = m.num_faces();
  need(nv * sizeof(Vec3) + ne * sizeof(Edge) + nf * sizeof(Leaf) + build_bytes(nf, 0, nf, ne, nv) +
       big_vector_bytes<Vec3>(3 * nf));  // the smooth normals of uniform_[0]
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
  // Edge points from the uniform levels need edges known by their end vertices: on a mesh
  // where two edges join the same two vertices the points come from the conforming mesh.
  // A simple mesh (no two edges on the same two vertices, no two faces on the same three)
  // has simple uniform levels.
  uniform_points_ = true;
  try {
    require_simple_mesh(m);
  } catch (const Error&) {
    uniform_points_ = false;
  }
  if (uniform_points_) {
    UniformLevel u0;
    u0.level.mesh = coarse.mesh;
    u0.level.features = coarse.features;
    // The smooth surface's normals the fold guard holds children to, estimated once on the
    // input and carried to every uniform level, as the uniform host does (issue 17 item 2).
    u0.level.smooth_normals = coarse.smooth_normals.size() == 3 * nf
                                  ? coarse.smooth_normals
                                  : sector_normals(coarse.mesh, coarse.features);
    u0.hierarchy_vertex.resize(nv);
    for (std::uint32_t v = 0; v < nv; ++v) u0.hierarchy_vertex[v] = v;
    u0.trusted.assign(nv, 1);
    u0.cut.assign(ne, 0);
    uniform_.push_back(std::move(u0));
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

std::uint64_t AdaptiveSplit4::held_bytes() const {
  return positions_.capacity() * sizeof(Vec3) + edges_.capacity() * sizeof(Edge) +
         leaves_.capacity() * sizeof(Leaf) + owner_.capacity() * sizeof(std::uint32_t) +
         leaf_halfedge_.capacity() * sizeof(leaf_halfedge_[0]) + level_bytes(level_) +
         uniform_bytes();
}

std::uint64_t AdaptiveSplit4::build_bytes(std::uint64_t faces, std::uint64_t greens,
                                          std::uint64_t leaves, std::uint64_t edges,
                                          std::uint64_t vertices) const {
  const std::size_t h = 3 * faces, v = vertices;
  // Mesh::from_parts reserves edge_halfedge for h / 2 + 1 edges and doubles it when the
  // boundary makes more: both buffers at once.
  const std::size_t edge_reserve = h / 2 + 1;
  return big_vector_bytes<VertexId>(h) + h * sizeof(std::uint32_t) +  // corners, keys
         (faces > owner_.capacity() ? faces * sizeof(std::uint32_t) : 0) +
         (leaves > leaf_halfedge_.capacity() ? leaves * sizeof(leaf_halfedge_[0]) : 0) +
         big_vector_bytes<HalfedgeId>(h) + (edges + greens) * sizeof(HalfedgeId) +  // twins
         big_vector_bytes<Vec3>(v) + big_vector_bytes<EdgeId>(h) +
         big_vector_bytes<HalfedgeId>(edge_reserve) +
         big_vector_bytes<HalfedgeId>(2 * edge_reserve) + big_vector_bytes<HalfedgeId>(v) +
         big_vector_bytes<std::uint8_t>(h) + big_vector_bytes<VertexKind>(v) +
         big_vector_bytes<std::array<VertexId, 2>>(v);
}

void AdaptiveSplit4::build_level() {
  // Conforming triangles, each side known by an edge key: an entry of edges_, or
  // edges_.size() + g for the bisector of the g-th green leaf.
  const std::uint32_t num_edges = static_cast<std::uint32_t>(edges_.size());
  std::size_t faces = leaves_.size();  // exactly: a green leaf makes two
  for (const Leaf& leaf : leaves_)
    for (const std::uint32_t e : leaf.e) faces += edges_[e].mid != kNone;
  BigVector<VertexId> corner_vertex;
  std::vector<std::uint32_t> key;
  corner_vertex.reserve(3 * faces);
  key.reserve(3 * faces);
  owner_.clear();
  owner_.reserve(faces);
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

namespace {

// The most a green half may turn from its leaf. A half of a well-shaped leaf turns by about
// the split point's height over the leaf's height; past this it is a sliver bent over.
constexpr double kGreenTurnDeg = 60;

Error face_budget_error(const char* bound, std::uint64_t faces, std::uint64_t max_faces) {
  return Error(ErrorCode::BudgetExceeded, "face_budget",
               std::string("the next adaptive level would make ") + bound + std::to_string(faces) +
                   " faces; the limit is max_faces = " + std::to_string(max_faces))
      .with_field("max_faces");
}

template <class T>
void free_array(T& array) {
  T().swap(array);
}

}  // namespace

bool AdaptiveSplit4::green_turns(std::uint32_t leaf, std::uint32_t k, const Vec3& p) const {
  const Leaf& l = leaves_[leaf];
  const Vec3 &a = positions_[l.v[k]], &b = positions_[l.v[(k + 1) % 3]],
             &c = positions_[l.v[(k + 2) % 3]];
  const Vec3 n = triangle_normal(a, b, c);
  const double cos_limit = std::cos(kGreenTurnDeg * std::numbers::pi / 180.0);
  return turned_past(n, triangle_normal(a, p, c), cos_limit) ||
         turned_past(n, triangle_normal(p, b, c), cos_limit);
}

bool AdaptiveSplit4::step(const Split4Stencil& stencil, double tolerance, std::uint64_t max_faces,
                          StepStats& stats, AdaptiveStepStats& step, double angle_deg) {
  const Mesh& m = level_.mesh;
  const std::size_t nv = m.num_vertices();
  const std::size_t num_leaves = leaves_.size(), num_edges = edges_.size();
  BigVector<Vec3> pos;
  std::vector<std::uint8_t> marked;
  std::vector<std::uint8_t> red(num_leaves, 0);
  if (uniform_points_) {
    // Every leaf is a face of a uniform level: its edges are measured with the points
    // uniform refinement puts there (the stencil on that level, not on the conforming
    // mesh, whose green triangles and mixed levels are not what the stencil is made for),
    // so a leaf split here has the children uniform refinement gives it, and a smaller
    // tolerance marks a superset.
    update_uniform(stencil);
    const double cos_limit = std::cos(angle_deg * std::numbers::pi / 180.0);
    std::vector<std::uint8_t> seen(num_edges, 0);
    for (std::uint32_t f = 0; f < num_leaves; ++f)
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t e = leaves_[f].e[k];
        if (edges_[e].mid != kNone) continue;
        double dist = 0;
        if (!uniform_over(f, k, tolerance, cos_limit, angle_deg > 0, dist)) continue;
        red[f] = 1;
        if (!seen[e]) seen[e] = 1, ++step.marked_by_tolerance;
      }
    if (step.marked_by_tolerance == 0) return false;
  }
  const std::uint64_t held = held_bytes();
  if (!uniform_points_) {
    const std::uint64_t marking = marking_bytes(level_, stencil);
    need(held + marking);
    std::function<void(std::uint64_t)> guard_reserve;
    if (reserve_) guard_reserve = [&](std::uint64_t work) { need(held + marking + work); };
    pos = candidate_points(level_, stencil, stats, guard_reserve);
    marked = over_tolerance(level_, pos, tolerance, angle_deg);
    step.marked_by_tolerance =
        static_cast<std::size_t>(std::count(marked.begin(), marked.end(), 1));
    if (step.marked_by_tolerance == 0) return false;
  }

  const std::uint64_t points = big_vector_bytes<Vec3>(pos.capacity()) + marked.capacity();
  need(held + points + num_leaves);

  // A leaf is split red when any edge of its conforming faces is over tolerance; that
  // includes a green's bisector and the halves of a split edge (the finer neighbour
  // needs refining, which needs this leaf at its level first).
  if (!uniform_points_)
    for (std::uint32_t h = 0; h < m.num_halfedges(); ++h)
      if (marked[m.edge(HalfedgeId(h)).idx]) red[owner_[h / 3]] = 1;
  step.red_by_tolerance = static_cast<std::size_t>(std::count(red.begin(), red.end(), 1));
  // A red leaf makes at least four faces, any other at least one: over the budget already,
  // the closure need not run.
  if (const std::uint64_t at_least = num_leaves + 3 * std::uint64_t(step.red_by_tolerance);
      at_least > max_faces)
    throw face_budget_error("at least ", at_least, max_faces);
  // The closure's work arrays: a flag per leaf (red, queued), a worklist that never holds a
  // leaf twice, and per edge its leaves and whether it will be split.
  need(held + points + num_leaves * (2 + sizeof(std::uint32_t)) +
       num_edges * (1 + sizeof(std::array<std::uint32_t, 2>)));

  // Closure: every edge of a red leaf gets a midpoint; a leaf that would then carry two
  // hanging midpoints, or one on a half of its already split edge (a level jump of two), or
  // one whose green halves would turn over (green_turns), turns red as well. A worklist holds the
  // leaves next to edges that just got marked: those on the edge, and those on the edge it is a
  // half of. The rule only ever adds red leaves, so the order does not change the result, and a
  // leaf is queued once at a time.
  std::vector<std::array<std::uint32_t, 2>> leaves_of(num_edges, {kNone, kNone});
  for (std::uint32_t f = 0; f < num_leaves; ++f)
    for (const std::uint32_t e : leaves_[f].e) leaves_of[e][leaves_of[e][0] == kNone ? 0 : 1] = f;
  std::vector<std::uint8_t> will_split(num_edges, 0), queued(num_leaves, 0);
  std::vector<std::uint32_t> todo;
  todo.reserve(num_leaves);
  auto enqueue = [&](std::uint32_t g) {
    if (g == kNone || red[g] || queued[g]) return;
    queued[g] = 1;
    todo.push_back(g);
  };
  auto mark_edges = [&](std::uint32_t f) {
    for (const std::uint32_t e : leaves_[f].e) {
      if (edges_[e].mid != kNone || will_split[e]) continue;
      will_split[e] = 1;
      for (const std::uint32_t g : leaves_of[e]) enqueue(g);
      if (edges_[e].parent != kNone)
        for (const std::uint32_t g : leaves_of[edges_[e].parent]) enqueue(g);
    }
  };
  auto split_after = [&](std::uint32_t e) { return edges_[e].mid != kNone || will_split[e]; };
  // The point a split of leaf side k puts (or put) there.
  auto split_point = [&](std::uint32_t f, std::uint32_t k) {
    const std::uint32_t e = leaves_[f].e[k];
    if (edges_[e].mid != kNone) return positions_[edges_[e].mid];
    return uniform_points_ ? uniform_point(f, k) : pos[nv + m.edge(leaf_halfedge_[f][k]).idx];
  };
  for (std::uint32_t f = 0; f < num_leaves; ++f)
    if (red[f]) mark_edges(f);
  while (!todo.empty()) {
    const std::uint32_t f = todo.back();
    todo.pop_back();
    queued[f] = 0;
    if (red[f]) continue;
    int hanging = 0;
    std::uint32_t split_side = 0;
    bool level_jump = false;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t e = leaves_[f].e[k];
      if (split_after(e)) ++hanging, split_side = k;
      if (edges_[e].mid != kNone)
        level_jump = level_jump || will_split[edges_[e].half[0]] || will_split[edges_[e].half[1]];
    }
    if (hanging >= 2 || level_jump ||
        (hanging == 1 && green_turns(f, split_side, split_point(f, split_side)))) {
      red[f] = 1;
      ++step.red_by_closure;
      mark_edges(f);
    }
  }
  step.red_faces = step.red_by_tolerance + step.red_by_closure;
  free_array(leaves_of);
  free_array(queued);
  free_array(todo);

  // The conforming face count of the next level, before anything is changed. A kept leaf
  // is green when one of its edges is split; of a red leaf's four children only a corner
  // child can be, when its half of an edge that was already split is split now.
  std::uint64_t faces = 0;
  step.green_faces = 0;
  auto count = [&](bool green) {
    faces += green ? 2 : 1;
    step.green_faces += green;
  };
  for (std::uint32_t f = 0; f < num_leaves; ++f) {
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
  if (faces > max_faces) throw face_budget_error("", faces, max_faces);

  // The next level's sizes are exact now: reserve the commit (the grown arrays next to the
  // old ones while they move) and the build (after this step's work arrays are gone).
  const std::size_t midpoints =
      static_cast<std::size_t>(std::count(will_split.begin(), will_split.end(), 1));
  const std::size_t next_vertices = positions_.size() + midpoints;
  const std::size_t next_edges = num_edges + 2 * midpoints + 3 * step.red_faces;
  const std::size_t next_leaves = num_leaves + 3 * step.red_faces;
  auto grown = [](std::size_t capacity, std::size_t size, std::size_t element) {
    return size > capacity ? std::uint64_t(size) * element : std::uint64_t{0};
  };
  const std::uint64_t commit = held + points + red.capacity() + will_split.capacity() +
                               grown(positions_.capacity(), next_vertices, sizeof(Vec3)) +
                               grown(edges_.capacity(), next_edges, sizeof(Edge)) +
                               next_leaves * sizeof(Leaf);
  const std::uint64_t after_commit =
      held - positions_.capacity() * sizeof(Vec3) - edges_.capacity() * sizeof(Edge) -
      leaves_.capacity() * sizeof(Leaf) +
      std::max(positions_.capacity(), next_vertices) * sizeof(Vec3) +
      std::max(edges_.capacity(), next_edges) * sizeof(Edge) + next_leaves * sizeof(Leaf);
  need(std::max(commit, after_commit + build_bytes(faces, step.green_faces, next_leaves, next_edges,
                                                   next_vertices)));

  // Commit. New vertices at the stencil's edge points; halves of sharp edges stay sharp.
  positions_.reserve(next_vertices);
  edges_.reserve(next_edges);
  for (std::uint32_t f = 0; f < num_leaves; ++f) {
    if (!red[f]) continue;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t e = leaves_[f].e[k];
      if (edges_[e].mid != kNone) continue;
      const std::uint32_t mid = static_cast<std::uint32_t>(positions_.size());
      bool guarded = false;
      positions_.push_back(uniform_points_ ? uniform_point(f, k, &guarded)
                                           : pos[nv + m.edge(leaf_halfedge_[f][k]).idx]);
      stats.fold_fallbacks += guarded;  // (the conforming evaluation counted its own)
      const auto [a, b] = edges_[e].v;
      const bool sharp = edges_[e].sharp;
      const std::uint32_t first = add_edge(a, mid, sharp, e);
      const std::uint32_t second = add_edge(mid, b, sharp, e);
      edges_[e].mid = mid;
      edges_[e].half = {first, second};
    }
  }
  free_array(pos);
  free_array(marked);
  free_array(will_split);
  std::vector<Leaf> next;
  next.reserve(next_leaves);
  for (std::uint32_t f = 0; f < num_leaves; ++f) {
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
                      {half_at(leaf.e[k], leaf.v[k]), inner[k], half_at(leaf.e[km1], leaf.v[k])},
                      leaf.level + 1});
    }
    next.push_back({{mid[0], mid[1], mid[2]}, {inner[1], inner[2], inner[0]}, leaf.level + 1});
  }
  free_array(red);
  leaves_ = std::move(next);
  build_level();
  return true;
}

}  // namespace stlrefine
