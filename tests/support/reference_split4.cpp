// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/reference_split4.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "tests/support/mesh_queries.h"

namespace stlrefine::test {

namespace {

std::vector<RingEntry> sharp_entries(const Level& level, VertexId v) {
  std::vector<RingEntry> out;
  for (const RingEntry& r : ring(level.mesh, v))
    if (level.features.is_sharp(r.edge)) out.push_back(r);
  return out;
}

// The sharp neighbour of crease vertex x other than along edge `along`; invalid when x ends
// the polyline (corner or dart).
VertexId curve_beyond(const Level& level, VertexId x, EdgeId along) {
  if (level.features.kind(x) != VertexKind::Crease) return VertexId();
  for (const RingEntry& r : sharp_entries(level, x))
    if (r.edge != along) return r.vertex;
  return VertexId();
}

}  // namespace

double loop_beta(int n) {
  const double l = 3.0 / 8.0 + std::cos(2.0 * std::numbers::pi / n) / 4.0;
  return (5.0 / 8.0 - l * l) / n;
}

std::vector<double> butterfly_ring_weights(int k) {
  if (k == 3) return {5.0 / 12.0, -1.0 / 12.0, -1.0 / 12.0};
  if (k == 4) return {3.0 / 8.0, 0.0, -1.0 / 8.0, 0.0};
  std::vector<double> s(k);
  for (int j = 0; j < k; ++j) {
    const double t = 2.0 * std::numbers::pi * j / k;
    s[j] = (0.25 + std::cos(t) + 0.5 * std::cos(2.0 * t)) / k;
  }
  return s;
}

bool loop_regular_crease(const Level& level, VertexId v) {
  if (level.features.kind(v) != VertexKind::Crease) return false;
  const Mesh& m = level.mesh;
  if (m.is_boundary(v)) return m.valence(v) == 4;
  const auto r = ring(m, v);
  if (r.size() != 6) return false;
  std::vector<int> sharp;
  for (int i = 0; i < 6; ++i)
    if (level.features.is_sharp(r[i].edge)) sharp.push_back(i);
  return sharp.size() == 2 && sharp[1] - sharp[0] == 3;
}

ReferenceStep reference_loop_step(const Level& coarse) {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  const std::size_t nv = m.num_vertices();
  ReferenceStep out;
  out.positions.resize(nv + m.num_edges());
  out.unspecified.assign(m.num_edges(), false);

  // Vertex rules.
  for (std::uint32_t i = 0; i < nv; ++i) {
    const VertexId v(i);
    const Vec3 p = m.position(v);
    switch (f.kind(v)) {
      case VertexKind::Corner:
        out.positions[i] = p;
        break;
      case VertexKind::Crease: {
        const auto s = sharp_entries(coarse, v);
        out.positions[i] =
            p * (3.0 / 4.0) + (m.position(s[0].vertex) + m.position(s[1].vertex)) * (1.0 / 8.0);
        break;
      }
      case VertexKind::Smooth:
      case VertexKind::Dart: {
        const auto r = ring(m, v);
        const int n = static_cast<int>(r.size());
        const double beta = loop_beta(n);
        Vec3 sum;
        for (const RingEntry& e : r) sum += m.position(e.vertex);
        out.positions[i] = p * (1.0 - n * beta) + sum * beta;
        break;
      }
    }
  }

  // Edge rules.
  for (std::uint32_t i = 0; i < m.num_edges(); ++i) {
    const EdgeId e(i);
    const HalfedgeId h = m.halfedge(e);
    const VertexId a = m.from(h), b = m.to(h);
    const Vec3 pa = m.position(a), pb = m.position(b);
    auto smooth_mask = [&] {
      const Vec3 c = m.position(m.opposite(h));
      const Vec3 d = m.position(m.opposite(m.twin(h)));
      return (pa + pb) * (3.0 / 8.0) + (c + d) * (1.0 / 8.0);
    };
    Vec3 q;
    if (!f.is_sharp(e)) {
      q = smooth_mask();
    } else if (f.kind(a) == VertexKind::Dart || f.kind(b) == VertexKind::Dart) {
      q = smooth_mask();
    } else {
      const bool ra = loop_regular_crease(coarse, a), rb = loop_regular_crease(coarse, b);
      if (!ra && rb) {
        q = pa * (3.0 / 8.0) + pb * (5.0 / 8.0);
      } else if (ra && !rb) {
        q = pb * (3.0 / 8.0) + pa * (5.0 / 8.0);
      } else {
        q = (pa + pb) * 0.5;
      }
    }
    out.positions[nv + i] = q;
  }
  return out;
}

ReferenceStep reference_butterfly_step(const Level& coarse) {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  const std::size_t nv = m.num_vertices();
  ReferenceStep out;
  out.positions.assign(m.positions().begin(), m.positions().end());
  out.positions.resize(nv + m.num_edges());
  out.unspecified.assign(m.num_edges(), false);

  // Zorin's one-sided rule around interior vertex v, ring starting at e0.
  auto one_sided = [&](VertexId v, VertexId e0) {
    const auto r = ring(m, v);
    const int k = static_cast<int>(r.size());
    int start = 0;
    while (r[start].vertex != e0) ++start;
    const auto s = butterfly_ring_weights(k);
    Vec3 q = m.position(v) * 0.75;
    for (int j = 0; j < k; ++j) q += m.position(r[(start + j) % k].vertex) * s[j];
    return q;
  };
  auto extraordinary = [&](VertexId v) {
    return f.kind(v) == VertexKind::Smooth && m.valence(v) != 6;
  };
  // Tip across the edge of half-edge g, seen from g's face; virtual when the edge is
  // sharp or a boundary: reflect the face's third vertex (p_i + p_j - p_k).
  auto across = [&](HalfedgeId g) {
    const HalfedgeId t = m.twin(g);
    if (t.valid() && !f.is_sharp(m.edge(g))) return m.position(m.opposite(t));
    return m.position(m.from(g)) + m.position(m.to(g)) - m.position(m.opposite(g));
  };

  for (std::uint32_t i = 0; i < m.num_edges(); ++i) {
    const EdgeId e(i);
    const HalfedgeId h = m.halfedge(e);
    const VertexId a0 = m.from(h), a1 = m.to(h);
    const Vec3 pa = m.position(a0), pb = m.position(a1);
    Vec3 q;
    if (f.is_sharp(e)) {
      // 4-point curve rule with the end condition p_{-1} = 2 p_0 - p_1.
      const VertexId ap = curve_beyond(coarse, a0, e), bp = curve_beyond(coarse, a1, e);
      const Vec3 pap = ap.valid() ? m.position(ap) : pa * 2.0 - pb;
      const Vec3 pbp = bp.valid() ? m.position(bp) : pb * 2.0 - pa;
      q = (pa + pb) * (9.0 / 16.0) - (pap + pbp) * (1.0 / 16.0);
    } else if (f.kind(a0) == VertexKind::Dart || f.kind(a1) == VertexKind::Dart) {
      // Open in the spec: keep the midpoint as a placeholder and let callers skip it.
      q = (pa + pb) * 0.5;
      out.unspecified[i] = true;
    } else if (extraordinary(a0) && extraordinary(a1)) {
      q = (one_sided(a0, a1) + one_sided(a1, a0)) * 0.5;
    } else if (extraordinary(a0)) {
      q = one_sided(a0, a1);
    } else if (extraordinary(a1)) {
      q = one_sided(a1, a0);
    } else {
      // 8-point butterfly; face of h is (a0, a1, b1), face of g = twin(h) is (a1, a0, b2).
      const HalfedgeId g = m.twin(h);
      const Vec3 b1 = m.position(m.opposite(h)), b2 = m.position(m.opposite(g));
      const Vec3 c = across(Mesh::prev(h)) + across(Mesh::next(h)) + across(Mesh::next(g)) +
                     across(Mesh::prev(g));
      q = (pa + pb) * 0.5 + (b1 + b2) * (1.0 / 8.0) - c * (1.0 / 16.0);
    }
    out.positions[nv + i] = q;
  }
  return out;
}

std::vector<std::array<std::uint32_t, 3>> reference_split4_faces(const Mesh& coarse) {
  const auto nv = static_cast<std::uint32_t>(coarse.num_vertices());
  std::vector<std::array<std::uint32_t, 3>> faces;
  faces.reserve(4 * coarse.num_faces());
  for (std::uint32_t fi = 0; fi < coarse.num_faces(); ++fi) {
    std::array<std::uint32_t, 3> v{}, mid{};
    for (int k = 0; k < 3; ++k) {
      const HalfedgeId h = Mesh::halfedge(FaceId(fi), k);
      v[k] = coarse.from(h).idx;
      mid[k] = nv + coarse.edge(h).idx;  // on edge v[k] -> v[k+1]
    }
    for (int k = 0; k < 3; ++k) faces.push_back({v[k], mid[k], mid[(k + 2) % 3]});
    faces.push_back({mid[0], mid[1], mid[2]});
  }
  return faces;
}

double min_child_parent_cos(const Mesh& coarse, std::span<const Vec3> fine) {
  const auto faces = reference_split4_faces(coarse);
  double worst = 1.0;
  for (std::uint32_t fi = 0; fi < coarse.num_faces(); ++fi) {
    const Vec3 np = normalized(coarse.face_normal(FaceId(fi)));
    if (norm(np) == 0) continue;
    for (int k = 0; k < 4; ++k) {
      const auto& t = faces[4 * fi + k];
      const Vec3 nc = normalized(triangle_normal(fine[t[0]], fine[t[1]], fine[t[2]]));
      if (norm(nc) == 0) continue;
      worst = std::min(worst, dot(np, nc));
    }
  }
  return worst;
}

}  // namespace stlrefine::test
