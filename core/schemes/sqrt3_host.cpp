// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/sqrt3_host.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <numbers>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/refine.h"
#include "core/schemes/crease_rules.h"
#include "core/schemes/split4_host.h"

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
//   flipped h (non-sharp):      kept h (sharp, odd step):    kept h (sharp, even step):
//          p                            p                            c
//         / \   fine face h            / \   fine face h           / \   fine face h
//        a---r  = (a, r, p)           a---b  = (a, b, p)          m1--m2 = (m1, m2, c)
//   p = apex(h), r = apex of the     (the 1-to-3 child)           (middle one of the three
//   twin's face                                                    children of a cut face)
//
// apex(h) is the face point of face(h), or, when face(h) has no face point (it lies on a
// sharp edge s in an even step), the trisection point of s that h's sub-triangle touches.
// Fine edges: coarse edge e -> e (the flipped diagonal, or the kept / middle piece); the
// edge of fine half-edge 3h+2 -> E + h; in even steps the edge (m2, c) of a sharp face ->
// E + s, and the first third of a boundary edge -> E + 3F + rank among boundary edges.
class Sqrt3Layout {
 public:
  Sqrt3Layout(const Mesh& m, const Features& features, bool trisects,
              std::span<const std::uint8_t> sharp_corner, std::span<const std::uint32_t> rank)
      : m_(m),
        features_(features),
        trisects_(trisects),
        sharp_corner_(sharp_corner),
        boundary_rank_(rank),
        nv_(static_cast<std::uint32_t>(m.num_vertices())),
        nf_(static_cast<std::uint32_t>(m.num_faces())),
        ne_(static_cast<std::uint32_t>(m.num_edges())) {}

  bool sharp(HalfedgeId h) const { return features_.is_sharp(m_.edge(h)); }
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

  FineFace fine_face(HalfedgeId h) const {
    return trisects_ ? fine_face_trisecting(h) : fine_face_plain(h);
  }

 private:
  // Odd steps: every face has its face point; sharp edges are kept whole.
  FineFace fine_face_plain(HalfedgeId h) const {
    const HalfedgeId t = m_.twin(h), p = Mesh::prev(h), n = Mesh::next(h);
    const bool prev_flipped = m_.twin(p).valid() && !sharp(p);
    // Spoke p -> a: paired with the spoke a -> p of the flipped triangle of twin(prev(h)),
    // or with the kept triangle of prev(h).
    const HalfedgeId spoke_twin = prev_flipped ? fine(m_.twin(p), 0) : fine(p, 1);
    const VertexId a = m_.from(h), p_h = face_point(h.idx / 3);
    if (t.valid() && !sharp(h)) {
      return {{a, face_point(t.idx / 3), p_h},
              {fine(Mesh::next(t), 2), fine(t, 1), spoke_twin},
              {spoke(Mesh::next(t)), m_.edge(h), spoke(h)}};
    }
    return {{a, m_.to(h), p_h},
            {t.valid() ? fine(t, 0) : HalfedgeId(), fine(n, 2), spoke_twin},
            {m_.edge(h), spoke(n), spoke(h)}};
  }

  // Even steps: faces along a sharp edge s have no face point; s is cut in three.
  FineFace fine_face_trisecting(HalfedgeId h) const {
    const HalfedgeId t = m_.twin(h);
    const HalfedgeId s = sharp_of(h.idx / 3);
    if (h == s) {
      return {{near_from(s), near_to(s), m_.opposite(s)},
              {t.valid() ? fine(t, 0) : HalfedgeId(), fine(m_.twin(Mesh::next(s)), 0),
               fine(Mesh::prev(s), 2)},
              {m_.edge(s), spoke(s), spoke(Mesh::prev(s))}};
    }
    FineFace out{{m_.from(h), apex(t), apex(h)}, {}, {}};
    // Half-edge a -> apex(t), seen from the twin's face g.
    const HalfedgeId sg = sharp_of(t.idx / 3);
    if (!sg.valid()) {
      out.twin[0] = fine(Mesh::next(t), 2);
      out.edge[0] = spoke(Mesh::next(t));
    } else if (t == Mesh::next(sg)) {
      out.twin[0] = fine(sg, 1);  // the edge (m2, c) of g's middle child
      out.edge[0] = spoke(sg);
    } else {  // t == prev(sg): a -> m1 is the first third of the sharp edge sg
      const HalfedgeId across = m_.twin(sg);
      out.twin[0] = across.valid() ? fine(Mesh::next(across), 2) : HalfedgeId();
      out.edge[0] = across.valid() ? spoke(Mesh::next(across)) : first_third_of_boundary(sg);
    }
    out.twin[1] = fine(t, 1);
    out.edge[1] = m_.edge(h);
    // Half-edge apex(h) -> a.
    if (!s.valid()) {
      out.twin[2] = fine(m_.twin(Mesh::prev(h)), 0);
    } else if (h == Mesh::next(s)) {  // m2 -> b: the last third of the sharp edge s
      const HalfedgeId across = m_.twin(s);
      out.twin[2] = across.valid() ? fine(m_.twin(Mesh::prev(across)), 0) : HalfedgeId();
    } else {  // h == prev(s): m1 -> c, shared with s's middle child
      out.twin[2] = fine(s, 2);
    }
    out.edge[2] = spoke(h);
    return out;
  }

  const Mesh& m_;
  const Features& features_;
  bool trisects_;
  std::span<const std::uint8_t> sharp_corner_;
  std::span<const std::uint32_t> boundary_rank_;
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

// Fold guard of the sqrt3 host (issue 17 item 2), the counterpart of split4's guard_folds.
// The smooth surface's normals come from the coarse level's sector normals (split4_host.h):
// at an old vertex the one of its corner in the coarse face the fine face belongs to, at a
// face point the mean of its face's three corner normals, at a trisection point the mean of
// its edge's two corners weighted by nearness. A fine face folds when its normal is more than
// kFoldAngleDeg from the mean of its corners' smooth normals. Its face points are then pulled
// towards the centroid of their face's (new) corner points in steps (1/2, 1/4, then the
// centroid itself: the linear 1-to-3 split). Old vertices and trisection points (on their
// crease curve) never move, so an interpolating stencil stays interpolating and creases
// exact. Returns how many face points moved.
std::size_t guard_sqrt3_folds(const Mesh& m, const Features& features, const Sqrt3Layout& layout,
                              bool trisects, std::span<const VertexId> corner_vertex,
                              BigVector<Vec3>& pos) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::uint32_t nf = static_cast<std::uint32_t>(m.num_faces());
  const std::uint32_t nh = 3 * nf;
  // Stages: the stencil's point, 1/2 and 1/4 of the way from the centroid, the centroid,
  // then towards the face's largest-angle corner (see target()).
  constexpr std::array<double, 6> kScale = {1.0, 0.5, 0.25, 0.0, 0.0, 0.0};
  const double cos_fold = std::cos(kFoldAngleDeg * std::numbers::pi / 180.0);
  const BigVector<Vec3> corner = sector_normals(m, features);
  auto face_normal_of = [&](std::uint32_t f) {
    return normalized(corner[3 * f] + corner[3 * f + 1] + corner[3 * f + 2]);
  };
  // The smooth normal at apex(h) (see Sqrt3Layout::apex).
  auto apex_normal = [&](HalfedgeId h) {
    const HalfedgeId s = layout.sharp_of(h.idx / 3);
    if (!s.valid()) return face_normal_of(h.idx / 3);
    const Vec3 &na = corner[s.idx], &nb = corner[Mesh::next(s).idx];
    return h == Mesh::next(s) ? normalized(na + 2.0 * nb) : normalized(2.0 * na + nb);
  };
  // The mean smooth normal of fine face h (unnormalised sum of its corners').
  auto smooth_normal = [&](HalfedgeId h) -> Vec3 {
    const HalfedgeId t = m.twin(h);
    if (!trisects) {
      if (t.valid() && !layout.sharp(h))
        return corner[h.idx] + face_normal_of(t.idx / 3) + face_normal_of(h.idx / 3);
      return corner[h.idx] + corner[Mesh::next(h).idx] + face_normal_of(h.idx / 3);
    }
    const HalfedgeId s = layout.sharp_of(h.idx / 3);
    if (h == s) {
      const Vec3 &na = corner[s.idx], &nb = corner[Mesh::next(s).idx];
      return normalized(2.0 * na + nb) + normalized(na + 2.0 * nb) + corner[Mesh::prev(s).idx];
    }
    return corner[h.idx] + apex_normal(t) + apex_normal(h);
  };
  auto folds = [&](std::uint32_t h) {
    const Vec3 n = triangle_normal(pos[corner_vertex[3 * h].idx], pos[corner_vertex[3 * h + 1].idx],
                                   pos[corner_vertex[3 * h + 2].idx]);
    const Vec3 smooth = smooth_normal(HalfedgeId(h));
    const double len = norm(n) * norm(smooth);
    return len > 0 && dot(n, smooth) < cos_fold * len;
  };
  std::vector<std::uint8_t> folding(nh, 0);
  parallel_for_each_index(
      nh, [&](std::size_t h) { folding[h] = folds(static_cast<std::uint32_t>(h)); });
  if (std::find(folding.begin(), folding.end(), 1) == folding.end()) return 0;
  std::vector<std::uint8_t> stage(nf, 0);
  std::vector<Vec3> original(nf);
  std::vector<std::uint32_t> todo, touched;
  for (std::uint32_t h = 0; h < nh; ++h)
    if (folding[h]) todo.push_back(h);
  std::fill(folding.begin(), folding.end(), 0);  // from now on: "in touched"
  // The face points of fine face h: those of the coarse faces whose apexes it uses.
  auto face_points_of = [&](std::uint32_t h, std::array<std::uint32_t, 2>& out) {
    int n = 0;
    for (int j = 0; j < 3; ++j) {
      const std::uint32_t v = corner_vertex[3 * h + j].idx;
      if (v < nv || v >= nv + nf) continue;
      const std::uint32_t f = v - nv;
      if (layout.sharp_of(f).valid()) continue;  // a trisection point in f's slot
      out[n++] = f;
    }
    return n;
  };
  auto touch = [&](std::uint32_t h) {
    if (folding[h]) return;
    folding[h] = 1;
    touched.push_back(h);
  };
  std::size_t moved = 0;
  while (!todo.empty()) {
    touched.clear();
    for (const std::uint32_t h : todo) {
      std::array<std::uint32_t, 2> fps{};
      const int n = face_points_of(h, fps);
      for (int i = 0; i < n; ++i) {
        const std::uint32_t f = fps[i];
        if (stage[f] + 1u >= kScale.size()) continue;
        const VertexId q = layout.face_point(f);
        if (stage[f] == 0) {
          original[f] = pos[q.idx];
          ++moved;
        }
        ++stage[f];
        const auto [a, b, c] = m.face_vertices(FaceId(f));
        const Vec3 centroid = (pos[a.idx] + pos[b.idx] + pos[c.idx]) * (1.0 / 3.0);
        pos[q.idx] = centroid + kScale[stage[f]] * (original[f] - centroid);
        if (stage[f] >= 4) {
          // Even the linear split folds where the flipped edge's quad (a, q_g, b, q_f) is not
          // convex: beside an obtuse face the centroids' segment misses the edge. Points
          // nearer the obtuse corner keep their projections inside the face's edges.
          const std::array<Vec3, 3> p = {pos[a.idx], pos[b.idx], pos[c.idx]};
          int obtuse = 0;
          double best = -2;
          for (int k = 0; k < 3; ++k) {
            const Vec3 u = normalized(p[(k + 1) % 3] - p[k]), v = normalized(p[(k + 2) % 3] - p[k]);
            const double cosine = -dot(u, v);  // larger for a larger angle
            if (cosine > best) best = cosine, obtuse = k;
          }
          const double t = stage[f] == 4 ? 1.0 / 3.0 : 2.0 / 3.0;
          pos[q.idx] = centroid + t * (p[obtuse] - centroid);
        }
        // Fine faces using q: those of f's half-edges and of their twins.
        for (std::uint32_t k = 0; k < 3; ++k) {
          const HalfedgeId g(3 * f + k);
          touch(g.idx);
          if (m.twin(g).valid()) touch(m.twin(g).idx);
        }
      }
    }
    std::sort(touched.begin(), touched.end());
    for (const std::uint32_t h : touched) folding[h] = 0;
    todo.clear();
    for (const std::uint32_t h : touched) {
      if (!folds(h)) continue;
      std::array<std::uint32_t, 2> fps{};
      const int n = face_points_of(h, fps);
      bool movable = false;
      for (int i = 0; i < n; ++i) movable |= stage[fps[i]] + 1u < kScale.size();
      if (movable) todo.push_back(h);
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
      // per coarse face, two lists of fine faces
      big_vector_bytes<Vec3>(3 * nf) + 3 * nf + nf + sizeof(Vec3) * nf +
      2 * sizeof(std::uint32_t) * 3 * std::uint64_t(nf);
  if (trisects) bytes += big_vector_bytes<std::uint8_t>(nf) + big_vector_bytes<std::uint32_t>(ne);
  return bytes;
}

Level sqrt3_refine(const Level& coarse, const Sqrt3Stencil& stencil, StepStats& stats) {
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
  const Sqrt3Layout layout(m, features, trisects, sharp_corner, boundary_rank);

  const std::size_t fine_vertices = std::size_t(nv) + nf + boundary_edges;
  const std::size_t fine_edges = std::size_t(ne) + 3 * std::size_t(nf) + boundary_edges;
  BigVector<Vec3> positions(fine_vertices);
  stencil.points(
      step, {std::span<Vec3>(positions.data(), nv), std::span<Vec3>(positions.data() + nv, nf)});

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
      const bool kept_whole = !trisects && (sharp_h || !m.twin(h).valid());
      const bool cut = trisects && sharp_h;
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
    // canonical side also writes the point nearest to(s) (the twin's slot, or the extra
    // boundary slot), so every point is computed once.
    const VertexId a = m.from(s), b = m.to(s);
    const VertexId m1 = layout.near_from(s), m2 = layout.near_to(s);
    vertex_halfedge[m1.idx] = Sqrt3Layout::fine(s, 0);
    kind[m1.idx] = VertexKind::Crease;
    curve[m1.idx] = {a, m2};
    if (!alpha.empty()) fine_alpha[m1.idx] = (2.0 * alpha[a.idx] + alpha[b.idx]) / 3.0;
    if (m.halfedge(m.edge(s)) == s) {
      const std::array<Vec3, 2> points = stencil.curve_points(step, s);
      positions[m1.idx] = points[0];
      positions[m2.idx] = points[1];
    }
    if (!m.twin(s).valid()) {
      vertex_halfedge[m2.idx] = Sqrt3Layout::fine(Mesh::next(s), 2);
      kind[m2.idx] = VertexKind::Crease;
      curve[m2.idx] = {m1, b};
      if (!alpha.empty()) fine_alpha[m2.idx] = (alpha[a.idx] + 2.0 * alpha[b.idx]) / 3.0;
      const EdgeId first_third = layout.first_third_of_boundary(s);
      edge_halfedge[first_third.idx] = Sqrt3Layout::fine(m.twin(Mesh::prev(s)), 0);
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
    vertex_halfedge[i] = trisects && layout.sharp(h) ? Sqrt3Layout::fine(m.twin(Mesh::prev(h)), 0)
                                                     : Sqrt3Layout::fine(h, 0);
    if (!trisects || kind[i] != VertexKind::Crease) return;
    for (VertexId& w : curve[i]) {
      const HalfedgeId out = halfedge_to(m, v, w);
      w = out.valid() ? layout.near_from(out) : layout.near_to(halfedge_to(m, w, v));
    }
  });

  if (stencil.guards_folds())
    stats.fold_fallbacks +=
        guard_sqrt3_folds(m, features, layout, trisects, corner_vertex, positions);

  Level fine;
  fine.mesh = Mesh::from_parts_with_edges(std::move(positions), std::move(corner_vertex),
                                          std::move(twin), std::move(edge_of),
                                          std::move(edge_halfedge), std::move(vertex_halfedge));
  fine.features = Features::from_parts(std::move(sharp), std::move(kind), std::move(curve));
  fine.step = coarse.step + 1;
  fine.alpha = std::move(fine_alpha);
  return fine;
}

}  // namespace stlrefine
