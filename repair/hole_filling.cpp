// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "repair/hole_filling.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>

#include <chrono>
#include <iterator>
#include <optional>
#include <vector>

#include "core/error.h"

namespace stlrefine::repair {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Halfedge = SurfaceMesh::Halfedge_index;

// Our mesh as a CGAL Surface_mesh with the same vertex and face indices, or nothing when a
// face does not fit: build_mesh cuts a non-manifold edge into two boundary edges between
// the same two vertices, which a Surface_mesh cannot hold without another vertex.
std::optional<SurfaceMesh> to_surface_mesh(const Mesh& mesh) {
  SurfaceMesh sm;
  sm.reserve(static_cast<SurfaceMesh::size_type>(mesh.num_vertices()),
             static_cast<SurfaceMesh::size_type>(mesh.num_halfedges() / 2 + mesh.num_faces()),
             static_cast<SurfaceMesh::size_type>(mesh.num_faces()));
  for (const Vec3& p : mesh.positions()) sm.add_vertex(Point(p.x, p.y, p.z));
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    const SurfaceMesh::Face_index added =
        sm.add_face(SurfaceMesh::Vertex_index(a.idx), SurfaceMesh::Vertex_index(b.idx),
                    SurfaceMesh::Vertex_index(c.idx));
    if (added == SurfaceMesh::null_face()) return std::nullopt;
  }
  return sm;
}

// The mesh as it is (a copy through its soup), for a repair that could not run.
IngestResult unchanged(const Mesh& mesh) {
  IndexedSoup soup;
  soup.positions.assign(mesh.positions().begin(), mesh.positions().end());
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    soup.triangles.push_back({a.idx, b.idx, c.idx});
  }
  return build_mesh(soup);
}

// One border half-edge per boundary loop, with the loop's length.
std::vector<std::pair<Halfedge, std::size_t>> boundary_loops(const SurfaceMesh& sm) {
  std::vector<std::pair<Halfedge, std::size_t>> loops;
  std::vector<bool> seen(sm.number_of_halfedges(), false);
  for (Halfedge h : sm.halfedges()) {
    if (seen[h.idx()] || !sm.is_border(h)) continue;
    std::size_t length = 0;
    for (Halfedge g = h; !seen[g.idx()]; g = sm.next(g)) {
      seen[g.idx()] = true;
      ++length;
    }
    loops.emplace_back(h, length);
  }
  return loops;
}

}  // namespace

std::string_view to_string(RepairMode mode) {
  return mode == RepairMode::FillHoles ? "fill_holes" : "none";
}

IngestResult fill_holes(const Mesh& mesh, const HoleFillOptions& options, HoleFillReport& report,
                        const std::atomic<bool>* cancel) {
  const auto start = std::chrono::steady_clock::now();
  report = HoleFillReport{};
  std::size_t predicted_added = 0;
  std::optional<SurfaceMesh> converted = to_surface_mesh(mesh);
  if (!converted) {
    report.skipped = true;
    return unchanged(mesh);
  }
  SurfaceMesh& sm = *converted;
  const std::size_t faces_before = sm.number_of_faces();
  const std::size_t vertices_before = sm.number_of_vertices();
  for (const auto& [border, length] : boundary_loops(sm)) {
    ++report.holes;
    report.largest_hole_edges = std::max(report.largest_hole_edges, length);
    if (length > options.max_hole_edges) {
      ++report.left_open;
      continue;
    }
    if (cancel && cancel->load(std::memory_order_relaxed))
      throw Error(ErrorCode::Cancelled, "cancelled", "cancelled while filling holes");
    // Never Liepa's cubic search over all diagonals (minutes on a long hostile rim): the
    // 2D constrained Delaunay triangulation for a rim that projects onto a plane, else the
    // 3D Delaunay search space; a hole neither can fill stays open.
    const auto np = CGAL::parameters::use_2d_constrained_delaunay_triangulation(true)
                        .do_not_use_cubic_algorithm(true);
    std::vector<SurfaceMesh::Face_index> faces;
    std::vector<SurfaceMesh::Vertex_index> vertices;
    // Refining a hole to its rim's density adds ~0.2 n^2 faces for a rim of n edges (a
    // 4,000-edge rim: ~750k faces, GBs): only short rims are refined and faired, and only
    // while the request's total stays within max_added_faces; the others get the rim's
    // own triangulation (n - 2 faces, no new vertex).
    const std::size_t refined_estimate = length * length / 5 + length;
    const bool refine = length <= options.max_refined_rim &&
                        predicted_added + refined_estimate <= options.max_added_faces;
    bool faired = false;
    if (refine) {
      faired = std::get<0>(CGAL::Polygon_mesh_processing::triangulate_refine_and_fair_hole(
          sm, border, std::back_inserter(faces), std::back_inserter(vertices), np));
      predicted_added += refined_estimate;
    } else {
      CGAL::Polygon_mesh_processing::triangulate_hole(sm, border, std::back_inserter(faces), np);
      predicted_added += length;
      ++report.flat;
    }
    if (faces.empty()) {
      ++report.left_open;  // CGAL found no triangulation (a degenerate rim)
      continue;
    }
    ++report.filled;
    if (refine && !faired) ++report.fairing_failed;
  }
  report.faces_added = sm.number_of_faces() - faces_before;
  report.vertices_added = sm.number_of_vertices() - vertices_before;

  // Back to a Mesh: Surface_mesh only appends (nothing was removed), so the input's vertex
  // and face indices are unchanged and its positions are the same doubles.
  IndexedSoup soup;
  soup.positions.reserve(sm.number_of_vertices());
  for (SurfaceMesh::Vertex_index v : sm.vertices()) {
    const Point& p = sm.point(v);
    soup.positions.push_back({p.x(), p.y(), p.z()});
  }
  soup.triangles.reserve(sm.number_of_faces());
  for (SurfaceMesh::Face_index f : sm.faces()) {
    std::array<std::uint32_t, 3> t{};
    int k = 0;
    for (SurfaceMesh::Vertex_index v : CGAL::vertices_around_face(sm.halfedge(f), sm))
      if (k < 3) t[k++] = static_cast<std::uint32_t>(v.idx());
    soup.triangles.push_back(t);
  }
  IngestResult out = build_mesh(soup);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace stlrefine::repair
