// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 hierarchy's connectivity and positions: the triangles and points of
// the uniform sqrt3 hierarchy, made one at a time when the driver asks for them.
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

#include "core/refine.h"
#include "core/schemes/adaptive_sqrt3_hierarchy.h"

namespace stlrefine {

using namespace adaptive_sqrt3_detail;

AdaptiveSqrt3::Hierarchy::Hierarchy(const Level& coarse, const Sqrt3Stencil& stencil,
                                    const Sqrt3AdaptiveCriteria& c,
                                    std::function<void(std::uint64_t)> reserve)
    : stencil_(stencil),
      criteria_(c),
      interpolating_(stencil.interpolating()),
      guarded_(c.guard == FoldGuard::AsStencil && stencil.guards_folds()),
      cos_fold_(std::cos(kSqrt3FoldAngleDeg * std::numbers::pi / 180.0)),
      top_level_(c.max_level + 2),
      input_vertices_(static_cast<std::uint32_t>(coarse.mesh.num_vertices())),
      input_faces_(coarse.mesh.num_faces()),
      reserve_(std::move(reserve)) {
  const Mesh& m = coarse.mesh;
  // Patches: a triangle and the fans round its corners, at most one per level alive at
  // once (positions recurse to coarser levels). Old vertices keep their valence; new
  // ones have at most 6, or a few more next to a crease.
  int valence = 12;
  for (std::uint32_t v = 0; v < input_vertices_; ++v)
    if (!m.is_isolated(VertexId(v))) valence = std::max(valence, m.valence(VertexId(v)));
  // The fold guard's decisions evaluate the points of the level above while a level's
  // fans are walked: up to twice as many patches.
  patch_bytes_ = std::uint64_t(top_level_ + 1) * (guarded_ ? 2 : 1) *
                 (kPatchBytes + kPatchFaceBytes * (1 + 3 * std::uint64_t(valence)));
  need(held_bytes() + big_vector_bytes<double>(input_vertices_));  // the initial alpha
  const BigVector<double> alpha = stencil.initial_alpha(coarse);
  has_alpha_ = !alpha.empty();
  // Input vertex v is hierarchy vertex v, input face f triangle f, half-edges alike.
  for (std::uint32_t i = 0; i < input_vertices_; ++i) {
    const VertexId v(i);
    const VertexId id = new_vertex(Origin::Input, FaceId(), 0);
    verts_[id].home = m.halfedge(v);
    set_position(id, 0, m.position(v));
    if (has_alpha_) alpha_[id] = alpha[i];
  }
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    Tri t;
    for (std::uint8_t k = 0; k < 3; ++k) {
      const HalfedgeId h = Mesh::halfedge(FaceId(f), k);
      t.v[k] = m.from(h);
      t.twin[k] = m.twin(h);
      if (coarse.features.is_sharp(m.edge(h))) t.sharp |= 1 << k;
      if (m.halfedge(m.edge(h)) == h) t.canon |= 1 << k;
    }
    add_tri(t);
  }
}

VertexId AdaptiveSqrt3::Hierarchy::new_vertex(Origin origin, FaceId tri, int level) {
  const VertexId id(static_cast<std::uint32_t>(verts_.size()));
  Vert v;
  v.tri = tri;
  v.origin = origin;
  v.level = static_cast<std::uint8_t>(level);
  v.slot = static_cast<std::uint32_t>(pool_.size());
  // Interpolating stencils never move a vertex: one position. Others: one per level.
  const int slots = interpolating_ ? 1 : std::max(1, top_level_ - level + 1);
  const std::uint64_t growth = pool_.growth_bytes(pool_.size() + slots) +
                               known_.growth_bytes(known_.size() + slots) +
                               verts_.growth_bytes(verts_.size() + 1) +
                               (has_alpha_ ? alpha_.growth_bytes(alpha_.size() + 1) : 0) +
                               (guarded_ ? guard_point_.growth_bytes(verts_.size() + 1) : 0);
  if (growth) need(held_bytes() + growth);
  pool_.grow(pool_.size() + slots);
  known_.grow(known_.size() + slots, 0);
  verts_.push_back(v);
  if (has_alpha_) alpha_.push_back(1.0);
  if (guarded_) {
    guard_point_.push_back({});
  }
  return id;
}

FaceId AdaptiveSqrt3::Hierarchy::add_tri(const Tri& t) {
  // Far past any face budget's memory; keeps the half-edge ids 3t + k in 32 bits.
  if (tris_.size() >= kMaxTriangles) throw internal("the hierarchy has too many triangles");
  const std::uint64_t growth =
      tris_.growth_bytes(tris_.size() + 1) +
      (guarded_ ? corner_normal_.growth_bytes(corner_normal_.size() + 1) : 0);
  if (growth) need(held_bytes() + growth);
  tris_.push_back(t);
  if (guarded_) corner_normal_.push_back({});
  return FaceId(static_cast<std::uint32_t>(tris_.size() - 1));
}

// ---------------------------------------------------------------------------------------
// Connectivity. A triangle of level l + 1 is child(h) of a level-l half-edge h; its corners
// and neighbours are sqrt3_refine's fine_face_plain / fine_face_trisecting, read here one
// triangle at a time instead of for the whole level.

HalfedgeId AdaptiveSqrt3::Hierarchy::sharp_of(FaceId t) const {
  HalfedgeId s;
  for (std::uint8_t k = 0; k < 3; ++k) {
    if (!((tris_[t].sharp >> k) & 1)) continue;
    if (s.valid()) throw internal("a trisecting level has a face with two sharp edges");
    s = he(t, k);
  }
  return s;
}

HalfedgeId AdaptiveSqrt3::Hierarchy::twin(HalfedgeId h) {
  HalfedgeId& known = tris_[Mesh::face(h)].twin[corner_of(h)];
  if (known != kUnknownTwin) return known;  // a twin, or invalid at a boundary
  const HalfedgeId r = derive_twin(h);
  if (r.valid() && (from(h) != to(r) || to(h) != from(r)))
    throw internal("neighbours at a level do not share their edge");
  tris_[Mesh::face(h)].twin[corner_of(h)] = r;
  if (r.valid()) tris_[Mesh::face(r)].twin[corner_of(r)] = h;
  return r;
}

HalfedgeId AdaptiveSqrt3::Hierarchy::to_apex_side(HalfedgeId x) {
  const FaceId f = Mesh::face(x);
  const HalfedgeId sx = trisects(level(f)) ? sharp_of(f) : HalfedgeId();
  if (!sx.valid()) return fine(Mesh::next(x), 2);
  if (x == Mesh::next(sx)) return fine(sx, 1);  // the edge (m2, c) of the middle child
  // x == prev(sx): to(x) -> m1 is the first third of the sharp edge sx
  const HalfedgeId across = twin(sx);
  return across.valid() ? fine(Mesh::next(across), 2) : HalfedgeId();
}

HalfedgeId AdaptiveSqrt3::Hierarchy::derive_twin(HalfedgeId h) {
  // sqrt3_host's Sqrt3Layout::fine_face, for the one fine half-edge h.
  const HalfedgeId c = tris_[Mesh::face(h)].owner;  // the coarse half-edge that made h's face
  const FaceId f = Mesh::face(c);
  const HalfedgeId s = trisects(level(f)) ? sharp_of(f) : HalfedgeId();
  const std::uint8_t k = corner_of(h);
  if (c == s) {  // the middle child (m1, m2, apex) of a face cut at its sharp edge
    if (k == 0) {
      const HalfedgeId t = twin(s);
      return t.valid() ? fine(t, 0) : HalfedgeId();
    }
    if (k == 1) return to_apex(Mesh::next(s));
    return fine(Mesh::prev(s), 2);
  }
  const HalfedgeId t = twin(c);
  if (k == 2) {  // apex(c) -> a
    if (!s.valid()) return to_apex(Mesh::prev(c));
    if (c == Mesh::next(s)) {  // m2 -> a: the last third of the sharp edge s
      const HalfedgeId across = twin(s);
      return across.valid() ? to_apex(Mesh::prev(across)) : HalfedgeId();
    }
    return fine(s, 2);  // c == prev(s): shared with s's middle child
  }
  if (kept(c)) {  // (a, b, apex(c))
    if (k == 0) return t.valid() ? fine(t, 0) : HalfedgeId();
    return to_apex_side(c);
  }
  // flipped: (a, apex(t), apex(c))
  if (k == 0) return to_apex_side(t);
  return fine(t, 1);
}

FaceId AdaptiveSqrt3::Hierarchy::child(HalfedgeId h) {
  const FaceId parent = Mesh::face(h);
  if (const FaceId known = tris_[parent].child[corner_of(h)]; known.valid()) return known;
  const int l = level(parent);
  const HalfedgeId s = trisects(l) ? sharp_of(parent) : HalfedgeId();
  Tri c;
  c.level = static_cast<std::uint8_t>(l + 1);
  c.owner = h;
  if (h == s) {  // the middle child of a face cut at its sharp edge
    const auto [m1, m2] = trisection(s);
    c.v = {m1, m2, opposite(s)};
    c.sharp = 1;
    c.canon = canonical(s) ? 1 : 0;
  } else if (const HalfedgeId t = twin(h); kept(h)) {  // the edge kept whole with its apex
    c.v = {from(h), to(h), apex(h)};
    if (sharp(h) || !t.valid()) {
      c.sharp = 1;
      c.canon = canonical(h) ? 1 : 0;
    }
    // to(h) -> m1 is the first third of this face's sharp edge: canonical at a boundary only
    // (across a crease it is the other side's last third).
    if (s.valid() && h == Mesh::prev(s)) {
      c.sharp |= 2;
      if (!twin(s).valid()) c.canon |= 2;
    }
    if (s.valid() && h == Mesh::next(s)) {  // m2 -> a, the last third: canonical here
      c.sharp |= 4;
      c.canon |= 4;
    }
  } else {  // t looked up before kept(h), as before the guard (the same numbering)
    c.v = {from(h), apex(t), apex(h)};
    c.flags = kFlip;
    // a -> m1 is the first third of the sharp edge of t's face; its canonical half is on
    // the other side of a crease (the last third there), on this side at a boundary.
    const HalfedgeId sg = trisects(l) ? sharp_of(Mesh::face(t)) : HalfedgeId();
    if (sg.valid() && t == Mesh::prev(sg)) {
      c.sharp |= 1;
      if (!twin(sg).valid()) c.canon |= 1;
    }
    // m2 -> a is the last third of this face's sharp edge; this side is canonical.
    if (s.valid() && h == Mesh::next(s)) {
      c.sharp |= 4;
      c.canon |= 4;
    }
  }
  if (tris_[parent].child[corner_of(h)].valid()) throw internal("a child was made twice");
  const FaceId id = add_tri(c);
  tris_[parent].child[corner_of(h)] = id;
  return id;
}

VertexId AdaptiveSqrt3::Hierarchy::face_point(FaceId t) {
  if (tris_[t].point.valid()) return tris_[t].point;
  const VertexId q = new_vertex(Origin::FacePoint, t, level(t) + 1);
  if (has_alpha_) {  // LL eq. 7
    const auto& v = tris_[t].v;
    alpha_[q] = (alpha_[v[0]] + alpha_[v[1]] + alpha_[v[2]]) / 3.0;
  }
  tris_[t].point = q;
  return q;
}

std::pair<VertexId, VertexId> AdaptiveSqrt3::Hierarchy::trisection(HalfedgeId s) {
  const FaceId f = Mesh::face(s);
  if (!tris_[f].point.valid()) {
    const int l = level(f) + 1;
    const VertexId m1 = new_vertex(Origin::NearFrom, f, l);
    const VertexId m2 = new_vertex(Origin::NearTo, f, l);
    if (has_alpha_) {
      alpha_[m1] = (2.0 * alpha_[from(s)] + alpha_[to(s)]) / 3.0;
      alpha_[m2] = (alpha_[from(s)] + 2.0 * alpha_[to(s)]) / 3.0;
    }
    tris_[f].point = m1;
    tris_[f].point2 = m2;
    // The face across a crease shares them, seen from its own sharp half-edge.
    const HalfedgeId t = twin(s);
    if (t.valid()) {
      tris_[Mesh::face(t)].point = m2;
      tris_[Mesh::face(t)].point2 = m1;
    }
  }
  return {tris_[f].point, tris_[f].point2};
}

VertexId AdaptiveSqrt3::Hierarchy::apex(HalfedgeId h) {
  const FaceId f = Mesh::face(h);
  const HalfedgeId s = trisects(level(f)) ? sharp_of(f) : HalfedgeId();
  if (!s.valid()) return face_point(f);
  const auto [m1, m2] = trisection(s);
  return h == Mesh::next(s) ? m2 : m1;
}

// ---------------------------------------------------------------------------------------
// Positions

HalfedgeId AdaptiveSqrt3::Hierarchy::home(VertexId v) {
  if (verts_[v].home.valid() || verts_[v].origin == Origin::Input) return verts_[v].home;
  // The fine triangle whose corner 2 (its apex) is the new vertex.
  const FaceId t = verts_[v].tri;
  HalfedgeId h = he(t, 0);
  if (verts_[v].origin != Origin::FacePoint) {
    const HalfedgeId s = sharp_of(t);
    h = verts_[v].origin == Origin::NearFrom ? Mesh::prev(s) : Mesh::next(s);
  }
  const HalfedgeId r = he(child(h), 2);
  if (from(r) != v) throw internal("a new vertex is not where its parent put it");
  verts_[v].home = r;
  return r;
}

HalfedgeId AdaptiveSqrt3::Hierarchy::halfedge_at(VertexId v, int l) {
  HalfedgeId h = home(v);
  if (!h.valid()) return h;
  while (level(Mesh::face(h)) < l) {
    // A cut face's middle child does not touch from(s): go through the next face round.
    if (trisects(level(Mesh::face(h))) && sharp(h)) h = twin(Mesh::prev(h));
    h = he(child(h), 0);
  }
  return h;
}

Vec3 AdaptiveSqrt3::Hierarchy::position(VertexId v, int l) {
  const int own = verts_[v].level;
  l = interpolating_ ? own : std::clamp(l, own, top_level_);
  const std::uint32_t s = slot_of(v, l);
  if (known_[s]) return pool_[s];
  Vec3 p;
  if (l == own) {
    p = creation_position(v);
  } else {
    // The stencil's rule for an old vertex, on its fan one level coarser.
    const HalfedgeId h = halfedge_at(v, l - 1);
    std::vector<FaceId> tris;
    gather_fan(h, tris);
    const Patch patch = build_patch(std::move(tris), l - 1);
    const auto local = static_cast<std::uint32_t>(
        std::lower_bound(patch.vertices.begin(), patch.vertices.end(), v) - patch.vertices.begin());
    p = stencil_.vertex_point(step_of(patch, l - 1), VertexId(local));
  }
  set_position(v, l, p);
  return p;
}

Vec3 AdaptiveSqrt3::Hierarchy::creation_position(VertexId v) {
  const FaceId t = verts_[v].tri;
  const int l = level(t);
  if (verts_[v].origin == Origin::FacePoint) {
    if (guarded_) {
      const int stage = guard_stage(v, kGuardPasses - 1, kGuardRounds - 1);
      verts_[v].pulled = stage > 0;
      return stage_point(v, stage);
    }
    std::vector<FaceId> tris{t};
    for (std::uint8_t k = 0; k < 3; ++k) gather_fan(he(t, k), tris);
    const Patch patch = build_patch(std::move(tris), l);
    return stencil_.face_point(step_of(patch, l), FaceId(0));
  }
  // A trisection point: both points of the edge at once, from the edge's canonical half
  // (the one sqrt3_refine evaluates), so the results are the uniform level's bit for bit.
  HalfedgeId s = sharp_of(t);
  const auto [m1, m2] = trisection(s);
  const bool flipped = !canonical(s);
  if (flipped) {
    s = twin(s);
    if (!s.valid() || !canonical(s)) throw internal("a sharp edge has no canonical half");
  }
  std::vector<FaceId> tris{Mesh::face(s)};
  gather_fan(s, tris);
  gather_fan(Mesh::next(s), tris);
  const Patch patch = build_patch(std::move(tris), l);
  const std::array<Vec3, 2> pts =
      stencil_.curve_points(step_of(patch, l), HalfedgeId(corner_of(s)));
  set_position(flipped ? m2 : m1, l + 1, pts[0]);
  set_position(flipped ? m1 : m2, l + 1, pts[1]);
  return pts[v == m1 ? (flipped ? 1 : 0) : (flipped ? 0 : 1)];
}

void AdaptiveSqrt3::Hierarchy::gather_fan(HalfedgeId h, std::vector<FaceId>& out) {
  // Counter-clockwise round from(h); at a boundary, clockwise from h as well.
  constexpr int kMaxValence = 1 << 16;
  HalfedgeId c = h;
  int steps = 0;
  bool open = false;
  do {
    out.push_back(Mesh::face(c));
    const HalfedgeId t = twin(Mesh::prev(c));
    if (!t.valid()) {
      open = true;
      break;
    }
    c = t;
    if (++steps > kMaxValence) throw internal("a vertex fan does not close");
  } while (c != h);
  if (!open) return;
  for (c = h;;) {
    const HalfedgeId t = twin(c);
    if (!t.valid()) break;
    c = Mesh::next(t);
    out.push_back(Mesh::face(c));
    if (++steps > kMaxValence) throw internal("a vertex fan does not close");
  }
}

AdaptiveSqrt3::Hierarchy::Patch AdaptiveSqrt3::Hierarchy::build_patch(std::vector<FaceId> tris,
                                                                      int l) {
  // Local face i is the i-th distinct triangle (the target first).
  {
    std::vector<FaceId> unique;
    unique.reserve(tris.size());
    for (FaceId t : tris)
      if (std::find(unique.begin(), unique.end(), t) == unique.end()) unique.push_back(t);
    tris = std::move(unique);
  }
  std::vector<std::pair<FaceId, std::uint32_t>> local_tri;  // (global, local) sorted
  local_tri.reserve(tris.size());
  for (std::uint32_t i = 0; i < tris.size(); ++i) local_tri.emplace_back(tris[i], i);
  std::sort(local_tri.begin(), local_tri.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });

  Patch p;
  for (FaceId t : tris)
    for (VertexId v : tris_[t].v) p.vertices.push_back(v);
  std::sort(p.vertices.begin(), p.vertices.end());
  p.vertices.erase(std::unique(p.vertices.begin(), p.vertices.end()), p.vertices.end());
  auto local_vertex = [&](VertexId v) {
    return VertexId(static_cast<std::uint32_t>(
        std::lower_bound(p.vertices.begin(), p.vertices.end(), v) - p.vertices.begin()));
  };

  // Positions first: they may grow the hierarchy (coarser patches).
  BigVector<Vec3> positions(p.vertices.size());
  for (std::size_t i = 0; i < p.vertices.size(); ++i) positions[i] = position(p.vertices[i], l);

  BigVector<VertexId> corner(3 * tris.size());
  BigVector<HalfedgeId> twin_of(3 * tris.size());
  for (std::uint32_t i = 0; i < tris.size(); ++i) {
    const Tri& t = tris_[tris[i]];
    for (std::uint8_t k = 0; k < 3; ++k) {
      corner[3 * i + k] = local_vertex(t.v[k]);
      const HalfedgeId tw = t.twin[k];
      if (!tw.valid() || tw == kUnknownTwin) continue;  // a boundary, or outside every fan
      const FaceId n = Mesh::face(tw);
      const auto it = std::lower_bound(local_tri.begin(), local_tri.end(), n,
                                       [](const auto& a, FaceId b) { return a.first < b; });
      if (it != local_tri.end() && it->first == n)
        twin_of[3 * i + k] = Mesh::halfedge(FaceId(it->second), corner_of(tw));
    }
  }
  p.mesh = Mesh::from_parts(std::move(positions), std::move(corner), std::move(twin_of));
  BigVector<std::uint8_t> sharp(p.mesh.num_edges());
  for (std::uint32_t e = 0; e < sharp.size(); ++e) {
    const HalfedgeId h = p.mesh.halfedge(EdgeId(e));
    sharp[e] = (tris_[tris[Mesh::face(h).idx]].sharp >> corner_of(h)) & 1;
  }
  p.features = Features(p.mesh, std::move(sharp));
  if (trisects(l)) {
    p.sharp_corner.resize(tris.size());
    for (std::uint32_t i = 0; i < tris.size(); ++i) {
      const HalfedgeId s = sharp_of(tris[i]);
      p.sharp_corner[i] = s.valid() ? corner_of(s) : 3;
    }
  }
  if (has_alpha_) {
    p.alpha.resize(p.vertices.size());
    for (std::size_t i = 0; i < p.vertices.size(); ++i) p.alpha[i] = alpha_[p.vertices[i]];
  }
  return p;
}

}  // namespace stlrefine
