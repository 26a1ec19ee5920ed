// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 host's fold guard (issue 17 item 2), the topological half of
// sqrt3_host's: an edge whose flip would fold is not flipped, decided once per edge of the
// hierarchy with the same test and limit (kSqrt3FoldAngleDeg) against the level's sector
// normals. The geometric half of the uniform host (face points pulled towards their face's
// centroid where a child still folds, in rounds over the whole level) is not done here: it
// moves points by what the whole level does, which a hierarchy made one triangle at a time
// does not see. So the adaptive points stay the stencil's; where the uniform host pulls
// points, the two differ (tests/core/adaptive_sqrt3_guard_test.cpp).
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

bool AdaptiveSqrt3::Hierarchy::folds(const std::array<VertexId, 3>& c, int l, const Vec3& smooth) {
  const Vec3 n = triangle_normal(position(c[0], l), position(c[1], l), position(c[2], l));
  const double len = norm(n) * norm(smooth);
  return len > 0 && dot(n, smooth) < cos_fold_ * len;
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
  const Vec3 pa = position(a, l), pb = position(b, l), pf = position(qf, l), pg = position(qg, l);
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
  const int l = level(Mesh::face(h));
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
  return normalized(sum);
}

}  // namespace stlrefine
