// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// AdaptiveSplit4's uniform regions (adaptive_split4.h, issue 17): the faces of each uniform
// level the hierarchy needs, with a margin, made by split4 from the region of the level
// below, and the edge points uniform refinement puts there (stencil, plane rule, fold guard
// with the input's carried smooth normals).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/refine.h"
#include "core/schemes/adaptive_split4.h"
#include "core/schemes/adaptive_split4_detail.h"

namespace stlrefine {

using adaptive_split4_detail::marking_bytes;

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
  return turned_past(n1, n2, cos_limit);
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

}  // namespace stlrefine
