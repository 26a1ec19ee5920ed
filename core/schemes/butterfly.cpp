// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/butterfly.h"

#include <cmath>
#include <numbers>

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"
#include "core/schemes/split4_host.h"

namespace stlrefine {

double ButterflyStencil::extraordinary_weight(int k, int j) {
  if (k == 3) return j == 0 ? 5.0 / 12.0 : -1.0 / 12.0;
  if (k == 4) return j == 0 ? 3.0 / 8.0 : j == 2 ? -1.0 / 8.0 : 0.0;
  const double t = 2.0 * std::numbers::pi * j / k;
  return (0.25 + std::cos(t) + 0.5 * std::cos(2.0 * t)) / k;
}

ButterflyStencil::ButterflyStencil(Extraordinary rule, bool check_normals)
    : rule_(rule), check_normals_(check_normals), weights_(kCachedValences) {
  for (int k = 3; k < kCachedValences; ++k) {
    weights_[k].resize(k);
    for (int j = 0; j < k; ++j) weights_[k][j] = extraordinary_weight(k, j);
  }
}

namespace {

// Per vertex: its valence when it gets the extraordinary rule (ring whole, i.e. smooth or
// dart, and valence not 6), else 0. A sharp endpoint's ring is cut: it counts as regular.
// So does a whole ring of valence 2 (two faces folded onto each other, e.g. a facet and its
// reverse with zero dihedral angle): Zorin's weights exist only for k >= 3 (they sum to
// 1/4 only there), and reading them at k = 2 read an empty table (a crash, found by fuzzing).
std::vector<int> extraordinary_valences(const Mesh& m, const Features& f) {
  std::vector<int> k(m.num_vertices(), 0);
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    if (f.cuts_ring(v) || m.is_isolated(v)) return;
    const int n = m.valence(v);
    k[i] = n == 6 || n < 3 ? 0 : n;
  });
  return k;
}

//           c1 ------ b1 ------ c2        a0, a1: 1/2
//             \      /  \      /          b1, b2: 1/8
//              \    /    \    /           c1..c4: -1/16, each a virtual point
//               a0 ---x---- a1            (tip_across) when beyond a sharp edge
//              /    \    /    \           .
//             /      \  /      \          .
//           c4 ------ b2 ------ c3
Vec3 eight_point(const Mesh& m, const Features& f, HalfedgeId h) {
  const HalfedgeId t = m.twin(h);
  const Vec3 a = m.position(m.from(h)) + m.position(m.to(h));
  const Vec3 b = m.position(m.opposite(h)) + m.position(m.opposite(t));
  const Vec3 c = tip_across(m, f, Mesh::next(h)) + tip_across(m, f, Mesh::prev(h)) +
                 tip_across(m, f, Mesh::next(t)) + tip_across(m, f, Mesh::prev(t));
  return 0.5 * a + 0.125 * b - 0.0625 * c;
}

//   a' ---- a ---x--- b ---- b'    -1/16, 9/16, 9/16, -1/16 along the sharp polyline;
//   a missing a' or b' (polyline end) is the end condition 2a - b.
Vec3 four_point(const Mesh& m, const Features& f, HalfedgeId h) {
  const auto [before, a, b, after] = curve_window(m, f, h);
  return 0.5625 * (a + b) - 0.0625 * (before + after);
}

}  // namespace

Vec3 ButterflyStencil::one_sided_point(const Mesh& m, HalfedgeId h, int k) const {
  //        e2 ---- e1
  //       /  \    /  \        v: 3/4, e_j: s_j (j counted from the edge's far end e0)
  //    e3 ---- v ---x-- e0
  //       \  /    \  /
  //        e4 ---- e5
  Vec3 sum = 0.75 * m.position(m.from(h));
  if (k < kCachedValences) {
    const std::vector<double>& s = weights_[k];
    for_each_ring_vertex_from(m, h, [&](int j, VertexId w) { sum += s[j] * m.position(w); });
  } else {
    for_each_ring_vertex_from(
        m, h, [&](int j, VertexId w) { sum += extraordinary_weight(k, j) * m.position(w); });
  }
  return sum;
}

void ButterflyStencil::edge_points(const Level& coarse, std::span<Vec3> out) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  const std::vector<int> extraordinary = rule_ == Extraordinary::Zorin
                                             ? extraordinary_valences(m, f)
                                             : std::vector<int>(m.num_vertices(), 0);
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    const HalfedgeId h = m.halfedge(edge);
    if (f.is_sharp(edge)) {
      out[e] = four_point(m, f, h);
      return;
    }
    const int k0 = extraordinary[m.from(h).idx];
    const int k1 = extraordinary[m.to(h).idx];
    if (k0 && k1) {
      out[e] = 0.5 * (one_sided_point(m, h, k0) + one_sided_point(m, m.twin(h), k1));
    } else if (k0) {
      out[e] = one_sided_point(m, h, k0);
    } else if (k1) {
      out[e] = one_sided_point(m, m.twin(h), k1);
    } else {
      out[e] = eight_point(m, f, h);
    }
  });
  // Ours (issue 17): Zorin's rule at uneven rings checked against the surface's normals. The
  // original butterfly (butterfly-g1's base) stays the paper's.
  if (checks_against_normals()) check_edge_points_against_normals(m, f, out);
}

}  // namespace stlrefine
