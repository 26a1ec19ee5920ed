// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Our slicer against CGAL::Polygon_mesh_slicer (the reference implementation) on the same
// planes, and our loops checked for simplicity with CGAL's exact 2-D predicates.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>
#include <CGAL/Polygon_mesh_slicer.h>
#include <CGAL/Surface_mesh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/refine.h"
#include "slicer/slice.h"
#include "tests/slicer/slicer_test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;
using CgalPolyline = std::vector<K::Point_3>;

SurfaceMesh to_surface_mesh(const Mesh& mesh) {
  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> v;
  for (const Vec3& p : mesh.positions()) v.push_back(sm.add_vertex(K::Point_3(p.x, p.y, p.z)));
  for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
    const auto c = mesh.face_vertices(FaceId(std::uint32_t(f)));
    sm.add_face(v[c[0].idx], v[c[1].idx], v[c[2].idx]);
  }
  return sm;
}

struct Totals {
  std::size_t closed = 0, open = 0;
  double length = 0, abs_area = 0;
};

Totals ours(const slicer::Layer& l) {
  Totals t;
  const auto add = [&](const std::vector<slicer::Point2>& pts, bool closed) {
    for (std::size_t i = 0; i + 1 < pts.size() + (closed ? 1 : 0); ++i) {
      const auto& a = pts[i];
      const auto& b = pts[(i + 1) % pts.size()];
      t.length += std::hypot(b.x - a.x, b.y - a.y);
    }
  };
  for (const auto& loop : l.loops)
    add(loop.points, true), t.abs_area += std::fabs(loop.area), ++t.closed;
  for (const auto& p : l.open) add(p.points, false), ++t.open;
  return t;
}

Totals cgal(const std::vector<CgalPolyline>& polylines) {
  Totals t;
  for (const CgalPolyline& p : polylines) {
    const bool closed = p.size() > 2 && p.front() == p.back();
    ++(closed ? t.closed : t.open);
    double twice = 0;
    for (std::size_t i = 0; i + 1 < p.size(); ++i) {
      t.length += std::sqrt(CGAL::squared_distance(p[i], p[i + 1]));
      twice += (p[i].x() - p[0].x()) * (p[i + 1].y() - p[0].y()) -
               (p[i].y() - p[0].y()) * (p[i + 1].x() - p[0].x());
    }
    if (closed) t.abs_area += std::fabs(0.5 * twice);
  }
  return t;
}

void expect_agreement(const Mesh& mesh, const slicer::SliceParams& params) {
  const SurfaceMesh sm = to_surface_mesh(mesh);
  CGAL::Polygon_mesh_slicer<SurfaceMesh, K> cgal_slicer(sm);
  for (const slicer::Layer& l : slicer::slice_all(mesh, params)) {
    std::vector<CgalPolyline> polylines;
    cgal_slicer(K::Plane_3(0, 0, 1, -l.z), std::back_inserter(polylines));
    const Totals a = ours(l), b = cgal(polylines);
    EXPECT_EQ(a.closed, b.closed) << "z = " << l.z;
    EXPECT_EQ(a.open, b.open) << "z = " << l.z;
    EXPECT_NEAR(a.length, b.length, 1e-9 * (1 + b.length)) << "z = " << l.z;
    EXPECT_NEAR(a.abs_area, b.abs_area, 1e-9 * (1 + b.abs_area)) << "z = " << l.z;
  }
}

TEST(CgalAgreement, TorusSphereAndRefinedCylinderMatchPolygonMeshSlicer) {
  // Planes off the vertices (CGAL has no common rule for planes through them).
  expect_agreement(to_mesh(torus_soup(40, 20, 15, 5)), uniform(0.37));
  expect_agreement(to_mesh(icosphere_soup(3, 10.0)), uniform(0.41));
  RefineParams rp;
  rp.levels = 2;
  expect_agreement(refine(to_mesh(cylinder_soup(24, 10.0, 20.0)), rp).mesh, uniform(0.43));
}

TEST(CgalAgreement, OpenBoxMatchesPolygonMeshSlicer) {
  expect_agreement(to_mesh(open_box_soup(10.0)), uniform(0.9));
}

TEST(CgalAgreement, LoopsAreSimplePolygons) {
  RefineParams rp;
  rp.levels = 2;
  const Mesh mesh = refine(to_mesh(torus_soup(24, 12, 15, 5)), rp).mesh;
  std::size_t loops = 0;
  for (const slicer::Layer& l : slicer::slice_all(mesh, uniform(0.2))) {
    for (const auto& loop : l.loops) {
      std::vector<K::Point_2> pts;
      for (const auto& p : loop.points) pts.emplace_back(p.x, p.y);
      EXPECT_TRUE(CGAL::is_simple_2(pts.begin(), pts.end(), K())) << "z = " << l.z;
      ++loops;
    }
  }
  EXPECT_GT(loops, 50u);
}

}  // namespace
}  // namespace stlrefine::test
