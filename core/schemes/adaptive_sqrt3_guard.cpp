// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 host's fold guard (issue 17 item 2), sqrt3_host's with the same test
// and limit (kSqrt3FoldAngleDeg) against the level's sector normals, one edge and one face
// point at a time: an edge whose flip would fold is not flipped (decided once per edge
// with the stencil's points, as the uniform host's first round), and a face point whose
// fine faces fold moves towards its face's centroid in the uniform host's stages. What the
// uniform host does over the whole level in rounds (later rounds that keep more flips after
// the pulls, and pulls judged against the neighbours' pulled points) is not done: a
// hierarchy made one triangle at a time does not see the level. So where the uniform host
// iterates, the two differ (tests/core/adaptive_sqrt3_guard_test.cpp,
// bench/results-issue17-s4-adaptive.md).
#include <array>
#include <cmath>

#include "core/schemes/adaptive_sqrt3_hierarchy.h"

namespace stlrefine {

using namespace adaptive_sqrt3_detail;

bool AdaptiveSqrt3::Hierarchy::unflipped(HalfedgeId h) {
  if (!guarded_) return false;
  const FaceId f = Mesh::face(h);
  const std::uint8_t k = corner_of(h);
  if ((tris_[f].keep >> k) & 1) return (tris_[f].keep >> (3 + k)) & 1;
  // Only asked of interior non-sharp edges (kept() tests those first). Both halves get the
  // one decision, taken from the edge's first half-edge seen, as the whole level's is one.
  const HalfedgeId t = twin(h);
  const bool keep = flip_folds(h);
  for (const HalfedgeId g : {h, t}) {
    Tri& x = tris_[Mesh::face(g)];
    x.keep |= static_cast<std::uint8_t>((1 << corner_of(g)) | (keep ? 8 << corner_of(g) : 0));
  }
  return keep;
}

Vec3 AdaptiveSqrt3::Hierarchy::stencil_face_point(VertexId q) {
  if (stencil_known_[q]) return stencil_pos_[q];
  const FaceId t = verts_[q].tri;
  const int l = level(t);
  std::vector<FaceId> tris{t};
  for (std::uint8_t k = 0; k < 3; ++k) gather_fan(he(t, k), tris);
  const Patch patch = build_patch(std::move(tris), l);
  const Vec3 p = stencil_.face_point(step_of(patch, l), FaceId(0));
  stencil_pos_[q] = p;
  stencil_known_[q] = 1;
  return p;
}

Vec3 AdaptiveSqrt3::Hierarchy::guard_view(VertexId v, int l) {
  return verts_[v].origin == Origin::FacePoint ? stencil_face_point(v) : position(v, l);
}

bool AdaptiveSqrt3::Hierarchy::folds(const std::array<VertexId, 3>& c, int l, const Vec3& smooth,
                                     VertexId moved, const Vec3& at) {
  std::array<Vec3, 3> p;
  for (int i = 0; i < 3; ++i) p[i] = c[i] == moved ? at : guard_view(c[i], l);
  const Vec3 n = triangle_normal(p[0], p[1], p[2]);
  const double len = norm(n) * norm(smooth);
  return len > 0 && dot(n, smooth) < cos_fold_ * len;
}

// sqrt3_host's guard_sqrt3_folds for the one face point q of face f, in its stages: the
// stencil's point, 1/2 and 1/4 of the way from f's centroid, the centroid (the linear
// split), then 1/3 and 2/3 of the way towards f's largest-angle corner; the first stage at
// which no fine face round q folds. The other points are the stencil's (the uniform host
// iterates over the whole level instead; its later rounds, which keep more flips after
// the pulls, are not done here).
Vec3 AdaptiveSqrt3::Hierarchy::guard_face_point(VertexId q, const Vec3& stencil) {
  const FaceId f = verts_[q].tri;
  const int l = level(f) + 1;
  struct Fine {
    std::array<VertexId, 3> c;
    Vec3 smooth;
  };
  std::array<Fine, 6> fine;
  int n = 0;
  for (std::uint8_t k = 0; k < 3; ++k) {
    const HalfedgeId h = he(f, k);
    const HalfedgeId t = twin(h);
    if (kept(h)) {
      fine[n++] = {{from(h), to(h), q},
                   sector_normal(h) + sector_normal(Mesh::next(h)) + apex_normal(h)};
      continue;
    }
    const VertexId across = apex(t);
    fine[n++] = {{from(h), across, q}, sector_normal(h) + apex_normal(t) + apex_normal(h)};
    fine[n++] = {{to(h), q, across}, sector_normal(t) + apex_normal(h) + apex_normal(t)};
  }
  auto any_folds = [&](const Vec3& at) {
    for (int i = 0; i < n; ++i)
      if (folds(fine[i].c, l, fine[i].smooth, q, at)) return true;
    return false;
  };
  if (!any_folds(stencil)) return stencil;
  verts_[q].pulled = true;
  const std::array<Vec3, 3> p = {position(tris_[f].v[0], l), position(tris_[f].v[1], l),
                                 position(tris_[f].v[2], l)};
  const Vec3 centroid = (p[0] + p[1] + p[2]) * (1.0 / 3.0);
  int obtuse = 0;
  double best = -2;
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = normalized(p[(k + 1) % 3] - p[k]), v = normalized(p[(k + 2) % 3] - p[k]);
    const double cosine = -dot(u, v);  // larger for a larger angle
    if (cosine > best) best = cosine, obtuse = k;
  }
  Vec3 at = stencil;
  for (const double scale : {0.5, 0.25, 0.0}) {
    at = centroid + scale * (stencil - centroid);
    if (!any_folds(at)) return at;
  }
  for (const double t : {1.0 / 3.0, 2.0 / 3.0}) {
    at = centroid + t * (p[obtuse] - centroid);
    if (!any_folds(at)) return at;
  }
  return at;
}

// sqrt3_host's Sqrt3FoldTest::flip_folds: one of the two flipped children (a, q_g, q_f),
// (b, q_f, q_g) turns more than kSqrt3FoldAngleDeg from its smooth normals, or the quad
// (a, q_g, b, q_f) is not convex seen along the edge's smooth normal. With the points of
// the level above (the stencil's) and the sector normals of h's level.
bool AdaptiveSqrt3::Hierarchy::flip_folds(HalfedgeId h) {
  const int l = level(Mesh::face(h)) + 1;
  const HalfedgeId t = twin(h);
  const VertexId a = from(h), b = to(h), qf = apex(h), qg = apex(t);
  const Vec3 nf = apex_normal(h), ng = apex_normal(t);
  const Vec3 nh = sector_normal(h), nt = sector_normal(t);
  if (folds({a, qg, qf}, l, nh + ng + nf)) return true;
  if (folds({b, qf, qg}, l, nt + nf + ng)) return true;
  const Vec3 edge_normal = nh + sector_normal(Mesh::next(h)) + nt + sector_normal(Mesh::next(t));
  const Vec3 pa = guard_view(a, l), pb = guard_view(b, l), pf = guard_view(qf, l),
             pg = guard_view(qg, l);
  return dot(cross(pg - pa, pf - pa), edge_normal) <= 0 ||
         dot(cross(pf - pb, pg - pb), edge_normal) <= 0;
}

// The smooth normal at apex(h): the mean of its face's corner normals, or at a trisection
// point the mean of its edge's two corners weighted by nearness.
Vec3 AdaptiveSqrt3::Hierarchy::apex_normal(HalfedgeId h) {
  const FaceId f = Mesh::face(h);
  const HalfedgeId s = trisects(level(f)) ? sharp_of(f) : HalfedgeId();
  if (!s.valid())
    return normalized(sector_normal(he(f, 0)) + sector_normal(he(f, 1)) + sector_normal(he(f, 2)));
  const Vec3 na = sector_normal(s), nb = sector_normal(Mesh::next(s));
  return h == Mesh::next(s) ? normalized(na + 2.0 * nb) : normalized(2.0 * na + nb);
}

// split4_host's sector_normals for the one corner from(h) of face(h), on h's level: the
// angle-weighted mean of the unit normals of the faces round from(h) between the sharp
// edges (or the boundary) on either side of h's face.
Vec3 AdaptiveSqrt3::Hierarchy::sector_normal(HalfedgeId h) {
  constexpr int kMaxValence = 1 << 16;
  const FaceId f = Mesh::face(h);
  const std::uint8_t k = corner_of(h);
  const auto known = static_cast<std::uint8_t>(kNormalKnown << k);
  if (tris_[f].flags & known) {
    const std::array<float, 9>& c = corner_normal_[f];
    return Vec3{c[3 * k], c[3 * k + 1], c[3 * k + 2]};
  }
  const int l = level(f);
  const Vec3 p = position(from(h), l);
  Vec3 sum{};
  auto add = [&](HalfedgeId c) {
    const Vec3 a = position(to(c), l) - p;
    const Vec3 b = position(opposite(c), l) - p;
    sum += std::atan2(norm(cross(a, b)), dot(a, b)) * normalized(cross(a, b));
  };
  add(h);
  bool closed = false;
  int steps = 0;
  for (HalfedgeId c = h;;) {  // counter-clockwise, across prev(c)
    const HalfedgeId in = Mesh::prev(c);
    if (sharp(in)) break;
    const HalfedgeId next = twin(in);
    if (!next.valid()) break;
    if (next == h) {
      closed = true;
      break;
    }
    c = next;
    add(c);
    if (++steps > kMaxValence) throw internal("a vertex fan does not close");
  }
  if (!closed) {
    for (HalfedgeId c = h;;) {  // clockwise, across c
      if (sharp(c)) break;
      const HalfedgeId across = twin(c);
      if (!across.valid()) break;
      c = Mesh::next(across);
      add(c);
      if (++steps > kMaxValence) throw internal("a vertex fan does not close");
    }
  }
  // Stored and returned as floats: the same value whether computed now or read back.
  const Vec3 n = normalized(sum);
  std::array<float, 9>& c = corner_normal_[f];
  c[3 * k] = static_cast<float>(n.x);
  c[3 * k + 1] = static_cast<float>(n.y);
  c[3 * k + 2] = static_cast<float>(n.z);
  tris_[f].flags |= known;
  return Vec3{c[3 * k], c[3 * k + 1], c[3 * k + 2]};
}

}  // namespace stlrefine
