// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/sqrt3_host.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/geometry/pn_centroid.h"
#include "core/parallel.h"
#include "core/refine.h"
#include "core/schemes/crease_rules.h"
#include "core/schemes/dominant_planes.h"
#include "core/schemes/lsf_rules.h"
#include "core/schemes/split4_host.h"
#include "core/schemes/sqrt3_degenerate.h"
#include "core/schemes/sqrt3_guard_stage.h"

namespace stlrefine {

namespace {

constexpr std::uint8_t kNoSharpCorner = 3;

// One fine triangle: corners, twins and edges of its half-edges 3h+0, 3h+1, 3h+2.
struct FineFace {
  std::array<VertexId, 3> corner;
  std::array<HalfedgeId, 3> twin;
  std::array<EdgeId, 3> edge;
};

// Where every fine vertex, face and edge of one sqrt3 step comes from, derived from the
// coarse mesh by index arithmetic. Fine face h belongs to coarse half-edge h (a -> b in
// coarse face f, apex c); its half-edges are 3h+0, 3h+1, 3h+2.
//
//   flipped h (non-sharp):      kept h (sharp or unflipped):  cut h (sharp, even step):
//          p                            p                            c
//         / \   fine face h            / \   fine face h           / \   fine face h
//        a---r  = (a, r, p)           a---b  = (a, b, p)          m1--m2 = (m1, m2, c)
//   p = apex(h), r = apex of the     (the 1-to-3 child)           (middle one of the three
//   twin's face                                                    children of a cut face)
//
// apex(h) is the face point of face(h), or, when face(h) has no face point (it lies on a
// sharp edge s in an even step), the trisection point of s that h's sub-triangle touches.
// A non-sharp edge is kept (left unflipped) when the fold guard says its flip would fold
// (unflipped_). Fine edges: coarse edge e -> e (the flipped diagonal, or the kept / middle
// piece); the edge of fine half-edge 3h+2 (apex(h) -> from(h), in every form) -> E + h; in
// even steps the edge (m2, c) of a sharp face -> E + s, and the first third of a boundary
// edge -> E + 3F + rank among boundary edges.
class Sqrt3Layout {
 public:
  Sqrt3Layout(const Mesh& m, const Features& features, bool trisects,
              std::span<const std::uint8_t> sharp_corner, std::span<const std::uint32_t> rank,
              std::span<const std::uint8_t> unflipped)
      : m_(m),
        features_(features),
        trisects_(trisects),
        sharp_corner_(sharp_corner),
        boundary_rank_(rank),
        unflipped_(unflipped),
        nv_(static_cast<std::uint32_t>(m.num_vertices())),
        nf_(static_cast<std::uint32_t>(m.num_faces())),
        ne_(static_cast<std::uint32_t>(m.num_edges())) {}

  bool sharp(HalfedgeId h) const { return features_.is_sharp(m_.edge(h)); }
  //! The edge of h is not flipped: sharp (in an even step: cut, see sharp_of), on the
  //! boundary, or left unflipped by the fold guard.
  bool kept(HalfedgeId h) const {
    return sharp(h) || !m_.twin(h).valid() || unflipped_[m_.edge(h).idx] != 0;
  }
  //! The sharp half-edge of face f in an even step, or invalid.
  HalfedgeId sharp_of(std::uint32_t f) const {
    if (!trisects_ || sharp_corner_[f] == kNoSharpCorner) return HalfedgeId();
    return HalfedgeId(3 * f + sharp_corner_[f]);
  }
  VertexId face_point(std::uint32_t f) const { return VertexId(nv_ + f); }
  //! Trisection point of sharp half-edge s nearest from(s). Each face along a sharp edge
  //! lends its (unused) face-point slot to the point nearest the start of its half-edge.
  VertexId near_from(HalfedgeId s) const { return VertexId(nv_ + s.idx / 3); }
  //! Trisection point nearest to(s): the twin's near_from, or an extra slot on a boundary.
  VertexId near_to(HalfedgeId s) const {
    const HalfedgeId t = m_.twin(s);
    if (t.valid()) return near_from(t);
    return VertexId(nv_ + nf_ + boundary_rank_[m_.edge(s).idx]);
  }
  EdgeId first_third_of_boundary(HalfedgeId s) const {
    return EdgeId(ne_ + 3 * nf_ + boundary_rank_[m_.edge(s).idx]);
  }
  EdgeId spoke(HalfedgeId h) const { return EdgeId(ne_ + h.idx); }
  static HalfedgeId fine(HalfedgeId h, std::uint32_t k) { return HalfedgeId(3 * h.idx + k); }

  VertexId apex(HalfedgeId h) const {
    const HalfedgeId s = sharp_of(h.idx / 3);
    if (!s.valid()) return face_point(h.idx / 3);
    return h == Mesh::next(s) ? near_to(s) : near_from(s);  // h == prev(s): near a = from(s)
  }

  //! The fine half-edge to(x) -> apex(x), x not cut: half-edge 1 of x's own fine face
  //! when x is kept, else half-edge 0 of its twin's (flipped) fine face.
  HalfedgeId to_apex(HalfedgeId x) const { return kept(x) ? fine(x, 1) : fine(m_.twin(x), 0); }

  //! The corners of fine face h.
  std::array<VertexId, 3> corners(HalfedgeId h) const {
    const HalfedgeId s = sharp_of(h.idx / 3);
    if (h == s) return {near_from(s), near_to(s), m_.opposite(s)};
    if (kept(h)) return {m_.from(h), m_.to(h), apex(h)};
    return {m_.from(h), apex(m_.twin(h)), apex(h)};
  }

  FineFace fine_face(HalfedgeId h) const {
    const HalfedgeId t = m_.twin(h);
    const HalfedgeId s = sharp_of(h.idx / 3);
    if (h == s) {  // the middle child of a cut face (even steps)
      return {
          corners(h),
          {t.valid() ? fine(t, 0) : HalfedgeId(), to_apex(Mesh::next(s)), fine(Mesh::prev(s), 2)},
          {m_.edge(s), spoke(s), spoke(Mesh::prev(s))}};
    }
    FineFace out{corners(h), {}, {}};
    if (kept(h)) {  // (a, b, apex(h))
      out.twin[0] = t.valid() ? fine(t, 0) : HalfedgeId();
      out.edge[0] = m_.edge(h);
      set_to_apex_side(h, out.twin[1], out.edge[1]);
    } else {  // (a, apex(t), apex(h))
      set_to_apex_side(t, out.twin[0], out.edge[0]);
      out.twin[1] = fine(t, 1);
      out.edge[1] = m_.edge(h);
    }
    // Half-edge apex(h) -> a.
    if (!s.valid()) {
      out.twin[2] = to_apex(Mesh::prev(h));
    } else if (h == Mesh::next(s)) {  // m2 -> b: the last third of the sharp edge s
      const HalfedgeId across = m_.twin(s);
      out.twin[2] = across.valid() ? to_apex(Mesh::prev(across)) : HalfedgeId();
    } else {  // h == prev(s): m1 -> c, shared with s's middle child
      out.twin[2] = fine(s, 2);
    }
    out.edge[2] = spoke(h);
    return out;
  }

 private:
  // The twin and edge of the fine half-edge to(x) -> apex(x) inside face(x) (x not cut).
  void set_to_apex_side(HalfedgeId x, HalfedgeId& twin, EdgeId& edge) const {
    const HalfedgeId sx = sharp_of(x.idx / 3);
    if (!sx.valid()) {
      twin = fine(Mesh::next(x), 2);
      edge = spoke(Mesh::next(x));
    } else if (x == Mesh::next(sx)) {
      twin = fine(sx, 1);  // the edge (m2, c) of the middle child
      edge = spoke(sx);
    } else {  // x == prev(sx): to(x) -> m1 is the first third of the sharp edge sx
      const HalfedgeId across = m_.twin(sx);
      twin = across.valid() ? fine(Mesh::next(across), 2) : HalfedgeId();
      edge = across.valid() ? spoke(Mesh::next(across)) : first_third_of_boundary(sx);
    }
  }

  const Mesh& m_;
  const Features& features_;
  bool trisects_;
  std::span<const std::uint8_t> sharp_corner_;
  std::span<const std::uint32_t> boundary_rank_;
  std::span<const std::uint8_t> unflipped_;
  std::uint32_t nv_, nf_, ne_;
};

// Per face in an even step: which corner's half-edge is sharp (kNoSharpCorner for none).
// A face with two sharp edges cannot occur after an odd step of this host.
BigVector<std::uint8_t> sharp_corners(const Mesh& m, const Features& features) {
  BigVector<std::uint8_t> corner(m.num_faces());
  std::atomic<bool> several{false};
  parallel_for_each_index(m.num_faces(), [&](std::size_t f) {
    std::uint8_t c = kNoSharpCorner;
    for (std::uint8_t k = 0; k < 3; ++k) {
      if (!features.is_sharp(m.edge(HalfedgeId(static_cast<std::uint32_t>(3 * f + k))))) continue;
      if (c != kNoSharpCorner) several.store(true, std::memory_order_relaxed);
      c = k;
    }
    corner[f] = c;
  });
  if (several)
    throw Error(ErrorCode::Internal, "sqrt3_parity",
                "sqrt3: a trisecting step met a face with two sharp edges");
  return corner;
}

// Rank of every boundary edge among the boundary edges (its extra trisection point and
// first third get the slots after the face-indexed ones). Returns the count.
std::uint32_t rank_boundary_edges(const Mesh& m, const Features& features,
                                  BigVector<std::uint32_t>& rank) {
  std::uint32_t count = 0;
  rank.resize(m.num_edges());
  for (std::uint32_t e = 0; e < m.num_edges(); ++e)
    if (features.is_sharp(EdgeId(e)) && m.is_boundary(EdgeId(e))) rank[e] = count++;
  return count;
}

// The smooth surface's normals at the fine faces of one step (issue 17 item 2), from the
// coarse level's sector normals (split4_host.h): at an old vertex the one of its corner in
// the coarse face the fine face belongs to, at a face point the mean of its face's three
// corner normals, at a trisection point the mean of its edge's two corners weighted by
// nearness. A fine face folds when its normal is more than kFoldAngleDeg from the mean of
// its corners' smooth normals, or when it is thinner than the float grid of its coordinates
// while the coarse faces it is made from are not (degenerate).
class Sqrt3FoldTest {
 public:
  Sqrt3FoldTest(const Mesh& m, const Sqrt3Layout& layout, std::span<const Vec3> corner,
                std::span<const Vec3> pos)
      : m_(m),
        layout_(layout),
        corner_(corner),
        pos_(pos),
        cos_fold_(std::cos(kSqrt3FoldAngleDeg * std::numbers::pi / 180.0)) {}

  //! Fine face h, with the current flips (layout.kept) and positions.
  bool folds(HalfedgeId h) const {
    return folds(layout_.corners(h), smooth_normal(h), [&] {
      const std::uint32_t f = h.idx / 3;
      // A flipped child spans its coarse face and the twin's; a kept or cut one its own face.
      return parent_shapes(f, layout_.kept(h) ? f : m_.twin(h).idx / 3);
    });
  }

  //! Whether flipping the (non-sharp, interior) edge of h, a -> b, would fold: one of the
  //! two flipped children (a, q_g, q_f), (b, q_f, q_g) turns more than kFoldAngleDeg from
  //! its smooth normals, or the quad (a, q_g, b, q_f) is not convex seen along the edge's
  //! smooth normal (a child reversed in the tangent plane). q_f = apex(h), q_g = apex(t).
  //! The smooth normals at the three corners of fine face h, in Sqrt3Layout::corners order
  //! (unit): carried to the fine level as its Level::smooth_normals.
  std::array<Vec3, 3> corner_normals(HalfedgeId h) const {
    const HalfedgeId s = layout_.sharp_of(h.idx / 3);
    if (h == s) {
      const Vec3 &na = corner_[s.idx], &nb = corner_[Mesh::next(s).idx];
      return {normalized(2.0 * na + nb), normalized(na + 2.0 * nb), corner_[Mesh::prev(s).idx]};
    }
    if (layout_.kept(h)) return {corner_[h.idx], corner_[Mesh::next(h).idx], apex_normal(h)};
    return {corner_[h.idx], apex_normal(m_.twin(h)), apex_normal(h)};
  }

  bool flip_folds(HalfedgeId h) const {
    const HalfedgeId t = m_.twin(h);
    const VertexId a = m_.from(h), b = m_.to(h), qf = layout_.apex(h), qg = layout_.apex(t);
    const Vec3 nf = apex_normal(h), ng = apex_normal(t);
    auto parents = [&] { return parent_shapes(h.idx / 3, t.idx / 3); };
    if (folds({a, qg, qf}, corner_[h.idx] + ng + nf, parents)) return true;
    if (folds({b, qf, qg}, corner_[t.idx] + nf + ng, parents)) return true;
    const Vec3 edge_normal =
        corner_[h.idx] + corner_[Mesh::next(h).idx] + corner_[t.idx] + corner_[Mesh::next(t).idx];
    const Vec3 &pa = pos_[a.idx], &pb = pos_[b.idx], &pf = pos_[qf.idx], &pg = pos_[qg.idx];
    return dot(cross(pg - pa, pf - pa), edge_normal) <= 0 ||
           dot(cross(pf - pb, pg - pb), edge_normal) <= 0;
  }

 private:
  Vec3 face_normal_of(std::uint32_t f) const {
    return normalized(corner_[3 * f] + corner_[3 * f + 1] + corner_[3 * f + 2]);
  }
  // The smooth normal at apex(h) (see Sqrt3Layout::apex).
  Vec3 apex_normal(HalfedgeId h) const {
    const HalfedgeId s = layout_.sharp_of(h.idx / 3);
    if (!s.valid()) return face_normal_of(h.idx / 3);
    const Vec3 &na = corner_[s.idx], &nb = corner_[Mesh::next(s).idx];
    return h == Mesh::next(s) ? normalized(na + 2.0 * nb) : normalized(2.0 * na + nb);
  }
  // The mean smooth normal of fine face h (unnormalised sum of its corners').
  Vec3 smooth_normal(HalfedgeId h) const {
    const HalfedgeId s = layout_.sharp_of(h.idx / 3);
    if (h == s) {
      const Vec3 &na = corner_[s.idx], &nb = corner_[Mesh::next(s).idx];
      return normalized(2.0 * na + nb) + normalized(na + 2.0 * nb) + corner_[Mesh::prev(s).idx];
    }
    if (layout_.kept(h)) return corner_[h.idx] + corner_[Mesh::next(h).idx] + apex_normal(h);
    return corner_[h.idx] + apex_normal(m_.twin(h)) + apex_normal(h);
  }
  // Triangle c folds against `smooth`, or is degenerate (sqrt3_degenerate; parents() gives
  // the shapes of the coarse faces it is made from).
  template <class Parents>
  bool folds(const std::array<VertexId, 3>& c, const Vec3& smooth, Parents&& parents) const {
    const std::array<Vec3, 3> p = {pos_[c[0].idx], pos_[c[1].idx], pos_[c[2].idx]};
    const Vec3 n = triangle_normal(p[0], p[1], p[2]);
    const double len = norm(n) * norm(smooth);
    if (len > 0 && dot(n, smooth) < cos_fold_ * len) return true;
    return sqrt3_degenerate(p, n, parents);
  }
  Sqrt3Shape coarse_shape(std::uint32_t f) const {
    const auto [a, b, c] = m_.face_vertices(FaceId(f));
    const std::array<Vec3, 3> p = {m_.position(a), m_.position(b), m_.position(c)};
    return sqrt3_shape(p, triangle_normal(p[0], p[1], p[2]));
  }
  std::pair<Sqrt3Shape, Sqrt3Shape> parent_shapes(std::uint32_t f, std::uint32_t g) const {
    const Sqrt3Shape sf = coarse_shape(f);
    return {sf, g == f ? sf : coarse_shape(g)};
  }

  const Mesh& m_;
  const Sqrt3Layout& layout_;
  std::span<const Vec3> corner_;
  std::span<const Vec3> pos_;
  double cos_fold_;
};

// The topological half of the fold guard: marks in `unflipped` every non-sharp interior
// edge whose flip folds (Sqrt3FoldTest::flip_folds) with the points of the moment. Such an
// edge stays, like a sharp edge in an odd step: the face points of its two faces join both
// of its ends. With `changed` (per new vertex v, at v - nv: moved since the last call), only
// the edges with an apex that moved: flip_folds reads the positions of the edge's ends (old
// vertices, fixed) and its two apexes alone, so an edge whose flip passed before and whose
// apexes stayed still passes, and the guard's later rounds re-test the few edges round the
// points they moved instead of every edge. Returns how many edges it marked.
std::size_t keep_folding_flips(const Mesh& m, const Sqrt3Layout& layout, const Sqrt3FoldTest& test,
                               std::span<std::uint8_t> unflipped,
                               std::span<const std::uint8_t> changed = {}) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  std::atomic<std::size_t> marked{0};
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    const HalfedgeId h = m.halfedge(edge);
    if (unflipped[e] || layout.kept(h)) return;  // sharp, boundary or already kept
    if (!changed.empty() && !changed[layout.apex(h).idx - nv] &&
        !changed[layout.apex(m.twin(h)).idx - nv])
      return;
    if (!test.flip_folds(h)) return;
    unflipped[e] = 1;
    marked.fetch_add(1, std::memory_order_relaxed);
  });
  return marked.load();
}

// The geometric half of the fold guard, the counterpart of split4's guard_folds. Where a
// fine face folds (Sqrt3FoldTest), its face points are pulled towards the centroid of their
// face's (new) corner points in steps (1/2, 1/4, then the centroid itself: the linear 1-to-3
// split), then towards the face's largest-angle corner. A folding face with no face point
// left to move but trisection points (a child of a face cut along a sharp edge) has the two
// trisection points of that edge pulled towards the thirds of its chord in steps (1/2, 1/4,
// then the thirds: the linear rule), the same points on both sides of the crease, so the
// crease stays a curve of the mesh through its old vertices. Old vertices never move, so an
// interpolating stencil stays interpolating. Marks the points it moves in `changed` (per new
// vertex v, at v - nv). Returns how many face points and sharp edges' trisection pairs moved.
std::size_t guard_sqrt3_folds(const Mesh& m, const Sqrt3Layout& layout, const Sqrt3FoldTest& test,
                              BigVector<Vec3>& pos, std::span<std::uint8_t> changed) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::uint32_t nf = static_cast<std::uint32_t>(m.num_faces());
  const std::uint32_t nh = 3 * nf;
  // Face point stages: the stencil's point, 1/2 and 1/4 of the way from the centroid, the
  // centroid, then towards the face's largest-angle corner. Trisection pair stages: the
  // stencil's points, 1/2 and 1/4 of the way from the chord's thirds, the thirds.
  constexpr std::size_t kFaceStages = 6;  // sqrt3_guard_stage_point's stages 0-5
  constexpr std::array<double, 4> kCreaseScale = {1.0, 0.5, 0.25, 0.0};
  auto folds = [&](std::uint32_t h) { return test.folds(HalfedgeId(h)); };
  std::vector<std::uint8_t> folding(nh, 0);
  parallel_for_each_index(
      nh, [&](std::size_t h) { folding[h] = folds(static_cast<std::uint32_t>(h)); });
  if (std::find(folding.begin(), folding.end(), 1) == folding.end()) return 0;
  // Items that move: face point of face f (item f), or the trisection pair of the sharp edge
  // whose canonical half-edge lies in face f (item nf + f).
  std::vector<std::uint8_t> stage(2 * std::size_t(nf), 0);
  std::vector<std::array<Vec3, 2>> original(2 * std::size_t(nf));
  // The sharp half-edge of a boundary edge's extra trisection slot (v - nv - nf).
  std::vector<HalfedgeId> extra_slot;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const HalfedgeId s = layout.sharp_of(f);
    if (!s.valid() || m.twin(s).valid()) continue;
    const std::uint32_t slot = layout.near_to(s).idx - nv - nf;
    if (extra_slot.size() <= slot) extra_slot.resize(slot + 1);
    extra_slot[slot] = s;
  }
  std::vector<std::uint32_t> todo, touched;
  for (std::uint32_t h = 0; h < nh; ++h)
    if (folding[h]) todo.push_back(h);
  std::fill(folding.begin(), folding.end(), 0);  // from now on: "in touched"
  auto last_stage = [&](std::uint32_t item) {
    return item < nf ? kFaceStages - 1 : kCreaseScale.size() - 1;
  };
  // The items of fine face h that can still move: its face points, or when none can, the
  // trisection pairs of its trisection points.
  auto items_of = [&](std::uint32_t h, std::array<std::uint32_t, 3>& out) {
    int n = 0, crease = 0;
    std::array<std::uint32_t, 3> pairs{};
    for (const VertexId c : layout.corners(HalfedgeId(h))) {
      const std::uint32_t v = c.idx;
      if (v < nv) continue;
      HalfedgeId s;
      if (v < nv + nf) {
        const std::uint32_t f = v - nv;
        s = layout.sharp_of(f);
        if (!s.valid()) {
          if (stage[f] < last_stage(f)) out[n++] = f;
          continue;
        }
      } else {
        s = extra_slot[v - nv - nf];
      }
      const std::uint32_t item = nf + m.halfedge(m.edge(s)).idx / 3;
      if (stage[item] < last_stage(item) &&
          std::find(pairs.begin(), pairs.begin() + crease, item) == pairs.begin() + crease)
        pairs[crease++] = item;
    }
    if (n > 0) return n;
    std::copy(pairs.begin(), pairs.begin() + crease, out.begin());
    return crease;
  };
  auto touch = [&](std::uint32_t h) {
    if (folding[h]) return;
    folding[h] = 1;
    touched.push_back(h);
  };
  // Fine faces using a point of face f: those of f's half-edges and of their twins.
  auto touch_around = [&](std::uint32_t f) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const HalfedgeId g(3 * f + k);
      touch(g.idx);
      if (m.twin(g).valid()) touch(m.twin(g).idx);
    }
  };
  std::size_t moved = 0;
  while (!todo.empty()) {
    touched.clear();
    for (const std::uint32_t h : todo) {
      std::array<std::uint32_t, 3> items{};
      const int n = items_of(h, items);
      for (int i = 0; i < n; ++i) {
        const std::uint32_t item = items[i];
        if (stage[item] >= last_stage(item)) continue;  // moved already by an earlier face
        if (item >= nf) {
          const HalfedgeId s = layout.sharp_of(item - nf);
          const VertexId m1 = layout.near_from(s), m2 = layout.near_to(s);
          if (stage[item] == 0) {
            original[item] = {pos[m1.idx], pos[m2.idx]};
            ++moved;
          }
          const double scale = kCreaseScale[++stage[item]];
          const Vec3 &a = pos[m.from(s).idx], &b = pos[m.to(s).idx];
          const Vec3 t1 = a + (1.0 / 3.0) * (b - a), t2 = a + (2.0 / 3.0) * (b - a);
          pos[m1.idx] = t1 + scale * (original[item][0] - t1);
          pos[m2.idx] = t2 + scale * (original[item][1] - t2);
          changed[m1.idx - nv] = changed[m2.idx - nv] = 1;
          touch_around(s.idx / 3);
          if (m.twin(s).valid()) touch_around(m.twin(s).idx / 3);
          continue;
        }
        const std::uint32_t f = item;
        const VertexId q = layout.face_point(f);
        if (stage[f] == 0) {
          original[f][0] = pos[q.idx];
          ++moved;
        }
        ++stage[f];
        const auto [a, b, c] = m.face_vertices(FaceId(f));
        pos[q.idx] =
            sqrt3_guard_stage_point({pos[a.idx], pos[b.idx], pos[c.idx]}, original[f][0], stage[f]);
        changed[q.idx - nv] = 1;
        touch_around(f);
      }
    }
    std::sort(touched.begin(), touched.end());
    for (const std::uint32_t h : touched) folding[h] = 0;
    todo.clear();
    for (const std::uint32_t h : touched) {
      if (!folds(h)) continue;
      std::array<std::uint32_t, 3> items{};
      if (items_of(h, items) > 0) todo.push_back(h);
    }
  }
  return moved;
}

// Plane rule, the counterpart of split4's keep_dominant_planes, run before the fold guard,
// for a face whose plane dominates its corners (dominant_planes): a CAD part's flat face (two
// big triangles or a fan beside a fillet's thin strips). Its face point goes onto its plane
// (the 12-point rule reaches two rings out and took the fillet's vertices), and its edges to
// faces off the plane are not flipped: a flip joins the flat face's point to the fillet
// face's point, and the two children tilt across what should stay flat (sqrt3-interp made
// the rounded box 1.4 times worse than its input). Such an edge is kept like a crease in an
// odd step, the flat children beside it; the next step keeps it again while the plane still
// dominates its ends. Returns how many face points moved; marks the kept edges in unflipped.
std::size_t keep_dominant_planes(const Mesh& m, const Features& features, const Sqrt3Layout& layout,
                                 std::span<std::uint8_t> unflipped, BigVector<Vec3>& pos) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const DominantPlanes planes = dominant_planes(m, features);
  auto holds = [&](std::uint32_t f) {
    return planes.dominant[3 * f] && planes.dominant[3 * f + 1] && planes.dominant[3 * f + 2];
  };
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const HalfedgeId h = m.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    if (layout.kept(h)) return;  // sharp, boundary or kept already
    const HalfedgeId t = m.twin(h);
    const std::uint32_t f = h.idx / 3, g = t.idx / 3;
    const bool f_holds = planes.dominant[h.idx] && planes.dominant[Mesh::next(h).idx];
    const bool g_holds = planes.dominant[t.idx] && planes.dominant[Mesh::next(t).idx];
    if ((f_holds && !planes.coplanar(m, f, g)) || (g_holds && !planes.coplanar(m, g, f)))
      unflipped[e] = 1;
  });
  std::atomic<std::size_t> moved{0};
  parallel_for_each_index(m.num_faces(), [&](std::size_t fi) {
    const std::uint32_t f = static_cast<std::uint32_t>(fi);
    if (layout.sharp_of(f).valid() || !holds(f)) return;  // no face point, or no plane
    Vec3& q = pos[nv + f];
    if (planes.on_plane(f, q, planes.plane[f].size)) return;
    q = planes.project(f, q);
    moved.fetch_add(1, std::memory_order_relaxed);
  });
  return moved.load();
}

// The smooth surface's normals at the corners of the input level, for the normal check and
// the fold guard (carried to later steps): lsf's guard normals, as LsfStencil makes them
// (lsf::sector_normal per one-sector vertex, then lsf::relax_guard_normals: two-curve normals
// at slivers' midpoints, the chord-symmetry relaxation of uneven rings, the slivers' crease
// sector normals), within the crease sector of each corner. The plain angle-weighted sector
// normals lean towards big flat triangles beside a fillet's strips (the rounded box, seeds
// 9000-9002, first step: the face points' PN centroids 0.67 mm RMS off the truth from them,
// 0.06 from lsf's unrelaxed normals); the relaxation halves the hull shapes' L2 error again
// (sphere 0.29 -> 0.10 of the input's RMS).
BigVector<Vec3> input_smooth_normals(const Mesh& m, const Features& features) {
  std::vector<lsf::GuardVertex> guard(m.num_vertices());
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    guard[i].one_sector = features.kind(v) <= VertexKind::Dart;
    if (!guard[i].one_sector || !m.halfedge(v).valid()) return;
    guard[i].normal = lsf::sector_normal(m, features, m.halfedge(v));
    guard[i].spokes = lsf::ring_spoke_flags(m, v);
  });
  lsf::SectorNormals sectors;
  lsf::relax_guard_normals(m, features, guard, sectors);
  const lsf::GuardNormals normal_of{m, features, guard.data(), &sectors};
  BigVector<Vec3> corner(3 * std::size_t(m.num_faces()));
  parallel_for_each_index(corner.size(), [&](std::size_t h) {
    corner[h] = normal_of(HalfedgeId(static_cast<std::uint32_t>(h)));
  });
  return corner;
}

// Whether v's ring is a lattice's seen along some direction u: valence 6, interior, and the
// ring's departures from a hexagon (d_i + d_i+3 and d_i + d_i+2 - d_i+1 for its spokes d, all
// zero on an affine image of the regular lattice) parallel to one u, over which the ring is
// a graph (its faces keep their orientation seen along u, none edge-on). Then the ring is a
// regular lattice lifted over the plane across u, where the paper's rule reproduces every
// cubic height (a steep cubic's spokes differ by 3x and more): the normal check leaves it.
bool lattice_ring(const Mesh& m, VertexId v) {
  constexpr double kParallel = 0.02, kEdgeOn = 0.1;
  if (m.is_boundary(v)) return false;
  std::array<Vec3, 6> d;
  int n = 0;
  bool too_many = false;
  for_each_outgoing(m, v, [&](HalfedgeId s) {
    if (n == 6) {
      too_many = true;
      return;
    }
    d[n++] = m.position(m.to(s)) - m.position(v);
  });
  if (too_many || n != 6) return false;
  std::array<Vec3, 9> defect;
  double scale = 0;
  for (int k = 0; k < 6; ++k) {
    defect[k] = d[k] + d[(k + 2) % 6] - d[(k + 1) % 6];
    if (k < 3) defect[6 + k] = d[k] + d[k + 3];
    scale = std::max(scale, norm(d[k]));
  }
  const Vec3* largest = &defect[0];
  for (const Vec3& e : defect)
    if (dot(e, e) > dot(*largest, *largest)) largest = &e;
  const Vec3 u = normalized(*largest);
  for (const Vec3& e : defect)
    if (norm(e - dot(e, u) * u) > kParallel * scale) return false;
  if (dot(u, u) == 0) return true;  // a planar lattice
  double sign = 0;
  for (int k = 0; k < 6; ++k) {
    const Vec3 c = cross(d[k], d[(k + 1) % 6]);
    const double along = dot(c, u);
    if (std::abs(along) < kEdgeOn * norm(c) || along * sign < 0) return false;
    sign = along;
  }
  return true;
}

// The normal check's parameters: split4's slack and height fraction; checked from a spoke
// ratio of 2, not 3: sqrt3's hull and torus rings of ratio 2-3 gave face points twice as far
// off as the PN centroids' (seeds 9000-9005, L2 RMS / input, gate 3 -> 2 with lsf's unrelaxed
// normals: torus 0.37 -> 0.28, sphere 0.35 -> 0.29; relaxed: 0.30 -> 0.18, 0.23 -> 0.10). A
// regular lattice's ratio is at most sqrt 2 (a right-angled grid), and lifted lattices of
// any ratio (a steep cubic height field) are left to the paper's rule by lattice_ring.
constexpr NormalCheckParams kSqrt3NormalCheck{
    .slack = 0.25, .width_fraction = 1e-3, .uneven_spokes = 2.0};

// Normal check (issue 17 item 3), ours, the face-point counterpart of split4's
// check_edge_points_against_normals. The interpolatory stencils' lattice weights assume a
// regular ring; on fans, zipped slivers and hull rings their face point lands about as far
// off the surface as the flat centroid (seeds 9000-9002, first step: 0.03-0.08 mm RMS against
// 0.04-0.15 for the centroid), while the PN centroid of the corners' smooth normals is 3-25
// times closer. So the face point of a face with a corner whose longest spoke is at least
// params.uneven_spokes times its shortest (and whose ring is not a lattice_ring) becomes that PN
// centroid P when it is farther from P along the corners' mean normal than params.slack |P -
// centroid| + params.width_fraction (the face's smallest height). On a plane P is the centroid and
// the stencil's point is on the plane: nothing moves. Returns how many face points moved.
std::size_t check_face_points_against_normals(const Mesh& m, const Sqrt3Layout& layout,
                                              std::span<const Vec3> corner,
                                              const NormalCheckParams& params,
                                              BigVector<Vec3>& pos) {
  params.validate();
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  std::vector<std::uint8_t> uneven = uneven_spoke_vertices(m, params.uneven_spokes);
  parallel_for_each_index(nv, [&](std::size_t i) {
    if (uneven[i]) uneven[i] = !lattice_ring(m, VertexId(static_cast<std::uint32_t>(i)));
  });
  std::atomic<std::size_t> moved{0};
  parallel_for_each_index(m.num_faces(), [&](std::size_t fi) {
    const std::uint32_t f = static_cast<std::uint32_t>(fi);
    if (layout.sharp_of(f).valid()) return;  // no face point
    const auto vs = m.face_vertices(FaceId(f));
    if (!uneven[vs[0].idx] && !uneven[vs[1].idx] && !uneven[vs[2].idx]) return;
    const std::array<Vec3, 3> p = {m.position(vs[0]), m.position(vs[1]), m.position(vs[2])};
    const std::array<Vec3, 3> n = {corner[3 * f], corner[3 * f + 1], corner[3 * f + 2]};
    const Vec3 mean = normalized(n[0] + n[1] + n[2]);
    if (dot(mean, mean) == 0) return;
    const Vec3 offset = pn_centroid_offset(p, n);
    const Vec3 reference = (p[0] + p[1] + p[2]) * (1.0 / 3.0) + offset;
    // What the normals cannot resolve: a fraction of the face's smallest height.
    double longest = 0;
    for (int k = 0; k < 3; ++k) longest = std::max(longest, distance(p[k], p[(k + 1) % 3]));
    if (!(longest > 0)) return;
    const double height = norm(cross(p[1] - p[0], p[2] - p[0])) / longest;
    const double allowed = params.slack * norm(offset) + params.width_fraction * height;
    Vec3& q = pos[nv + f];
    if (std::abs(dot(q - reference, mean)) <= allowed) return;
    q = reference;
    moved.fetch_add(1, std::memory_order_relaxed);
  });
  return moved.load();
}

// The whole fold guard of one step. First the flips that fold with the stencil's points are
// not made; then face points move where a fine face still folds (guard_sqrt3_folds); a flip
// that folds after that is not made either, the face points beside it go back to the
// stencil's and the face points move again, up to kRounds times. Returns the face points
// moved; adds the edges left unflipped to `kept`.
std::size_t guard_sqrt3_step(const Mesh& m, const Sqrt3Layout& layout,
                             const BigVector<Vec3>& corner, std::span<std::uint8_t> unflipped,
                             BigVector<Vec3>& pos, std::size_t& kept) {
  constexpr int kRounds = 4;
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::uint32_t nf = static_cast<std::uint32_t>(m.num_faces());
  const Sqrt3FoldTest test(m, layout, corner, pos);
  kept += keep_folding_flips(m, layout, test, unflipped);
  std::vector<Vec3> stencil_points(pos.begin() + nv, pos.begin() + nv + nf);
  std::vector<std::uint8_t> changed(pos.size() - nv, 0);  // new points moved since the flips' test
  std::size_t moved = 0;
  for (int round = 0;; ++round) {
    moved += guard_sqrt3_folds(m, layout, test, pos, changed);
    if (round + 1 == kRounds) break;
    std::vector<std::uint8_t> before(unflipped.begin(), unflipped.end());
    const std::size_t more = keep_folding_flips(m, layout, test, unflipped, changed);
    std::fill(changed.begin(), changed.end(), 0);
    if (more == 0) break;
    kept += more;
    for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
      if (before[e] == unflipped[e]) continue;
      const HalfedgeId h = m.halfedge(EdgeId(e));
      for (const HalfedgeId g : {h, m.twin(h)}) {
        const std::uint32_t f = g.idx / 3;
        if (layout.sharp_of(f).valid()) continue;
        pos[nv + f] = stencil_points[f];
        changed[f] = 1;
      }
    }
  }
  return moved;
}

}  // namespace

std::uint64_t sqrt3_step_bytes(const Level& coarse) {
  const Mesh& m = coarse.mesh;
  const std::size_t nv = m.num_vertices(), ne = m.num_edges(), nf = m.num_faces();
  const bool trisects = coarse.step % 2 == 1;
  std::size_t boundary_edges = 0;
  if (trisects)
    for (std::uint32_t e = 0; e < ne; ++e) boundary_edges += m.is_boundary(EdgeId(e));
  const std::size_t fine_vertices = nv + nf + boundary_edges;
  const std::size_t fine_edges = ne + 3 * nf + boundary_edges;
  std::uint64_t bytes =
      big_vector_bytes<Vec3>(fine_vertices) + 3 * big_vector_bytes<HalfedgeId>(9 * nf) +
      big_vector_bytes<HalfedgeId>(fine_edges) + big_vector_bytes<HalfedgeId>(fine_vertices) +
      big_vector_bytes<std::uint8_t>(fine_edges) + big_vector_bytes<VertexKind>(fine_vertices) +
      big_vector_bytes<std::array<VertexId, 2>>(fine_vertices) +
      // alpha, fine and initial, when the stencil blends per vertex
      big_vector_bytes<double>(fine_vertices) + big_vector_bytes<double>(nv) +
      32 * std::uint64_t(nv) +  // stencil scratch
      // fold guard: sector normals, a flag per fine face, a stage and an original point
      // per coarse face, two lists of fine faces, the stencil's face points; the edges
      // left unflipped (and their copy), a flag per new point (moved since the flips' test)
      big_vector_bytes<Vec3>(3 * nf) + 3 * nf + nf + 2 * sizeof(Vec3) * nf +
      2 * sizeof(std::uint32_t) * 3 * std::uint64_t(nf) + big_vector_bytes<std::uint8_t>(ne) + ne +
      (fine_vertices - nv) +
      dominant_planes_bytes(m) +  // the plane rule's, freed before the guard's
      // the input's smooth normals (lsf's guard records), the normal check's flags
      (sizeof(lsf::GuardVertex) + 1) * std::uint64_t(nv) +
      // the fine level's smooth normals, unless this is the last step
      (coarse.pass_smooth_normals ? big_vector_bytes<Vec3>(9 * nf) : 0);
  if (trisects) bytes += big_vector_bytes<std::uint8_t>(nf) + big_vector_bytes<std::uint32_t>(ne);
  return bytes;
}

Level sqrt3_refine(const Level& coarse, const Sqrt3Stencil& stencil, StepStats& stats,
                   FoldGuard guard) {
  const Mesh& m = coarse.mesh;
  const Features& features = coarse.features;
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::uint32_t nf = static_cast<std::uint32_t>(m.num_faces());
  const std::uint32_t ne = static_cast<std::uint32_t>(m.num_edges());
  const bool trisects = coarse.step % 2 == 1;

  BigVector<std::uint8_t> sharp_corner;
  BigVector<std::uint32_t> boundary_rank;
  std::uint32_t boundary_edges = 0;
  if (trisects) {
    sharp_corner = sharp_corners(m, features);
    boundary_edges = rank_boundary_edges(m, features, boundary_rank);
  }
  // The input level has no alpha yet: the stencil says what it is (or that it needs none).
  BigVector<double> initial_alpha;
  std::span<const double> alpha = coarse.alpha;
  if (alpha.size() != nv) {
    initial_alpha = stencil.initial_alpha(coarse);
    alpha = initial_alpha;
  }
  const Sqrt3Step step{m, features, trisects, alpha, sharp_corner};
  BigVector<std::uint8_t> unflipped(ne, 0);
  const Sqrt3Layout layout(m, features, trisects, sharp_corner, boundary_rank, unflipped);

  const std::size_t fine_vertices = std::size_t(nv) + nf + boundary_edges;
  const std::size_t fine_edges = std::size_t(ne) + 3 * std::size_t(nf) + boundary_edges;
  BigVector<Vec3> positions(fine_vertices);
  stencil.points(
      step, {std::span<Vec3>(positions.data(), nv), std::span<Vec3>(positions.data() + nv, nf)});
  // Trisection points, each once (from the canonical side of its sharp edge).
  if (trisects) {
    parallel_for_each_index(nf, [&](std::size_t fi) {
      const HalfedgeId s = layout.sharp_of(static_cast<std::uint32_t>(fi));
      if (!s.valid() || m.halfedge(m.edge(s)) != s) return;
      const std::array<Vec3, 2> points = stencil.curve_points(step, s);
      positions[layout.near_from(s).idx] = points[0];
      positions[layout.near_to(s).idx] = points[1];
    });
  }
  // The fold guard decides which edges are flipped, so it runs before the topology is made.
  BigVector<Vec3> fine_normals;
  if (guard == FoldGuard::AsStencil && stencil.guards_folds()) {
    // The smooth normals: the input's, carried from step to step (the sector normals of this
    // level follow the faces earlier steps bent, 30-37 degrees off the truth after 3 steps
    // beside the rounded box's fanned corners). For interpolating stencils lsf's relaxed guard
    // normals, which the normal check needs; the approximating ones keep the sector normals
    // their guard was tuned with.
    BigVector<Vec3> estimated;
    const bool carried = coarse.smooth_normals.size() == 3 * std::size_t(nf);
    if (!carried)
      estimated =
          stencil.interpolating() ? input_smooth_normals(m, features) : sector_normals(m, features);
    const BigVector<Vec3>& corner = carried ? coarse.smooth_normals : estimated;
    if (stencil.interpolating()) {
      check_face_points_against_normals(m, layout, corner, kSqrt3NormalCheck, positions);
      keep_dominant_planes(m, features, layout, unflipped, positions);
    }
    std::size_t kept = 0;
    stats.fold_fallbacks += guard_sqrt3_step(m, layout, corner, unflipped, positions, kept);
    stats.fold_fallbacks += kept;
    if (coarse.pass_smooth_normals) {
      const Sqrt3FoldTest normals(m, layout, corner, positions);
      fine_normals = BigVector<Vec3>(9 * std::size_t(nf));
      parallel_for_each_index(3 * std::size_t(nf), [&](std::size_t h) {
        const std::array<Vec3, 3> n =
            normals.corner_normals(HalfedgeId(static_cast<std::uint32_t>(h)));
        std::copy(n.begin(), n.end(), fine_normals.begin() + 3 * h);
      });
    }
  }

  BigVector<VertexId> corner_vertex(9 * std::size_t(nf));
  BigVector<HalfedgeId> twin(9 * std::size_t(nf));
  BigVector<EdgeId> edge_of(9 * std::size_t(nf));
  BigVector<HalfedgeId> edge_halfedge(fine_edges);
  BigVector<HalfedgeId> vertex_halfedge(fine_vertices);
  BigVector<std::uint8_t> sharp(fine_edges);
  BigVector<VertexKind> kind(fine_vertices);
  BigVector<std::array<VertexId, 2>> curve(fine_vertices);
  BigVector<double> fine_alpha(alpha.empty() ? 0 : fine_vertices);

  // New vertices, fine faces and the edges each coarse half-edge owns.
  parallel_for_each_index(nf, [&](std::size_t fi) {
    const std::uint32_t f = static_cast<std::uint32_t>(fi);
    for (std::uint32_t k = 0; k < 3; ++k) {
      const HalfedgeId h(3 * f + k);
      const FineFace face = layout.fine_face(h);
      for (std::uint32_t j = 0; j < 3; ++j) {
        corner_vertex[3 * h.idx + j] = face.corner[j];
        twin[3 * h.idx + j] = face.twin[j];
        edge_of[3 * h.idx + j] = face.edge[j];
      }
      const bool sharp_h = layout.sharp(h);
      const bool cut = trisects && sharp_h;
      const bool kept_whole = !cut && layout.kept(h);
      const EdgeId e = m.edge(h);
      if (m.halfedge(e) == h) {
        edge_halfedge[e.idx] = Sqrt3Layout::fine(h, kept_whole || cut ? 0 : 1);
        sharp[e.idx] = sharp_h;
      }
      const EdgeId own = layout.spoke(h);
      edge_halfedge[own.idx] = Sqrt3Layout::fine(h, cut ? 1 : 2);
      // The spoke of the sub-triangle after a sharp edge s is the last third of s.
      const HalfedgeId s = layout.sharp_of(f);
      sharp[own.idx] = s.valid() && h == Mesh::next(s);
    }

    const HalfedgeId s = layout.sharp_of(f);
    if (!s.valid()) {
      const VertexId q = layout.face_point(f);
      vertex_halfedge[q.idx] = Sqrt3Layout::fine(HalfedgeId(3 * f), 2);
      kind[q.idx] = VertexKind::Smooth;
      curve[q.idx] = {};
      if (!alpha.empty()) {
        const auto [a, b, c] = m.face_vertices(FaceId(f));
        fine_alpha[q.idx] = (alpha[a.idx] + alpha[b.idx] + alpha[c.idx]) / 3.0;
      }
      return;
    }
    // A face along a sharp edge: its slot holds the trisection point nearest from(s); the
    // point nearest to(s) is in the twin's slot, or in an extra boundary slot.
    const VertexId a = m.from(s), b = m.to(s);
    const VertexId m1 = layout.near_from(s), m2 = layout.near_to(s);
    vertex_halfedge[m1.idx] = Sqrt3Layout::fine(s, 0);
    kind[m1.idx] = VertexKind::Crease;
    curve[m1.idx] = {a, m2};
    if (!alpha.empty()) fine_alpha[m1.idx] = (2.0 * alpha[a.idx] + alpha[b.idx]) / 3.0;
    if (!m.twin(s).valid()) {
      vertex_halfedge[m2.idx] = Sqrt3Layout::fine(Mesh::next(s), 2);
      kind[m2.idx] = VertexKind::Crease;
      curve[m2.idx] = {m1, b};
      if (!alpha.empty()) fine_alpha[m2.idx] = (alpha[a.idx] + 2.0 * alpha[b.idx]) / 3.0;
      const EdgeId first_third = layout.first_third_of_boundary(s);
      edge_halfedge[first_third.idx] = layout.to_apex(Mesh::prev(s));
      sharp[first_third.idx] = 1;
    }
  });

  // Old vertices keep their ids, kinds and alpha. In an even step a crease vertex's curve
  // neighbours become the trisection points next to it.
  parallel_for_each_index(nv, [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    const HalfedgeId h = m.halfedge(v);
    kind[i] = features.kind(v);
    curve[i] = features.curve_neighbours(v);
    if (!alpha.empty()) fine_alpha[i] = alpha[i];
    if (!h.valid()) {
      vertex_halfedge[i] = HalfedgeId();
      return;
    }
    // Fine half-edge 3h+0 leaves from(h) unless h is cut; then the first third v -> m1,
    // which is on the boundary exactly when h is.
    vertex_halfedge[i] =
        trisects && layout.sharp(h) ? layout.to_apex(Mesh::prev(h)) : Sqrt3Layout::fine(h, 0);
    if (!trisects || kind[i] != VertexKind::Crease) return;
    for (VertexId& w : curve[i]) {
      const HalfedgeId out = halfedge_to(m, v, w);
      w = out.valid() ? layout.near_from(out) : layout.near_to(halfedge_to(m, w, v));
    }
  });

  Level fine;
  fine.mesh = Mesh::from_parts_with_edges(std::move(positions), std::move(corner_vertex),
                                          std::move(twin), std::move(edge_of),
                                          std::move(edge_halfedge), std::move(vertex_halfedge));
  fine.features = Features::from_parts(std::move(sharp), std::move(kind), std::move(curve));
  fine.step = coarse.step + 1;
  fine.alpha = std::move(fine_alpha);
  fine.smooth_normals = std::move(fine_normals);
  return fine;
}

}  // namespace stlrefine
