// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 host's fold guard (issue 17 item 2), sqrt3_host's with the same test
// and limit (kSqrt3FoldAngleDeg) against the level's sector normals, one edge and one face
// point at a time. A hierarchy made one triangle at a time does not see the level, so the
// uniform host's iterations over the level are unrolled into a fixed depth of local ones,
// each decision made once from the decisions of the depth before (cached per edge and per
// face point), so the result does not depend on the order triangles are made in:
// - pass 0: an edge whose flip folds with the stencil's points is not flipped (the uniform
//   host's first round); a face point whose fine faces fold moves towards its face's
//   centroid in the uniform host's stages, in kGuardRounds rounds, each against its
//   neighbours' points of the round before (the uniform host moves the points of a
//   folding face together, and repeats until none moves);
// - pass 1: an edge whose flip still folds with pass 0's points is not flipped either
//   (the uniform host's later rounds), and the face points are pulled again, from the
//   stencil's, with those flips.
// Judged against the stencil's points alone (one round, one pass), the rounded box kept
// 165-167 faces folded (> 90 degrees from the truth) at tol 2e-3, 4 steps, uniform 0
// (bench/results-issue17-s6-adaptive.md; tests/core/adaptive_sqrt3_guard_test.cpp).
#include <array>
#include <cmath>
#include <utility>

#include "core/schemes/adaptive_sqrt3_hierarchy.h"
#include "core/schemes/sqrt3_guard_stage.h"

namespace stlrefine {

using namespace adaptive_sqrt3_detail;

bool AdaptiveSqrt3::Hierarchy::unflipped(HalfedgeId h, int pass) {
  if (!guarded_) return false;
  const FaceId f = Mesh::face(h);
  const std::uint8_t k = corner_of(h);
  auto bits = [&](FaceId x) -> std::uint8_t& {
    return pass == kGuardPasses - 1 ? tris_[x].keep : tris_[x].keep_first;
  };
  if ((bits(f) >> k) & 1) return (bits(f) >> (3 + k)) & 1;
  // Only asked of interior non-sharp edges (kept() tests those first). Both halves get the
  // one decision, taken from the edge's first half-edge seen, as the whole level's is one.
  // A flip kept by a pass stays kept.
  const HalfedgeId t = twin(h);
  bool keep = pass > 0 && unflipped(h, pass - 1);
  if (!keep && pass > 0) {  // with both face points unpulled, the pass before's decision
    bool moved = false;
    for (const VertexId q : {apex(h), apex(t)})
      moved |=
          verts_[q].origin == Origin::FacePoint && guard_stage(q, pass - 1, kGuardRounds - 1) > 0;
    keep = moved && flip_folds(h, pass);
  } else if (!keep) {
    keep = flip_folds(h, pass);
  }
  for (const HalfedgeId g : {h, t})
    bits(Mesh::face(g)) |=
        static_cast<std::uint8_t>((1 << corner_of(g)) | (keep ? 8 << corner_of(g) : 0));
  return keep;
}

Vec3 AdaptiveSqrt3::Hierarchy::stencil_face_point(VertexId q) {
  GuardPoint& g = guard_point_[q];  // Chunked: stays valid while the hierarchy grows
  if (g.stencil_known) return g.stencil;
  const FaceId t = verts_[q].tri;
  const int l = level(t);
  std::vector<FaceId> tris{t};
  for (std::uint8_t k = 0; k < 3; ++k) gather_fan(he(t, k), tris);
  const Patch patch = build_patch(std::move(tris), l);
  g.stencil = stencil_.face_point(step_of(patch, l), FaceId(0));
  g.stencil_known = true;
  return g.stencil;
}

Vec3 AdaptiveSqrt3::Hierarchy::guard_view(VertexId v, int l, View view) {
  // Only the face points of level l are being decided; a face point of a coarser level is
  // an old vertex here, at its position (its stencil point had been taken for it, so the
  // guard judged the faces round a pulled old vertex with a point it was not at).
  if (verts_[v].origin != Origin::FacePoint || verts_[v].level != l) return position(v, l);
  if (view.pass < 0) return stencil_face_point(v);
  return stage_point(v, guard_stage(v, view.pass, view.round));
}

bool AdaptiveSqrt3::Hierarchy::folds(const std::array<VertexId, 3>& c, int l, const Vec3& smooth,
                                     FaceId f, FaceId g, View view, VertexId moved,
                                     const Vec3& at) {
  std::array<Vec3, 3> p;
  for (int i = 0; i < 3; ++i) p[i] = c[i] == moved ? at : guard_view(c[i], l, view);
  const Vec3 n = triangle_normal(p[0], p[1], p[2]);
  const double len = norm(n) * norm(smooth);
  if (len > 0 && dot(n, smooth) < cos_fold_ * len) return true;
  return sqrt3_degenerate(p, n, [&] {
    const Sqrt3Shape sf = shape(f);
    return std::pair(sf, g == f ? sf : shape(g));
  });
}

// Triangle t at its level's positions, for the degenerate test.
Sqrt3Shape AdaptiveSqrt3::Hierarchy::shape(FaceId t) {
  const int l = level(t);
  const std::array<Vec3, 3> p = {position(tris_[t].v[0], l), position(tris_[t].v[1], l),
                                 position(tris_[t].v[2], l)};
  return sqrt3_shape(p, triangle_normal(p[0], p[1], p[2]));
}

// sqrt3_host's stages (sqrt3_guard_stage_point) for the face point q of face f.
Vec3 AdaptiveSqrt3::Hierarchy::stage_point(VertexId q, int stage) {
  const Vec3 stencil = stencil_face_point(q);
  if (stage == 0) return stencil;
  const FaceId f = verts_[q].tri;
  const int l = level(f) + 1;
  return sqrt3_guard_stage_point(
      {position(tris_[f].v[0], l), position(tris_[f].v[1], l), position(tris_[f].v[2], l)}, stencil,
      stage);
}

// sqrt3_host's guard_sqrt3_folds for the one face point q of face f, with the flips of pass
// `pass`: the first stage, from its stage of the round before on (round 0: from the
// stencil's point), at which no fine face round q folds with the other face points of the
// round before (round 0: the stencil's); the last stage when every one folds. The uniform
// host moves the face points of a folding face together; here each is pulled against its
// neighbours' points of the round before, so that where the neighbour across a flipped
// edge was pulled too, q sees it (judged against the stencil's points alone, 7-12 flipped
// faces per rounded box were left more than 60 degrees off the truth after one step,
// uniform 0).
int AdaptiveSqrt3::Hierarchy::guard_stage(VertexId q, int pass, int round) {
  {
    const GuardPoint& g = guard_point_[q];
    if ((g.known[pass] >> round) & 1) return g.stage[pass][round];
  }
  const FaceId f = verts_[q].tri;
  auto remember = [&](int stage) {
    GuardPoint& g = guard_point_[q];
    g.stage[pass][round] = static_cast<std::uint8_t>(stage);
    g.known[pass] |= static_cast<std::uint8_t>(1 << round);
    return stage;
  };
  // Where what q sees has not changed since the round (or pass) before, neither has its
  // stage: most face points are never pulled, and this spares them the later rounds.
  bool unchanged = true;
  if (round > 0) {  // q's neighbours across its flips stayed where they were
    for (std::uint8_t k = 0; k < 3 && unchanged; ++k) {
      const HalfedgeId h = he(f, k);
      if (kept(h, pass)) continue;
      const VertexId n = apex(twin(h));
      if (verts_[n].origin != Origin::FacePoint) continue;
      unchanged =
          guard_stage(n, pass, round - 1) == (round == 1 ? 0 : guard_stage(n, pass, round - 2));
    }
    if (unchanged) return remember(guard_stage(q, pass, round - 1));
  } else if (pass > 0) {  // the same flips as the pass before
    for (std::uint8_t k = 0; k < 3 && unchanged; ++k)
      unchanged = kept(he(f, k), pass) == kept(he(f, k), pass - 1);
    if (unchanged) return remember(guard_stage(q, pass - 1, 0));
  }
  const int first = round == 0 ? 0 : guard_stage(q, pass, round - 1);
  const View view = round == 0 ? View{} : View{pass, round - 1};
  const int l = level(f) + 1;
  struct Fine {
    std::array<VertexId, 3> c;
    Vec3 smooth;
    FaceId across;  // the other coarse triangle it is made from (f for a kept child)
  };
  std::array<Fine, 6> fine;
  int n = 0;
  for (std::uint8_t k = 0; k < 3; ++k) {
    const HalfedgeId h = he(f, k);
    const HalfedgeId t = twin(h);
    if (kept(h, pass)) {
      fine[n++] = {
          {from(h), to(h), q}, sector_normal(h) + sector_normal(Mesh::next(h)) + apex_normal(h), f};
      continue;
    }
    const VertexId across = apex(t);
    const FaceId g = Mesh::face(t);
    fine[n++] = {{from(h), across, q}, sector_normal(h) + apex_normal(t) + apex_normal(h), g};
    fine[n++] = {{to(h), q, across}, sector_normal(t) + apex_normal(h) + apex_normal(t), g};
  }
  auto any_folds = [&](const Vec3& at) {
    for (int i = 0; i < n; ++i)
      if (folds(fine[i].c, l, fine[i].smooth, f, fine[i].across, view, q, at)) return true;
    return false;
  };
  constexpr int kLastStage = 5;
  int stage = first;
  while (stage < kLastStage && any_folds(stage_point(q, stage))) ++stage;
  return remember(stage);
}

// sqrt3_host's Sqrt3FoldTest::flip_folds: one of the two flipped children (a, q_g, q_f),
// (b, q_f, q_g) turns more than kSqrt3FoldAngleDeg from its smooth normals, or the quad
// (a, q_g, b, q_f) is not convex seen along the edge's smooth normal. With the sector
// normals of h's level and the points of the level above: pass 0 the stencil's, a later
// pass those of the pass before after its last round.
bool AdaptiveSqrt3::Hierarchy::flip_folds(HalfedgeId h, int pass) {
  const View view = pass == 0 ? View{} : View{pass - 1, kGuardRounds - 1};
  const int l = level(Mesh::face(h)) + 1;
  const HalfedgeId t = twin(h);
  const VertexId a = from(h), b = to(h), qf = apex(h), qg = apex(t);
  const Vec3 nf = apex_normal(h), ng = apex_normal(t);
  const Vec3 nh = sector_normal(h), nt = sector_normal(t);
  const FaceId f = Mesh::face(h), g = Mesh::face(t);
  if (folds({a, qg, qf}, l, nh + ng + nf, f, g, view)) return true;
  if (folds({b, qf, qg}, l, nt + nf + ng, f, g, view)) return true;
  const Vec3 edge_normal = nh + sector_normal(Mesh::next(h)) + nt + sector_normal(Mesh::next(t));
  const Vec3 pa = guard_view(a, l, view), pb = guard_view(b, l, view), pf = guard_view(qf, l, view),
             pg = guard_view(qg, l, view);
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
