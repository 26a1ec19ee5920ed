// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/openmesh_butterfly.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/ModifiedButterFlyT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/Sqrt3InterpolatingSubdividerLabsikGreinerT.hh>
#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mesh/build_mesh.h"

namespace stlrefine::fidelity {
namespace {

//! Double-precision points, like our stencils (the same traits as bench/jobs_openmesh.cpp).
struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

TriMesh to_openmesh(const Mesh& mesh) {
  TriMesh om;
  std::vector<TriMesh::VertexHandle> vh;
  vh.reserve(mesh.num_vertices());
  for (const Vec3& p : mesh.positions()) vh.push_back(om.add_vertex({p.x, p.y, p.z}));
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto v = mesh.face_vertices(FaceId(f));
    if (!om.add_face(vh[v[0].idx], vh[v[1].idx], vh[v[2].idx]).is_valid())
      throw std::runtime_error("OpenMesh add_face rejected a face");
  }
  return om;
}

Mesh from_openmesh(const TriMesh& om) {
  IndexedSoup soup;
  soup.positions.reserve(om.n_vertices());
  for (const auto v : om.vertices()) {
    const auto& p = om.point(v);
    soup.positions.push_back({p[0], p[1], p[2]});
  }
  for (const auto f : om.faces()) {
    std::array<std::uint32_t, 3> t{};
    int k = 0;
    for (const auto v : om.fv_range(f)) t[k++] = static_cast<std::uint32_t>(v.idx());
    soup.triangles.push_back(t);
  }
  return build_mesh(soup).mesh;
}

//! Converts (untimed), runs subdivider S `steps` times (timed), converts back.
template <template <class, class> class S>
Mesh run_openmesh(const Mesh& mesh, int steps, double& seconds, const char* name) {
  TriMesh om = to_openmesh(mesh);
  const auto t0 = std::chrono::steady_clock::now();
  S<TriMesh, double> subdivider;
  subdivider.attach(om);
  const bool ok = subdivider(static_cast<std::size_t>(steps));
  subdivider.detach();
  seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!ok) throw std::runtime_error(std::string("OpenMesh ") + name + " returned false");
  return from_openmesh(om);
}

}  // namespace

bool have_openmesh() {
  return true;
}

Mesh openmesh_butterfly(const Mesh& mesh, int levels, double& seconds) {
  return run_openmesh<OpenMesh::Subdivider::Uniform::ModifiedButterflyT>(mesh, levels, seconds,
                                                                         "ModifiedButterflyT");
}

Mesh openmesh_sqrt3_lg(const Mesh& mesh, int steps, double& seconds) {
  return run_openmesh<OpenMesh::Subdivider::Uniform::InterpolatingSqrt3LGT>(
      mesh, steps, seconds, "InterpolatingSqrt3LGT");
}

}  // namespace stlrefine::fidelity
