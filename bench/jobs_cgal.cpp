// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <CGAL/IO/STL.h>
#include <CGAL/Polygon_mesh_processing/IO/polygon_mesh_io.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Subdivision_method_3/subdivision_methods_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/IO/polygon_mesh_io.h>
#include <CGAL/version.h>

#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/jobs.h"

namespace stlrefine::bench {
namespace {

namespace fs = std::filesystem;
using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;

std::uint64_t stl_header_triangles(const fs::path& path) {
  const auto size = fs::file_size(path);
  return size >= 84 ? (size - 84) / 50 : 0;
}

enum class CgalMethod { Loop, Sqrt3 };

class CgalSubdivide final : public Job {
 public:
  CgalSubdivide(const fs::path& path, int levels, CgalMethod method)
      : levels_(levels), method_(method) {
    const IndexedSoup soup = load_ingested_triangles(path);
    const double t0 = now_seconds();
    {
      std::vector<Point> points;
      points.reserve(soup.positions.size());
      for (const Vec3& p : soup.positions) points.emplace_back(p.x, p.y, p.z);
      std::vector<std::array<std::size_t, 3>> polygons;
      polygons.reserve(soup.triangles.size());
      for (const auto& t : soup.triangles) polygons.push_back({t[0], t[1], t[2]});
      if (!CGAL::Polygon_mesh_processing::is_polygon_soup_a_polygon_mesh(polygons)) {
        throw std::runtime_error("CGAL: our ingested mesh is not a polygon mesh for CGAL");
      }
      CGAL::Polygon_mesh_processing::polygon_soup_to_polygon_mesh(points, polygons, mesh_);
    }
    convert_seconds_ = now_seconds() - t0;
    in_faces_ = mesh_.number_of_faces();
  }
  void run() override {
    const auto iterations = CGAL::parameters::number_of_iterations(levels_);
    if (method_ == CgalMethod::Loop)
      CGAL::Subdivision_method_3::Loop_subdivision(mesh_, iterations);
    else
      CGAL::Subdivision_method_3::Sqrt3_subdivision(mesh_, iterations);
  }
  std::uint64_t in_faces() const override { return in_faces_; }
  std::uint64_t out_faces() const override { return mesh_.number_of_faces(); }
  std::uint64_t out_vertices() const override { return mesh_.number_of_vertices(); }
  double convert_seconds() const override { return convert_seconds_; }

 private:
  int levels_;
  CgalMethod method_;
  SurfaceMesh mesh_;
  std::uint64_t in_faces_ = 0;
  double convert_seconds_ = 0;
};

enum class CgalRead { Soup, Mesh, MeshRepair };

class CgalReader final : public Job {
 public:
  CgalReader(const fs::path& path, CgalRead variant) : path_(path), variant_(variant) {}
  void run() override {
    const std::string name = path_.string();
    bool ok = false;
    switch (variant_) {
      case CgalRead::Soup:
        ok = CGAL::IO::read_STL(name, points_, triangles_);
        faces_ = triangles_.size();
        vertices_ = points_.size();
        break;
      case CgalRead::Mesh:
        ok = CGAL::IO::read_polygon_mesh(name, mesh_);
        faces_ = mesh_.number_of_faces();
        vertices_ = mesh_.number_of_vertices();
        break;
      case CgalRead::MeshRepair:
        ok = CGAL::Polygon_mesh_processing::IO::read_polygon_mesh(name, mesh_);
        faces_ = mesh_.number_of_faces();
        vertices_ = mesh_.number_of_vertices();
        break;
    }
    if (!ok) throw std::runtime_error("CGAL reader returned false");
  }
  std::uint64_t in_faces() const override { return stl_header_triangles(path_); }
  std::uint64_t out_faces() const override { return faces_; }
  std::uint64_t out_vertices() const override { return vertices_; }

 private:
  fs::path path_;
  CgalRead variant_;
  std::vector<Point> points_;
  std::vector<std::array<std::size_t, 3>> triangles_;
  SurfaceMesh mesh_;
  std::uint64_t faces_ = 0, vertices_ = 0;
};

JobFactory cgal_read(const fs::path& path, CgalRead variant) {
  return [path, variant] { return std::make_unique<CgalReader>(path, variant); };
}

}  // namespace

JobFactory cgal_loop_job(const fs::path& path, int levels) {
  return [path, levels] { return std::make_unique<CgalSubdivide>(path, levels, CgalMethod::Loop); };
}
JobFactory cgal_sqrt3_job(const fs::path& path, int levels) {
  return
      [path, levels] { return std::make_unique<CgalSubdivide>(path, levels, CgalMethod::Sqrt3); };
}
JobFactory cgal_read_soup_job(const fs::path& path) {
  return cgal_read(path, CgalRead::Soup);
}
JobFactory cgal_read_mesh_job(const fs::path& path) {
  return cgal_read(path, CgalRead::Mesh);
}
JobFactory cgal_read_mesh_repair_job(const fs::path& path) {
  return cgal_read(path, CgalRead::MeshRepair);
}

std::string cgal_version() {
  return CGAL_STR(CGAL_VERSION);
}

}  // namespace stlrefine::bench
