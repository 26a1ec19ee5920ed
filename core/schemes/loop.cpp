// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/loop.h"

#include <cmath>
#include <numbers>

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

double loop_beta(int n) {
  const double lambda = 3.0 / 8.0 + std::cos(2.0 * std::numbers::pi / n) / 4.0;
  return (5.0 / 8.0 - lambda * lambda) / n;
}

bool is_regular_crease_vertex(const Mesh& mesh, const Features& features, VertexId v) {
  if (features.kind(v) != VertexKind::Crease) return false;
  if (mesh.is_boundary(v)) return mesh.valence(v) == 4;
  // Interior: the two sharp edges split the six edges into sectors of 2 smooth edges each.
  int valence = 0, smooth_run = 0, first_run = -1;
  bool ok = true;
  for_each_outgoing(mesh, v, [&](HalfedgeId h) {
    ++valence;
    if (features.is_sharp(mesh.edge(h))) {
      if (first_run < 0)
        first_run = smooth_run;
      else
        ok &= smooth_run == 2;
      smooth_run = 0;
    } else {
      ++smooth_run;
    }
  });
  // The run before the first sharp edge joins the run after the last one (cyclic ring).
  return ok && valence == 6 && first_run + smooth_run == 2;
}

namespace {

//   E-mask (smooth edge a-b)     a, b: 3/8     c, d: 1/8 (opposite vertices)
Vec3 smooth_edge_point(const Mesh& m, HalfedgeId h) {
  const Vec3& a = m.position(m.from(h));
  const Vec3& b = m.position(m.to(h));
  const Vec3& c = m.position(m.opposite(h));
  const Vec3& d = m.position(m.opposite(m.twin(h)));
  return 0.375 * (a + b) + 0.125 * (c + d);
}

bool is_special(const Mesh& m, const Features& f, VertexId v) {
  return f.kind(v) == VertexKind::Corner ||
         (f.kind(v) == VertexKind::Crease && !is_regular_crease_vertex(m, f, v));
}

}  // namespace

void LoopStencil::edge_points(const Level& coarse, std::span<Vec3> out) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    const HalfedgeId h = m.halfedge(edge);
    if (!f.is_sharp(edge)) {
      out[e] = smooth_edge_point(m, h);
      return;
    }
    const VertexId a = m.from(h), b = m.to(h);
    // Hoppe's sharp-edge rules, first match wins.
    if (f.kind(a) == VertexKind::Dart || f.kind(b) == VertexKind::Dart) {
      out[e] = smooth_edge_point(m, h);  // the crease fades out towards its dart end
      return;
    }
    const bool special_a = is_special(m, f, a), special_b = is_special(m, f, b);
    const bool regular_a = is_regular_crease_vertex(m, f, a);
    const bool regular_b = is_regular_crease_vertex(m, f, b);
    if (special_a && regular_b) {
      out[e] = 0.375 * m.position(a) + 0.625 * m.position(b);
    } else if (special_b && regular_a) {
      out[e] = 0.625 * m.position(a) + 0.375 * m.position(b);
    } else {
      out[e] = 0.5 * (m.position(a) + m.position(b));
    }
  });
}

void LoopStencil::vertex_points(const Level& coarse, std::span<Vec3> out) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    const Vec3& p = m.position(v);
    switch (f.kind(v)) {
      case VertexKind::Corner:
        out[i] = p;
        return;
      case VertexKind::Crease: {
        //   a 1/8 --- v 3/4 --- b 1/8   (a, b: the two sharp neighbours)
        const auto& ends = f.curve_neighbours(v);
        out[i] = 0.75 * p + 0.125 * (m.position(ends[0]) + m.position(ends[1]));
        return;
      }
      case VertexKind::Smooth:
      case VertexKind::Dart: {
        if (m.is_isolated(v)) {
          out[i] = p;
          return;
        }
        Vec3 sum;
        const int n = for_each_ring_vertex_from(m, m.halfedge(v),
                                                [&](int, VertexId w) { sum += m.position(w); });
        const double beta = loop_beta(n);
        out[i] = (1.0 - n * beta) * p + beta * sum;
        return;
      }
    }
  });
}

}  // namespace stlrefine
