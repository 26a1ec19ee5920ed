// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/cad_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <utility>

#include "core/mesh/build_mesh.h"
#include "tests/support/mesh_queries.h"

namespace stlrefine::fidelity {

CadMetrics measure_cad(const Mesh& mesh, const test::TrueSurface& surface, std::size_t samples) {
  CadMetrics m;
  const std::size_t nf = mesh.num_faces();
  m.faces = nf;
  m.vertices = mesh.num_vertices();
  const int k = std::clamp(static_cast<int>(std::ceil(
                               std::sqrt(double(samples) / double(std::max<std::size_t>(nf, 1))))),
                           1, 16);
  auto dist = [&](const Vec3& p) { return distance(p, surface.closest_point(p).point); };
  const double crease_snap = 1e-6 * test::bbox_diagonal(mesh);
  double sum_w = 0, sum_d2 = 0, sum_a2 = 0, total_area = 0;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const auto fv = mesh.face_vertices(FaceId(f));
    const Vec3 &a = mesh.position(fv[0]), &b = mesh.position(fv[1]), &c = mesh.position(fv[2]);
    const Vec3 area_vector = triangle_normal(a, b, c);
    const double area = 0.5 * norm(area_vector);
    const Vec3 n = normalized(area_vector);
    total_area += area;
    auto at = [&](double s, double t) { return a + (b - a) * s + (c - a) * t; };

    // --- the centroid's closest point (with k = 1 the face's one distance sample); the
    // normal against the truth below
    const Vec3 centroid = (a + b + c) * (1.0 / 3);
    test::SurfacePoint cs = surface.closest_point(centroid);
    // A crease within float32 rounding of the closest point is where the face is: meshes
    // measured here went through binary STL (vertices rounded by about 1e-7 of the size),
    // which can leave a face of a flat cap a hair below the cap plane and just outside the
    // rim, so that its nearest piece is the side wall (scored at 90 degrees) although the
    // nearest point is the rim itself, a crease whose arc of normals holds the face's.
    if (!cs.on_crease() && crease_snap > 0)
      if (const auto crease = surface.closest_crease_point(centroid);
          crease && distance(crease->point, cs.point) <= crease_snap)
        cs = *crease;
    if (n == Vec3{}) {
      ++m.degenerate_faces;
    } else {
      // The best agreeing of the centroid's and the corners' closest points (a flat face a
      // hair past its rim is not a fold; see test::face_truth_angle_deg).
      const double angle = test::face_truth_angle_deg(surface, n, a, b, c, crease_snap);
      sum_a2 += area * angle * angle;
      m.worst_normal_deg = std::max(m.worst_normal_deg, angle);
      if (angle > 90) ++m.folded;
      if (angle > 60) ++m.over_60;
    }

    // --- distance: the k^2 equal sub-triangles' centroids, area-weighted; the maximum also
    // over the barycentric lattice (its vertices and edge points included)
    if (k == 1) {
      const double d = distance(centroid, cs.point);
      sum_d2 += area * d * d;
      sum_w += area;
      m.max = std::max(m.max, d);
      continue;
    }
    const double w = area / (k * k);
    auto rms_sample = [&](double s, double t) {
      const double d = dist(at(s, t));
      sum_d2 += w * d * d;
      sum_w += w;
      m.max = std::max(m.max, d);
    };
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j) {
        rms_sample((i + 1.0 / 3) / k, (j + 1.0 / 3) / k);
        if (i + j + 1 < k) rms_sample((i + 2.0 / 3) / k, (j + 2.0 / 3) / k);
      }
    for (int i = 0; i <= k; ++i)
      for (int j = 0; i + j <= k; ++j)
        m.max = std::max(m.max, dist(at(double(i) / k, double(j) / k)));
  }
  if (k == 1) {
    // Fine meshes: the maximum over every vertex and edge midpoint once.
    for (const Vec3& p : mesh.positions()) m.max = std::max(m.max, dist(p));
    for (std::uint32_t e = 0; e < mesh.num_edges(); ++e) {
      const HalfedgeId h = mesh.halfedge(EdgeId(e));
      m.max =
          std::max(m.max, dist((mesh.position(mesh.from(h)) + mesh.position(mesh.to(h))) * 0.5));
    }
  }
  m.rms = sum_w > 0 ? std::sqrt(sum_d2 / sum_w) : 0;
  m.normal_rms_deg = total_area > 0 ? std::sqrt(sum_a2 / total_area) : 0;
  return m;
}

Mesh ideal_refinement(const test::CadShape& shape, int levels) {
  const test::TrueSurface& surface = *shape.surface;
  IndexedSoup soup = shape.soup;
  using Edge = std::pair<std::uint32_t, std::uint32_t>;
  std::set<Edge> crease;
  for (const auto& [a, b] : shape.crease_edges) crease.insert({a, b});
  for (int level = 0; level < levels; ++level) {
    std::map<Edge, std::uint32_t> edge_point;
    std::set<Edge> next_crease;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const Edge key = std::minmax(a, b);
      const auto it = edge_point.find(key);
      if (it != edge_point.end()) return it->second;
      const Vec3 m = (soup.positions[a] + soup.positions[b]) * 0.5;
      const bool on_crease = crease.count(key) > 0;
      soup.positions.push_back(on_crease ? surface.closest_crease_point(m)->point
                                         : surface.closest_point(m).point);
      const auto id = static_cast<std::uint32_t>(soup.positions.size() - 1);
      edge_point.emplace(key, id);
      if (on_crease) {
        next_crease.insert(std::minmax(a, id));
        next_crease.insert(std::minmax(id, b));
      }
      return id;
    };
    std::vector<std::array<std::uint32_t, 3>> next;
    next.reserve(soup.triangles.size() * 4);
    for (const auto& t : soup.triangles) {
      const std::uint32_t ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({ab, t[1], bc});
      next.push_back({ca, bc, t[2]});
      next.push_back({ab, bc, ca});
    }
    soup.triangles = std::move(next);
    crease = std::move(next_crease);
  }
  return build_mesh(soup).mesh;
}

}  // namespace stlrefine::fidelity
