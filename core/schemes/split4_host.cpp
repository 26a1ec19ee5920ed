// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/split4_host.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "core/geometry/hermite.h"
#include "core/parallel.h"
#include "core/refine.h"
#include "core/schemes/crease_rules.h"
#include "core/schemes/dominant_planes.h"
#include "core/schemes/lsf_rules.h"

namespace stlrefine {

void Split4Stencil::vertex_points(const Level& coarse, std::span<Vec3> out) const {
  const auto p = coarse.mesh.positions();
  std::copy(p.begin(), p.end(), out.begin());
}

void Split4Stencil::points(const Level& coarse, const IrregularVertices&,
                           std::span<Vec3> vertex_out, std::span<Vec3> edge_out) const {
  vertex_points(coarse, vertex_out);
  edge_points(coarse, edge_out);
}

std::uint64_t Split4Stencil::scratch_bytes(const Level& coarse) const {
  return 24 * std::uint64_t(coarse.mesh.num_edges()) +
         64 * std::uint64_t(coarse.mesh.num_vertices());
}

IrregularVertices irregular_vertices(const Level& level) {
  const Mesh& m = level.mesh;
  if (level.irregular.valid_for(m)) return level.irregular;
  std::vector<int> valence(m.num_vertices(), 6);
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    if (!m.is_isolated(v) && !m.is_boundary(v)) valence[i] = m.valence(v);
  });
  auto list = std::make_shared<std::vector<std::pair<VertexId, int>>>();
  for (std::size_t i = 0; i < valence.size(); ++i)
    if (valence[i] != 6) list->emplace_back(VertexId(static_cast<std::uint32_t>(i)), valence[i]);
  return {std::move(list), m.corner_vertices().data(), m.num_vertices(), m.num_faces()};
}

namespace {

// Connectivity of the 1-to-4 split, derived arithmetically from the coarse mesh.
//
//              v2                    coarse face f = (v0, v1, v2), half-edge k: v_k -> v_k+1
//             /  \                   m_k = midpoint vertex of half-edge k = V + edge(3f+k)
//           m2 -- m1                 child 4f+k = (v_k, m_k, m_k-1), child 4f+3 = (m0, m1, m2)
//          /  \  /  \                child half-edge 0: first half of coarse half-edge k
//        v0 -- m0 -- v1                              1: inner edge m_k -> m_k-1
//                                                    2: second half of coarse half-edge k-1
// Child edges: coarse edge e -> 2e (first half of its canonical half-edge), 2e+1 (second
// half); the inner edge of corner child k -> 2E + 3f + k.
struct Split4Topology {
  BigVector<VertexId> corner_vertex;
  BigVector<HalfedgeId> twin;
  BigVector<EdgeId> edge_of;
  BigVector<HalfedgeId> edge_halfedge;
  BigVector<HalfedgeId> vertex_halfedge;
  BigVector<std::uint8_t> sharp;
};

constexpr std::uint32_t first_half(std::uint32_t f, std::uint32_t k) {
  return 12 * f + 3 * k;
}
constexpr std::uint32_t second_half(std::uint32_t f, std::uint32_t k) {
  return 12 * f + 3 * ((k + 1) % 3) + 2;
}

Split4Topology split4_topology(const Mesh& m, const Features& features) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::uint32_t ne = static_cast<std::uint32_t>(m.num_edges());
  const std::uint32_t nf = static_cast<std::uint32_t>(m.num_faces());
  Split4Topology t;
  t.corner_vertex.resize(12 * std::size_t(nf));
  t.twin.resize(12 * std::size_t(nf));
  t.edge_of.resize(12 * std::size_t(nf));
  t.edge_halfedge.resize(2 * std::size_t(ne) + 3 * std::size_t(nf));
  t.vertex_halfedge.resize(std::size_t(nv) + ne);
  t.sharp.resize(t.edge_halfedge.size());

  parallel_for_each_index(nf, [&](std::size_t fi) {
    const std::uint32_t f = static_cast<std::uint32_t>(fi);
    std::array<VertexId, 3> v, mid;
    for (std::uint32_t k = 0; k < 3; ++k) {
      v[k] = m.from(HalfedgeId(3 * f + k));
      mid[k] = VertexId(nv + m.edge(HalfedgeId(3 * f + k)).idx);
    }
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t km1 = (k + 2) % 3;
      const std::uint32_t c = 12 * f + 3 * k;  // corner child 4f+k
      t.corner_vertex[c] = v[k];
      t.corner_vertex[c + 1] = mid[k];
      t.corner_vertex[c + 2] = mid[km1];
      t.corner_vertex[12 * f + 9 + k] = mid[k];  // middle child
      // Inner edge m_k -> m_k-1 pairs with the middle child's m_k-1 -> m_k.
      t.twin[c + 1] = HalfedgeId(12 * f + 9 + km1);
      t.twin[12 * f + 9 + km1] = HalfedgeId(c + 1);
      const std::uint32_t inner_edge = 2 * ne + 3 * f + k;
      t.edge_of[c + 1] = t.edge_of[12 * f + 9 + km1] = EdgeId(inner_edge);
      t.edge_halfedge[inner_edge] = HalfedgeId(c + 1);

      // Halves of coarse half-edge k pair with the swapped halves of its twin.
      const HalfedgeId coarse(3 * f + k);
      const HalfedgeId ct = m.twin(coarse);
      const EdgeId e = m.edge(coarse);
      const bool canonical = m.halfedge(e) == coarse;
      if (ct.valid()) {
        const std::uint32_t g = ct.idx / 3, j = ct.idx % 3;
        t.twin[first_half(f, k)] = HalfedgeId(second_half(g, j));
        t.twin[second_half(f, k)] = HalfedgeId(first_half(g, j));
      } else {
        t.twin[first_half(f, k)] = t.twin[second_half(f, k)] = HalfedgeId();
      }
      t.sharp[inner_edge] = 0;
      t.edge_of[first_half(f, k)] = EdgeId(2 * e.idx + (canonical ? 0 : 1));
      t.edge_of[second_half(f, k)] = EdgeId(2 * e.idx + (canonical ? 1 : 0));
      if (canonical) {
        t.edge_halfedge[2 * e.idx] = HalfedgeId(first_half(f, k));
        t.edge_halfedge[2 * e.idx + 1] = HalfedgeId(second_half(f, k));
        t.sharp[2 * e.idx] = t.sharp[2 * e.idx + 1] = features.is_sharp(e);
        // The second half leaves the midpoint with no twin on a boundary: most clockwise.
        t.vertex_halfedge[nv + e.idx] = HalfedgeId(second_half(f, k));
      }
    }
  });
  parallel_for_each_index(nv, [&](std::size_t v) {
    const HalfedgeId h = m.halfedge(VertexId(static_cast<std::uint32_t>(v)));
    // The first half of v's most clockwise half-edge is most clockwise at v again.
    t.vertex_halfedge[v] = h.valid() ? HalfedgeId(first_half(h.idx / 3, h.idx % 3)) : HalfedgeId();
  });
  return t;
}

}  // namespace

std::uint64_t guard_folds_work_bytes(const Mesh& m) {
  return sizeof(Vec3) * std::uint64_t(m.num_edges()) +
         2 * sizeof(std::uint32_t) * std::uint64_t(m.num_faces()) +
         (1 + sizeof(Vec3)) * std::uint64_t(m.num_vertices());  // moved old vertices
}

std::uint64_t guard_folds_normal_bytes(const Mesh& m) {
  return sizeof(Vec3) * 3 * std::uint64_t(m.num_faces());
}

BigVector<Vec3> sector_normals(const Mesh& m, const Features& features) {
  BigVector<Vec3> corner(3 * std::size_t(m.num_faces()));
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    const HalfedgeId start = sector_walk_start(m, features, v);
    if (!start.valid()) return;
    HalfedgeId sector_begin = start, h = start;
    Vec3 sum{};
    while (true) {
      // Face of h, corner at v: its unit normal weighted by its angle at v.
      const Vec3 p = m.position(v);
      const Vec3 a = m.position(m.to(h)) - p;
      const Vec3 b = m.position(m.from(Mesh::prev(h))) - p;
      const Vec3 n = normalized(cross(a, b));
      sum += std::atan2(norm(cross(a, b)), dot(a, b)) * n;
      const HalfedgeId next = m.ccw_rotated(h);
      const bool end = !next.valid() || next == start;
      if (end || features.is_sharp(m.edge(next))) {
        const Vec3 unit = normalized(sum);
        for (HalfedgeId g = sector_begin;; g = m.ccw_rotated(g)) {
          corner[g.idx] = unit;
          if (g == h) break;
        }
        sector_begin = next;
        sum = Vec3{};
      }
      if (end) break;
      h = next;
    }
  });
  return corner;
}

BigVector<Vec3> split4_smooth_normals(const Mesh& m, const BigVector<Vec3>& corner) {
  const std::size_t nf = m.num_faces();
  BigVector<Vec3> fine(12 * nf);
  parallel_for_each_index(nf, [&](std::size_t f) {
    const Vec3* c = &corner[3 * f];
    // The normal at edge point k (on half-edge k: corner k -> corner k + 1).
    const std::array<Vec3, 3> n = {normalized(c[0] + c[1]), normalized(c[1] + c[2]),
                                   normalized(c[2] + c[0])};
    for (std::size_t k = 0; k < 3; ++k) {
      const std::size_t km1 = (k + 2) % 3;
      // Corner child 4f + k = (v_k, m_k, m_k-1), middle child 4f + 3 = (m0, m1, m2): the
      // corner order of split4_topology.
      fine[12 * f + 3 * k] = c[k];
      fine[12 * f + 3 * k + 1] = n[k];
      fine[12 * f + 3 * k + 2] = n[km1];
      fine[12 * f + 9 + k] = n[k];
    }
  });
  return fine;
}

std::uint64_t keep_dominant_planes_bytes(const Mesh& m) {
  return dominant_planes_bytes(m) + m.num_edges();
}

std::size_t keep_dominant_planes(const Mesh& m, const Features& features, BigVector<Vec3>& pos) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const DominantPlanes planes = dominant_planes(m, features);
  std::vector<std::uint8_t> moved(m.num_edges(), 0);
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    if (features.is_sharp(edge) || m.is_boundary(edge)) return;
    const HalfedgeId h = m.halfedge(edge), t = m.twin(h);
    const bool f_holds = planes.dominant[h.idx] && planes.dominant[Mesh::next(h).idx];
    const bool g_holds = planes.dominant[t.idx] && planes.dominant[Mesh::next(t).idx];
    const std::uint32_t f = h.idx / 3, g = t.idx / 3;
    // two planes: leave it to the stencil
    if (f_holds && g_holds && !planes.coplanar(m, f, g)) return;
    if (!f_holds && !g_holds) return;
    const std::uint32_t held = f_holds ? f : g;
    Vec3& q = pos[nv + e];
    if (planes.on_plane(held, q, planes.plane[held].size)) return;
    q = planes.project(held, q);
    moved[e] = 1;
  });
  return static_cast<std::size_t>(std::count(moved.begin(), moved.end(), 1));
}

void NormalCheckParams::validate() const {
  if (!(slack >= 0 && slack <= 4)) throw std::invalid_argument("normal check slack outside [0, 4]");
  if (!(width_fraction >= 0 && width_fraction <= 0.1))
    throw std::invalid_argument("normal check width fraction outside [0, 0.1]");
  if (!(uneven_spokes >= 1 && uneven_spokes <= 1000))
    throw std::invalid_argument("normal check spoke ratio outside [1, 1000]");
  if (!(sliver_trust >= 1 && sliver_trust <= 1000))
    throw std::invalid_argument("normal check sliver trust outside [1, 1000]");
  if (!(sliver_turn_deg >= 0 && sliver_turn_deg <= 180))
    throw std::invalid_argument("normal check sliver turn outside [0, 180]");
}

std::uint64_t check_edge_points_bytes(const Mesh& m) {
  return std::uint64_t(m.num_vertices()) + m.num_edges();
}

std::vector<std::uint8_t> uneven_spoke_vertices(const Mesh& m, double ratio) {
  std::vector<std::uint8_t> uneven(m.num_vertices(), 0);
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    if (m.is_isolated(v)) return;
    double shortest = std::numeric_limits<double>::infinity(), longest = 0;
    const Vec3 p = m.position(v);
    for_each_outgoing(m, v, [&](HalfedgeId s) {
      const Vec3 d = m.position(m.to(s)) - p;
      const double l2 = dot(d, d);  // squared
      shortest = std::min(shortest, l2);
      longest = std::max(longest, l2);
    });
    uneven[i] = longest >= (ratio * ratio) * shortest;
  });
  return uneven;
}

std::size_t check_edge_points_against_normals(const Mesh& m, const Features& features,
                                              std::span<Vec3> edge_points,
                                              const NormalCheckParams& params) {
  params.validate();
  // Where the butterfly's lattice assumption fails.
  const std::vector<std::uint8_t> uneven = uneven_spoke_vertices(m, params.uneven_spokes);
  std::vector<std::uint8_t> moved(m.num_edges(), 0);
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    if (features.is_sharp(edge) || m.is_boundary(edge)) return;
    const HalfedgeId h = m.halfedge(edge);
    if (!uneven[m.from(h).idx] && !uneven[m.to(h).idx]) return;
    // lsf's guard normals (sector normals of area- and angle-weighted faces, a dominant
    // plane's where one rules the ring), at each end within the sector of h's face.
    const Vec3 na = lsf::sector_normal(m, features, h);
    const Vec3 nb = lsf::sector_normal(m, features, Mesh::next(h));
    const Vec3 n = normalized(na + nb);
    if (dot(n, n) == 0) return;
    const Vec3 a = m.position(m.from(h)), b = m.position(m.to(h));
    const double length = distance(a, b);
    if (!(length > 0)) return;
    const Vec3 offset = hermite_midpoint_offset(b - a, length, na, nb);
    Vec3& q = edge_points[e];
    // What the normals cannot resolve: a fraction of the narrower face's height across the
    // edge (a 305 mm sliver's length would allow ten times the sagitta of its arc).
    const Vec3 c = m.position(m.opposite(h)), d = m.position(m.opposite(m.twin(h)));
    const double twice_area_c = norm(cross(b - a, c - a)), twice_area_d = norm(cross(b - a, d - a));
    const double narrow = std::min(twice_area_c, twice_area_d) / length;
    const double wide = std::max(twice_area_c, twice_area_d) / length;
    const double allowed = params.slack * norm(offset) + params.width_fraction * narrow;
    const Vec3 mid = 0.5 * (a + b);
    const double have = dot(q - mid, n), hermite = dot(offset, n);
    if (std::abs(have - hermite) <= allowed) return;
    // The normals' turn is trusted up to the bulge of an arc across the wider face turning as
    // they do, (width / 8) |na - nb|: a zipped cylinder's sliver bulges that much (its normals
    // turn across it); tray_bottom's 38 mm wall slivers, 3.2 mm tall, whose end normal averages
    // a 4.5 degree kink of the flat wall, had Hermite midpoints 0.2-0.3 mm out, ten times more.
    // Past it the Hermite midpoint is only a bound: points between it and the chord stay.
    // Only a shallow turn (sliver_turn_deg) is read as a possible kink: a larger one is the
    // surface's own (a rim left smooth turns 45 degrees and more).
    const double turn = norm(na - nb);  // 2 sin(angle / 2)
    const double trusted = params.sliver_trust * 0.125 * wide * turn;
    const bool shallow = turn < 2 * std::sin(0.5 * params.sliver_turn_deg * std::numbers::pi / 180);
    const double bound = shallow && std::abs(hermite) > trusted ? 0.0 : hermite;
    const double target = std::clamp(have, std::min(bound, hermite), std::max(bound, hermite));
    if (target == have) return;
    // The whole point, not only its normal part: the stencil's tangential position is off too
    // on fans and zippers (along the normal only, the 2-level RMS of ButterflyCad's families
    // went from 0.45 to 0.63 of the input's).
    q = mid + (hermite != 0 ? target / hermite : 1.0) * offset;
    moved[e] = 1;
  });
  return static_cast<std::size_t>(std::count(moved.begin(), moved.end(), 1));
}

// Fold guard. An interpolating stencil can push an edge point so far that a child turns
// over (the butterfly does on long thin CAD triangles) or turns far from the surface the
// coarse mesh stands for. That surface's normals are estimated per corner of a coarse face:
// on the input, the angle-weighted mean of the face normals around the corner's vertex
// within its crease sector (sector_normals); an edge point's is the mean of its edge's two
// corner normals; split4 carries them to later levels (split4_smooth_normals) instead of
// estimating them again on faces the stencil made. A child folds when its normal is more
// than kGuardAngleDeg from the mean of its three vertices' normals, or more than 90 degrees
// from its parent's. Folding children's edge
// points are pulled towards their chord midpoints in steps (1/2, 1/4, then the midpoint
// itself). With all three edge points at their midpoints the children are parallel to the
// parent, so the loop ends.
// Sharp (crease and boundary) edge points lie on their curve and are moved only when the
// face's smooth edges are already at their midpoints: pulling a crease point off its curve
// would make a dent in the crease that later levels amplify.
std::size_t guard_folds(const Mesh& m, const Features& features, BigVector<Vec3>& pos,
                        const std::function<void(std::uint64_t)>& reserve) {
  return guard_folds(m, features, sector_normals(m, features), pos, reserve);
}

std::size_t guard_folds(const Mesh& m, const Features& features, const BigVector<Vec3>& corner,
                        BigVector<Vec3>& pos, const std::function<void(std::uint64_t)>& reserve) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::uint32_t nf = static_cast<std::uint32_t>(m.num_faces());
  constexpr std::array<double, 4> kScale = {1.0, 0.5, 0.25, 0.0};
  const double cos_fold = std::cos(kGuardAngleDeg * std::numbers::pi / 180.0);
  std::vector<std::uint8_t> stage(m.num_edges(), 0);
  std::vector<Vec3> original;  // filled lazily: most meshes never fold

  auto edge_point = [&](std::uint32_t f, std::uint32_t k) -> const Vec3& {
    return pos[nv + m.edge(HalfedgeId(3 * f + k)).idx];
  };
  // Whether the child (a, b, c) turns too far: from its parent's normal n, or from the mean
  // of its vertices' smooth normals.
  auto child_folds = [&](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n,
                         const Vec3& smooth) {
    const Vec3 t = triangle_normal(a, b, c);
    if (dot(t, n) < 0) return true;
    const double len = norm(t) * norm(smooth);
    return len > 0 && dot(t, smooth) < cos_fold * len;
  };
  auto folds = [&](std::uint32_t f) {
    const Vec3 n = m.face_normal(FaceId(f));
    if (dot(n, n) == 0) return false;
    const Vec3 m0 = edge_point(f, 0), m1 = edge_point(f, 1), m2 = edge_point(f, 2);
    const auto [v0, v1, v2] = m.face_vertices(FaceId(f));
    const Vec3 &p0 = pos[v0.idx], &p1 = pos[v1.idx], &p2 = pos[v2.idx];
    const Vec3 &c0 = corner[3 * f], &c1 = corner[3 * f + 1], &c2 = corner[3 * f + 2];
    const Vec3 n0 = normalized(c0 + c1), n1 = normalized(c1 + c2), n2 = normalized(c2 + c0);
    return child_folds(p0, m0, m2, n, c0 + n0 + n2) || child_folds(p1, m1, m0, n, c1 + n1 + n0) ||
           child_folds(p2, m2, m1, n, c2 + n2 + n1) || child_folds(m0, m1, m2, n, n0 + n1 + n2);
  };

  std::vector<std::uint8_t> folding(nf, 0);
  parallel_for_each_index(
      nf, [&](std::size_t f) { folding[f] = folds(static_cast<std::uint32_t>(f)); });
  if (std::find(folding.begin(), folding.end(), 1) == folding.end()) return 0;
  // Work arrays of a known size from here on (the face lists never repeat a face), so
  // memory admission can reserve them first.
  if (reserve) reserve(guard_folds_work_bytes(m));
  std::vector<std::uint32_t> todo, touched;
  todo.reserve(nf);
  touched.reserve(nf);
  for (std::uint32_t f = 0; f < nf; ++f)
    if (folding[f]) todo.push_back(f);
  std::fill(folding.begin(), folding.end(), 0);  // from now on: "in touched"
  auto touch = [&](std::uint32_t f) {
    if (folding[f]) return;
    folding[f] = 1;
    touched.push_back(f);
  };
  // Old vertices the stencil moved (butterfly-g1 from its second step on): where a child of
  // theirs folds they go back towards where they were, first (see below).
  std::vector<std::uint8_t> vertex_stage;
  std::vector<Vec3> vertex_original;
  auto moved_corner = [&](VertexId v) {
    if (vertex_stage.empty()) return false;
    return vertex_stage[v.idx] + 1u < kScale.size();
  };
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (pos[v] == m.position(VertexId(v))) continue;
    if (vertex_stage.empty()) {
      vertex_stage.assign(nv, kScale.size() - 1);
      vertex_original.assign(pos.begin(), pos.begin() + nv);
    }
    vertex_stage[v] = 0;
  }
  std::size_t moved_edges = 0;
  while (!todo.empty()) {
    if (original.empty()) original.assign(pos.begin() + nv, pos.end());
    touched.clear();
    for (std::uint32_t f : todo) {
      // A moved corner goes back first, in the edge points' stages, to where the coarse level
      // has it: G1's moves of old vertices are what folds there, and with the corner back
      // the edge points are the plain butterfly's.
      bool corner_moved = false;
      for (const VertexId v : m.face_vertices(FaceId(f))) {
        if (!moved_corner(v)) continue;
        corner_moved = true;
        if (vertex_stage[v.idx] == 0) ++moved_edges;
        ++vertex_stage[v.idx];
        const Vec3& home = m.position(v);
        pos[v.idx] = home + kScale[vertex_stage[v.idx]] * (vertex_original[v.idx] - home);
        for_each_outgoing(m, v, [&](HalfedgeId h) { touch(h.idx / 3); });
      }
      if (corner_moved) continue;
      bool smooth_movable = false;
      for (std::uint32_t k = 0; k < 3; ++k) {
        const EdgeId e = m.edge(HalfedgeId(3 * f + k));
        smooth_movable |= !features.is_sharp(e) && stage[e.idx] + 1u < kScale.size();
      }
      for (std::uint32_t k = 0; k < 3; ++k) {
        const HalfedgeId h(3 * f + k);
        const EdgeId e = m.edge(h);
        if (stage[e.idx] + 1u >= kScale.size()) continue;
        if (smooth_movable && features.is_sharp(e)) continue;
        if (stage[e.idx] == 0) ++moved_edges;
        ++stage[e.idx];
        const Vec3 mid = 0.5 * (pos[m.from(h).idx] + pos[m.to(h).idx]);
        pos[nv + e.idx] = mid + kScale[stage[e.idx]] * (original[e.idx] - mid);
        touch(f);
        if (m.twin(h).valid()) touch(m.twin(h).idx / 3);
      }
    }
    std::sort(touched.begin(), touched.end());
    for (std::uint32_t f : touched) folding[f] = 0;
    todo.clear();
    for (std::uint32_t f : touched) {
      if (!folds(f)) continue;
      // Stop when every edge of a folding face is already at its midpoint (degenerate
      // parent geometry): nothing further can be done there.
      bool movable = false;
      for (std::uint32_t k = 0; k < 3; ++k)
        movable |= stage[m.edge(HalfedgeId(3 * f + k)).idx] + 1u < kScale.size() ||
                   moved_corner(m.from(HalfedgeId(3 * f + k)));
      if (movable) todo.push_back(f);
    }
  }
  return moved_edges;
}

namespace {

// Vertex kinds of the fine level without walking any ring: old vertices keep their kind
// (each sharp edge at them is halved, not removed); a new vertex is a crease vertex
// between the two endpoints' halves when its edge is sharp, smooth otherwise. Curve
// neighbours of an old crease vertex become the midpoints of its two sharp edges.
Features split4_features(const Mesh& m, const Features& coarse, BigVector<std::uint8_t> sharp) {
  const std::uint32_t nv = static_cast<std::uint32_t>(m.num_vertices());
  const std::size_t ne = m.num_edges();
  BigVector<VertexKind> kind(nv + ne);
  BigVector<std::array<VertexId, 2>> curve(nv + ne);
  parallel_for_each_index(nv, [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    kind[i] = coarse.kind(v);
    curve[i] = {};
    if (kind[i] != VertexKind::Crease) return;
    for (int s = 0; s < 2; ++s) {
      const VertexId w = coarse.curve_neighbours(v)[s];
      HalfedgeId h = halfedge_to(m, v, w);
      if (!h.valid()) h = halfedge_to(m, w, v);  // a boundary edge only runs w -> v
      curve[i][s] = VertexId(nv + m.edge(h).idx);
    }
  });
  parallel_for_each_index(ne, [&](std::size_t e) {
    const bool sharp_edge = coarse.is_sharp(EdgeId(static_cast<std::uint32_t>(e)));
    kind[nv + e] = sharp_edge ? VertexKind::Crease : VertexKind::Smooth;
    const HalfedgeId h = m.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    curve[nv + e] =
        sharp_edge ? std::array<VertexId, 2>{m.from(h), m.to(h)} : std::array<VertexId, 2>{};
  });
  return Features::from_parts(std::move(sharp), std::move(kind), std::move(curve));
}

}  // namespace

std::uint64_t split4_step_bytes(const Level& coarse, const Split4Stencil& stencil) {
  const Mesh& m = coarse.mesh;
  const std::size_t nv = m.num_vertices(), ne = m.num_edges(), nf = m.num_faces();
  const std::size_t fine_vertices = nv + ne, fine_edges = 2 * ne + 3 * nf;
  std::uint64_t bytes =
      big_vector_bytes<Vec3>(fine_vertices) + 3 * big_vector_bytes<HalfedgeId>(12 * nf) +
      big_vector_bytes<HalfedgeId>(fine_edges) + big_vector_bytes<HalfedgeId>(fine_vertices) +
      big_vector_bytes<std::uint8_t>(fine_edges) + big_vector_bytes<VertexKind>(fine_vertices) +
      big_vector_bytes<std::array<VertexId, 2>>(fine_vertices) + stencil.scratch_bytes(coarse);
  // irregular_vertices(): a valence per vertex and the list of the irregular ones.
  if (stencil.uses_irregular()) bytes += (sizeof(int) + 8) * std::uint64_t(nv);
  // The guard: its stage and face flags, the smooth normals when the coarse level carries
  // none, its work arrays, the plane rule's, and the fine level's smooth normals (12 per
  // coarse face) unless this is the last step.
  if (stencil.guards_folds())
    bytes += ne + nf + guard_folds_normal_bytes(m) + guard_folds_work_bytes(m) +
             keep_dominant_planes_bytes(m) +
             (coarse.pass_smooth_normals ? big_vector_bytes<Vec3>(12 * nf) : 0);
  return bytes;
}

Level split4(const Level& coarse, const Split4Stencil& stencil, StepStats& stats, FoldGuard guard) {
  const Mesh& m = coarse.mesh;
  const std::size_t nv = m.num_vertices();
  BigVector<Vec3> positions(nv + m.num_edges());
  const IrregularVertices irregular =
      stencil.uses_irregular() ? irregular_vertices(coarse) : IrregularVertices{};
  stencil.points(coarse, irregular, std::span<Vec3>(positions.data(), nv),
                 std::span<Vec3>(positions.data() + nv, m.num_edges()));
  BigVector<Vec3> fine_normals;
  if (guard == FoldGuard::AsStencil && stencil.guards_folds()) {
    // The smooth normals: the input's sector normals, carried from level to level, not
    // the sector normals of this level (after a level or two those follow the faces the
    // stencil bent, and the guard would hold children to its own mistakes).
    BigVector<Vec3> estimated;
    const bool carried = coarse.smooth_normals.size() == 3 * std::size_t(m.num_faces());
    if (!carried) estimated = sector_normals(m, coarse.features);
    const BigVector<Vec3>& corner = carried ? coarse.smooth_normals : estimated;
    keep_dominant_planes(m, coarse.features, positions);
    stats.fold_fallbacks += guard_folds(m, coarse.features, corner, positions);
    if (coarse.pass_smooth_normals) fine_normals = split4_smooth_normals(m, corner);
  }

  Split4Topology t = split4_topology(m, coarse.features);
  Level fine;
  fine.mesh = Mesh::from_parts_with_edges(std::move(positions), std::move(t.corner_vertex),
                                          std::move(t.twin), std::move(t.edge_of),
                                          std::move(t.edge_halfedge), std::move(t.vertex_halfedge));
  fine.features = split4_features(m, coarse.features, std::move(t.sharp));
  fine.step = coarse.step + 1;
  fine.smooth_normals = std::move(fine_normals);
  // Old vertices keep their ids and valences and new interior vertices have valence 6:
  // the fine level's irregular vertices are the coarse level's.
  const IrregularVertices& carried = irregular.list ? irregular : coarse.irregular;
  if (carried.valid_for(m))
    fine.irregular = {carried.list, fine.mesh.corner_vertices().data(), fine.mesh.num_vertices(),
                      fine.mesh.num_faces()};
  return fine;
}

}  // namespace stlrefine
