// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// Compiled only when CMake found OpenMesh (STLREFINE_BENCH_HAVE_OPENMESH); see
// jobs_openmesh_missing.cpp for the stubs used otherwise.
#include <OpenMesh/Core/IO/MeshIO.hh>
// MeshIO.hh must come before the mesh kernel so the readers are registered.
#include <OpenMesh/Core/System/config.h>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/LoopT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/ModifiedButterFlyT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/Sqrt3InterpolatingSubdividerLabsikGreinerT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/Sqrt3T.hh>
#include <cstdint>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/jobs.h"

namespace stlrefine::bench {
namespace {

namespace fs = std::filesystem;

//! Double-precision points, like our stencils and CGAL's Simple_cartesian<double>.
struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

std::uint64_t stl_header_triangles(const fs::path& path) {
  const auto size = fs::file_size(path);
  return size >= 84 ? (size - 84) / 50 : 0;
}

//! Routes OpenMesh's error/log streams into a buffer for the lifetime of the object, so
//! what it complains about ends up in the report (as a count) instead of the terminal.
class CaptureOpenMeshMessages {
 public:
  CaptureOpenMeshMessages() {
    omerr().disconnect(std::cerr);
    omerr().connect(buffer_);
    omlog().disable();
    omout().disable();
  }
  ~CaptureOpenMeshMessages() {
    omerr().flush();
    omerr().disconnect(buffer_);
    omerr().connect(std::cerr);
  }
  CaptureOpenMeshMessages(const CaptureOpenMeshMessages&) = delete;
  CaptureOpenMeshMessages& operator=(const CaptureOpenMeshMessages&) = delete;

  //! Number of message lines and the first one, e.g. "12 OpenMesh errors, first: ...".
  std::string summary() {
    omerr().flush();
    std::istringstream lines(buffer_.str());
    std::string line, first;
    std::size_t count = 0;
    while (std::getline(lines, line)) {
      if (line.empty()) continue;
      if (count++ == 0) first = line;
    }
    if (count == 0) return {};
    return std::to_string(count) + " OpenMesh error lines, first: " + first;
  }

 private:
  std::ostringstream buffer_;
};

enum class Subdivider { Loop, ModifiedButterfly, Sqrt3, Sqrt3LabsikGreiner };

//! Attaches OpenMesh subdivider S to the mesh, runs `levels` steps, detaches.
template <template <class, class> class S, class Mesh>
bool subdivide(Mesh& mesh, int levels) {
  S<Mesh, double> subdivider;
  subdivider.attach(mesh);
  const bool ok = subdivider(std::size_t(levels));
  subdivider.detach();
  return ok;
}

class OpenMeshSubdivide final : public Job {
 public:
  OpenMeshSubdivide(const fs::path& path, int levels, Subdivider kind)
      : levels_(levels), kind_(kind) {
    const IndexedSoup soup = load_ingested_triangles(path);
    const double t0 = now_seconds();
    {
      mesh_.reserve(soup.positions.size(), soup.triangles.size() * 3 / 2 + 16,
                    soup.triangles.size());
      std::vector<TriMesh::VertexHandle> vh;
      vh.reserve(soup.positions.size());
      for (const Vec3& p : soup.positions) vh.push_back(mesh_.add_vertex({p.x, p.y, p.z}));
      for (const auto& t : soup.triangles) {
        const auto fh = mesh_.add_face(vh[t[0]], vh[t[1]], vh[t[2]]);
        if (!fh.is_valid()) ++rejected_faces_;
      }
    }
    convert_seconds_ = now_seconds() - t0;
    in_faces_ = mesh_.n_faces();
  }
  void run() override {
    namespace U = OpenMesh::Subdivider::Uniform;
    bool ok = false;
    switch (kind_) {
      case Subdivider::Loop:
        ok = subdivide<U::LoopT>(mesh_, levels_);
        break;
      case Subdivider::ModifiedButterfly:
        ok = subdivide<U::ModifiedButterflyT>(mesh_, levels_);
        break;
      case Subdivider::Sqrt3:
        ok = subdivide<U::Sqrt3T>(mesh_, levels_);
        break;
      case Subdivider::Sqrt3LabsikGreiner:
        ok = subdivide<U::InterpolatingSqrt3LGT>(mesh_, levels_);
        break;
    }
    if (!ok) throw std::runtime_error("OpenMesh subdivider returned false");
  }
  std::uint64_t in_faces() const override { return in_faces_; }
  std::uint64_t out_faces() const override { return mesh_.n_faces(); }
  std::uint64_t out_vertices() const override { return mesh_.n_vertices(); }
  double convert_seconds() const override { return convert_seconds_; }
  std::string note() const override {
    std::string note;
    if (rejected_faces_ > 0) {
      note = "add_face rejected " + std::to_string(rejected_faces_) + " faces; ";
    }
    return note + messages_.summary();
  }

 private:
  mutable CaptureOpenMeshMessages messages_;
  int levels_;
  Subdivider kind_;
  TriMesh mesh_;
  std::uint64_t in_faces_ = 0, rejected_faces_ = 0;
  double convert_seconds_ = 0;
};

class OpenMeshRead final : public Job {
 public:
  explicit OpenMeshRead(const fs::path& path) : path_(path) {}
  void run() override {
    if (!OpenMesh::IO::read_mesh(mesh_, path_.string())) {
      throw std::runtime_error("OpenMesh::IO::read_mesh returned false");
    }
  }
  std::uint64_t in_faces() const override { return stl_header_triangles(path_); }
  std::uint64_t out_faces() const override { return mesh_.n_faces(); }
  std::uint64_t out_vertices() const override { return mesh_.n_vertices(); }
  std::string note() const override { return messages_.summary(); }

 private:
  mutable CaptureOpenMeshMessages messages_;
  fs::path path_;
  TriMesh mesh_;
};

}  // namespace

bool have_openmesh() {
  return true;
}

JobFactory openmesh_loop_job(const fs::path& path, int levels) {
  return [path, levels] {
    return std::make_unique<OpenMeshSubdivide>(path, levels, Subdivider::Loop);
  };
}
JobFactory openmesh_butterfly_job(const fs::path& path, int levels) {
  return [path, levels] {
    return std::make_unique<OpenMeshSubdivide>(path, levels, Subdivider::ModifiedButterfly);
  };
}
JobFactory openmesh_sqrt3_job(const fs::path& path, int levels) {
  return [path, levels] {
    return std::make_unique<OpenMeshSubdivide>(path, levels, Subdivider::Sqrt3);
  };
}
JobFactory openmesh_sqrt3_lg_job(const fs::path& path, int levels) {
  return [path, levels] {
    return std::make_unique<OpenMeshSubdivide>(path, levels, Subdivider::Sqrt3LabsikGreiner);
  };
}
JobFactory openmesh_read_job(const fs::path& path) {
  return [path] { return std::make_unique<OpenMeshRead>(path); };
}

std::string openmesh_version() {
  return std::to_string(OM_GET_VER) + "." + std::to_string(OM_GET_MAJ) + "." +
         std::to_string(OM_GET_MIN);
}

}  // namespace stlrefine::bench
