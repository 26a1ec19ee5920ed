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

namespace stlrefine {

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

// What the marking allocates besides the level at most: the candidate points, the stencil's
// scratch, the plane rule's and the fold guard's flags and the marks (the guard's work arrays are
// reserved by the guard itself, see candidate_points).
std::uint64_t marking_bytes(const Level& level, const Split4Stencil& stencil) {
  const Mesh& m = level.mesh;
  return big_vector_bytes<Vec3>(m.num_vertices() + m.num_edges()) + stencil.scratch_bytes(level) +
         2 * std::uint64_t(m.num_edges()) + m.num_faces() + keep_dominant_planes_bytes(m);
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

std::uint64_t AdaptiveSplit4::uniform_bytes() const {
  std::uint64_t bytes = 0;
  for (const UniformLevel& u : uniform_) {
    bytes += level_bytes(u.level) + u.hierarchy_vertex.capacity() * sizeof(std::uint32_t) +
             u.trusted.capacity() + u.cut.capacity() + u.edge_trusted.capacity() +
             big_vector_bytes<Vec3>(u.points.capacity()) +
             u.edge_of.size() * (sizeof(std::uint64_t) + sizeof(std::uint32_t) + 16) +
             u.edge_of.bucket_count() * sizeof(void*);
  }
  return bytes;
}

namespace {

// How far (in edges of a level) the points of an edge may depend on the level around its
// two end vertices: the stencils read the 1-ring (butterfly, with its wings) or fit the
// neighbourhood (lsf), and the fold guard looks at the faces around the edge.
constexpr int kStencilReach = 3;
// Rings of level k - 1 faces kept around the faces the hierarchy split, so that the leaves
// of level k and those a closure may split are kStencilReach away from the region's cut.
constexpr int kRegionMargin = kStencilReach + 2;

// Per edge of `level`: whether its point depends only on trusted vertices of an uncut
// neighbourhood (both end vertices kStencilReach edges or more away from an untrusted
// vertex or a vertex on a cut edge).
std::vector<std::uint8_t> trusted_edges(const Mesh& m, const std::vector<std::uint8_t>& trusted,
                                        const std::vector<std::uint8_t>& cut) {
  const std::size_t nv = m.num_vertices(), ne = m.num_edges();
  std::vector<int> depth(nv, kStencilReach);
  std::vector<std::uint32_t> frontier;
  for (std::uint32_t v = 0; v < nv; ++v)
    if (!trusted[v]) depth[v] = 0;
  for (std::uint32_t e = 0; e < ne; ++e) {
    if (!cut[e]) continue;
    const HalfedgeId h = m.halfedge(EdgeId(e));
    depth[m.from(h).idx] = depth[m.to(h).idx] = 0;
  }
  for (std::uint32_t v = 0; v < nv; ++v)
    if (depth[v] == 0) frontier.push_back(v);
  // Breadth first over the edges, kStencilReach rounds.
  for (int d = 1; d < kStencilReach && !frontier.empty(); ++d) {
    std::vector<std::uint32_t> next;
    for (std::uint32_t e = 0; e < ne; ++e) {
      const HalfedgeId h = m.halfedge(EdgeId(e));
      const std::uint32_t a = m.from(h).idx, b = m.to(h).idx;
      if (depth[a] == d - 1 && depth[b] > d) depth[b] = d, next.push_back(b);
      if (depth[b] == d - 1 && depth[a] > d) depth[a] = d, next.push_back(a);
    }
    frontier = std::move(next);
  }
  std::vector<std::uint8_t> out(ne);
  for (std::uint32_t e = 0; e < ne; ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    out[e] = depth[m.from(h).idx] >= kStencilReach && depth[m.to(h).idx] >= kStencilReach;
  }
  return out;
}

}  // namespace

void AdaptiveSplit4::evaluate_uniform(UniformLevel& u, const Split4Stencil& stencil) {
  const Mesh& m = u.level.mesh;
  std::function<void(std::uint64_t)> guard_reserve;
  const std::uint64_t held = held_bytes();
  if (reserve_) guard_reserve = [&](std::uint64_t work) { need(held + work); };
  // Points, the stencil's scratch, the guard's flags, the unguarded copy, trust, edge map.
  need(held + marking_bytes(u.level, stencil) + m.num_edges() * (sizeof(Vec3) + 48));
  // candidate_points, keeping which edge points the fold guard moved.
  const std::size_t nv = m.num_vertices(), ne = m.num_edges();
  u.points = BigVector<Vec3>(nv + ne);
  stencil.vertex_points(u.level, std::span<Vec3>(u.points.data(), nv));
  stencil.edge_points(u.level, std::span<Vec3>(u.points.data() + nv, ne));
  const std::vector<Vec3> raw(u.points.begin() + static_cast<std::ptrdiff_t>(nv), u.points.end());
  keep_dominant_planes(m, u.level.features, u.points);
  if (u.level.smooth_normals.size() == 3 * std::size_t(m.num_faces()))
    guard_folds(m, u.level.features, u.level.smooth_normals, u.points, guard_reserve);
  else
    guard_folds(m, u.level.features, u.points, guard_reserve);
  u.edge_guarded.resize(ne);
  for (std::size_t e = 0; e < ne; ++e) u.edge_guarded[e] = !(u.points[nv + e] == raw[e]);
  u.edge_trusted = trusted_edges(m, u.trusted, u.cut);
  u.edge_of.clear();
  u.edge_of.reserve(m.num_edges());
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    const std::uint32_t a = u.hierarchy_vertex[m.from(h).idx], b = u.hierarchy_vertex[m.to(h).idx];
    if (a != kNone && b != kNone) u.edge_of.emplace(pair_key(a, b), e);
  }
}

void AdaptiveSplit4::update_uniform(const Split4Stencil& stencil) {
  std::uint32_t finest = 0;
  for (const Leaf& leaf : leaves_) finest = std::max(finest, leaf.level);
  if (uniform_[0].points.empty()) evaluate_uniform(uniform_[0], stencil);
  // Split edges of the hierarchy by their end vertices.
  std::unordered_map<std::uint64_t, std::uint32_t> mid_of;
  for (const Edge& e : edges_)
    if (e.mid != kNone) mid_of.emplace(pair_key(e.v[0], e.v[1]), e.mid);
  auto mid = [&](std::uint32_t a, std::uint32_t b) {
    if (a == kNone || b == kNone) return kNone;
    const auto it = mid_of.find(pair_key(a, b));
    return it == mid_of.end() ? kNone : it->second;
  };
  bool rebuilt = false;  // a level below was made anew (its vertex numbers changed)
  for (std::uint32_t k = 1; k <= finest; ++k) {
    const UniformLevel& c = uniform_[k - 1];
    const Mesh& cm = c.level.mesh;
    const std::size_t cf = cm.num_faces(), cv = cm.num_vertices();
    // The faces of level k - 1 the hierarchy split (all three edges split), and around them
    // kRegionMargin rings.
    std::vector<std::uint8_t> in_vertex(cv, 0), in_face(cf, 0);
    std::size_t num_split = 0;
    for (std::uint32_t f = 0; f < cf; ++f) {
      bool split = true;
      for (std::uint32_t j = 0; j < 3 && split; ++j) {
        const HalfedgeId h(3 * f + j);
        split = c.hierarchy_vertex[cm.from(h).idx] != kNone &&
                mid(c.hierarchy_vertex[cm.from(h).idx], c.hierarchy_vertex[cm.to(h).idx]) != kNone;
      }
      if (!split) continue;
      ++num_split;
      for (std::uint32_t j = 0; j < 3; ++j) in_vertex[cm.from(HalfedgeId(3 * f + j)).idx] = 1;
    }
    // The hierarchy only ever splits more faces: the same count is the same faces, and the
    // region made from them last time is still this level's (with the same hierarchy
    // vertices: a vertex of level k gets one only when a face of level k - 1 is split).
    if (!rebuilt && k < uniform_.size() && uniform_[k].source_split == num_split) continue;
    rebuilt = true;
    uniform_.resize(k);
    for (int ring = 0; ring < kRegionMargin; ++ring) {
      for (std::uint32_t f = 0; f < cf; ++f)
        for (std::uint32_t j = 0; j < 3; ++j)
          if (in_vertex[cm.from(HalfedgeId(3 * f + j)).idx]) in_face[f] = 1;
      for (std::uint32_t f = 0; f < cf; ++f)
        if (in_face[f])
          for (std::uint32_t j = 0; j < 3; ++j) in_vertex[cm.from(HalfedgeId(3 * f + j)).idx] = 1;
    }
    // No vertex may pinch the region (two or more fans of region faces meeting only at
    // it): fill the ring of such a vertex, until none is left.
    for (bool pinched = true; pinched;) {
      pinched = false;
      std::vector<std::uint32_t> fans(cv, 0);  // region faces at v minus region edges at v
      for (std::uint32_t h = 0; h < cm.num_halfedges(); ++h) {
        if (!in_face[h / 3]) continue;
        const std::uint32_t v = cm.from(HalfedgeId(h)).idx;
        ++fans[v];
        const HalfedgeId t = cm.twin(HalfedgeId(h));
        if (t.valid() && in_face[t.idx / 3]) --fans[v];
      }
      for (std::uint32_t h = 0; h < cm.num_halfedges(); ++h) {
        const std::uint32_t v = cm.from(HalfedgeId(h)).idx;
        if (fans[v] >= 2 && !in_face[h / 3]) in_face[h / 3] = 1, pinched = true;
      }
    }
    // The region as a level of its own.
    std::vector<std::uint32_t> local(cv, kNone), global_of;
    std::vector<std::uint32_t> faces;
    for (std::uint32_t f = 0; f < cf; ++f)
      if (in_face[f]) faces.push_back(f);
    BigVector<VertexId> corner(3 * faces.size());
    for (std::uint32_t i = 0; i < faces.size(); ++i)
      for (std::uint32_t j = 0; j < 3; ++j) {
        const std::uint32_t v = cm.from(HalfedgeId(3 * faces[i] + j)).idx;
        if (local[v] == kNone)
          local[v] = static_cast<std::uint32_t>(global_of.size()), global_of.push_back(v);
        corner[3 * i + j] = VertexId(local[v]);
      }
    BigVector<Vec3> positions(global_of.size());
    for (std::uint32_t v = 0; v < global_of.size(); ++v)
      positions[v] = cm.position(VertexId(global_of[v]));
    BigVector<HalfedgeId> twin(3 * faces.size());
    for (std::uint32_t h = 0; h < twin.size(); ++h) {
      const HalfedgeId ct = cm.twin(HalfedgeId(3 * faces[h / 3] + h % 3));
      twin[h] = ct.valid() && in_face[ct.idx / 3]
                    ? HalfedgeId(3 * static_cast<std::uint32_t>(
                                         std::lower_bound(faces.begin(), faces.end(), ct.idx / 3) -
                                         faces.begin()) +
                                 ct.idx % 3)
                    : HalfedgeId();
    }
    const std::uint64_t held = held_bytes();
    const bool carried = c.level.smooth_normals.size() == 3 * cf;
    need(held + mesh_bytes(cm) + (carried ? big_vector_bytes<Vec3>(3 * faces.size()) : 0));
    Level region;
    region.mesh = Mesh::from_parts(std::move(positions), std::move(corner), std::move(twin));
    region.step = static_cast<int>(k) - 1;
    // The level's carried smooth normals, per corner of its faces: split4 guards the region's
    // children with them and carries them on to the next level, as the uniform host does.
    if (carried) {
      region.smooth_normals = BigVector<Vec3>(3 * faces.size());
      for (std::size_t i = 0; i < 3 * faces.size(); ++i)
        region.smooth_normals[i] = c.level.smooth_normals[3 * std::size_t(faces[i / 3]) + i % 3];
    }
    const Mesh& rm = region.mesh;
    BigVector<std::uint8_t> sharp(rm.num_edges());
    std::vector<std::uint8_t> region_cut(rm.num_edges(), 0);
    for (std::uint32_t h = 0; h < rm.num_halfedges(); ++h) {
      const HalfedgeId ch(3 * faces[h / 3] + h % 3);
      const EdgeId e = rm.edge(HalfedgeId(h));
      sharp[e.idx] = c.level.features.is_sharp(cm.edge(ch));
      if (!rm.twin(HalfedgeId(h)).valid())
        region_cut[e.idx] = cm.twin(ch).valid() || c.cut[cm.edge(ch).idx];
    }
    region.features = Features(rm, std::move(sharp));
    std::vector<std::uint8_t> region_trusted(rm.num_vertices());
    for (std::uint32_t v = 0; v < rm.num_vertices(); ++v)
      region_trusted[v] = c.trusted[global_of[v]];
    const std::vector<std::uint8_t> region_edge_trusted =
        trusted_edges(rm, region_trusted, region_cut);
    need(held + level_bytes(region) + split4_step_bytes(region, stencil));
    StepStats ignored;
    UniformLevel u;
    u.level = split4(region, stencil, ignored);
    const Mesh& um = u.level.mesh;
    const std::size_t rv = rm.num_vertices();
    u.hierarchy_vertex.resize(um.num_vertices());
    u.trusted.resize(um.num_vertices());
    for (std::uint32_t v = 0; v < rv; ++v) {
      u.hierarchy_vertex[v] = c.hierarchy_vertex[global_of[v]];
      u.trusted[v] = region_trusted[v];
    }
    for (std::uint32_t e = 0; e < rm.num_edges(); ++e) {
      const HalfedgeId h = rm.halfedge(EdgeId(e));
      u.hierarchy_vertex[rv + e] =
          mid(u.hierarchy_vertex[rm.from(h).idx], u.hierarchy_vertex[rm.to(h).idx]);
      u.trusted[rv + e] = region_edge_trusted[e];
    }
    u.cut.assign(um.num_edges(), 0);
    for (std::uint32_t e = 0; e < um.num_edges(); ++e) {
      const HalfedgeId h = um.halfedge(EdgeId(e));
      if (um.twin(h).valid()) continue;
      const std::uint32_t m = std::max(um.from(h).idx, um.to(h).idx);
      u.cut[e] = m >= rv && region_cut[m - rv];
    }
    u.source_split = num_split;
    uniform_.push_back(std::move(u));
    evaluate_uniform(uniform_.back(), stencil);
  }
}

Vec3 AdaptiveSplit4::uniform_point(std::uint32_t leaf, std::uint32_t k, bool* guarded) const {
  const Leaf& l = leaves_[leaf];
  const UniformLevel& u = uniform_.at(l.level);
  const auto it = u.edge_of.find(pair_key(l.v[k], l.v[(k + 1) % 3]));
  if (it == u.edge_of.end() || !u.edge_trusted[it->second])
    throw Error(ErrorCode::Internal, "adaptive_stencil_margin",
                "adaptive refinement: the uniform level " + std::to_string(l.level) +
                    " around an edge to split is not wide enough for the stencil");
  if (guarded) *guarded = u.edge_guarded[it->second];
  return u.points[u.level.mesh.num_vertices() + it->second];
}

bool AdaptiveSplit4::uniform_over(std::uint32_t leaf, std::uint32_t k, double tolerance,
                                  double cos_limit, bool angle_on, double& dist) const {
  const Leaf& l = leaves_[leaf];
  const Vec3 p = uniform_point(leaf, k);
  const Vec3 mid = 0.5 * (positions_[l.v[k]] + positions_[l.v[(k + 1) % 3]]);
  dist = distance(p, mid);
  if (tolerance > 0 && dist > tolerance) return true;
  if (!angle_on || edges_[l.e[k]].sharp) return false;
  const UniformLevel& u = uniform_[l.level];
  const Mesh& m = u.level.mesh;
  const HalfedgeId h = m.halfedge(EdgeId(u.edge_of.at(pair_key(l.v[k], l.v[(k + 1) % 3]))));
  const HalfedgeId t = m.twin(h);
  if (!t.valid()) return false;
  const Vec3 n1 = m.face_normal(Mesh::face(h)), n2 = m.face_normal(Mesh::face(t));
  const double scale = std::sqrt(dot(n1, n1) * dot(n2, n2));
  return scale > 0 && dot(n1, n2) < cos_limit * scale;
}

EdgesOverTolerance AdaptiveSplit4::remaining(const Split4Stencil& stencil, double tolerance,
                                             double angle_deg) {
  if (!uniform_points_)
    return edges_over_tolerance(level_, stencil, tolerance, angle_deg, reserve_);
  update_uniform(stencil);
  EdgesOverTolerance out;
  const double cos_limit = std::cos(angle_deg * std::numbers::pi / 180.0);
  std::vector<std::uint8_t> seen(edges_.size(), 0);
  for (std::uint32_t f = 0; f < leaves_.size(); ++f)
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t e = leaves_[f].e[k];
      if (edges_[e].mid != kNone || seen[e]) continue;
      seen[e] = 1;
      double dist = 0;
      if (!uniform_over(f, k, tolerance, cos_limit, angle_deg > 0, dist)) continue;
      ++out.count;
      if (const std::uint32_t parent = edges_[e].parent; parent != kNone && tolerance > 0) {
        const Edge& p = edges_[parent];
        const double parent_dist =
            distance(positions_[p.mid], 0.5 * (positions_[p.v[0]] + positions_[p.v[1]]));
        out.not_shrinking += dist > tolerance && dist > 0.5 * parent_dist;
      }
      if (tolerance > 0 && dist > tolerance && dist > out.max_distance) {
        out.max_distance = dist;
        out.worst_at = 0.5 * (positions_[edges_[e].v[0]] + positions_[edges_[e].v[1]]);
      }
    }
  return out;
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
  // hanging midpoints, or one on a half of its already split edge (a level jump of two),
  // turns red as well. A worklist holds the leaves next to edges that just got marked:
  // those on the edge, and those on the edge it is a half of. The rule only ever adds red
  // leaves, so the order does not change the result, and a leaf is queued once at a time.
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
  for (std::uint32_t f = 0; f < num_leaves; ++f)
    if (red[f]) mark_edges(f);
  while (!todo.empty()) {
    const std::uint32_t f = todo.back();
    todo.pop_back();
    queued[f] = 0;
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
