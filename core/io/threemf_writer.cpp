// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// 3MF output through lib3mf: one mesh object and one build item (no transform) per mesh.

#include <Model/COM/NMR_DLLInterfaces.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/mesh_formats.h"

namespace stlrefine {

namespace {

struct Released {
  void operator()(NMR::PLib3MFBase* p) const {
    if (p) NMR::lib3mf_release(p);
  }
};
using Lib3mfHandle = std::unique_ptr<NMR::PLib3MFBase, Released>;

void check(LIB3MFRESULT r, NMR::PLib3MFBase* instance, const char* what) {
  if (r == LIB3MF_OK) return;
  DWORD code = 0;
  LPCSTR message = nullptr;
  if (instance) NMR::lib3mf_getlasterror(instance, &code, &message);
  throw Error(ErrorCode::Internal, "write_failed",
              std::string("lib3mf: ") + what + ": " + (message ? message : "error"));
}

DWORD unit_code(const std::string& unit) {
  if (unit == "micron") return NMR::MODELUNIT_MICROMETER;
  if (unit == "millimeter") return NMR::MODELUNIT_MILLIMETER;
  if (unit == "centimeter") return NMR::MODELUNIT_CENTIMETER;
  if (unit == "inch") return NMR::MODELUNIT_INCH;
  if (unit == "foot") return NMR::MODELUNIT_FOOT;
  if (unit == "meter") return NMR::MODELUNIT_METER;
  throw Error(ErrorCode::Internal, "internal", "unknown 3MF unit '" + unit + "'");
}

void add_mesh(NMR::PLib3MFModel* model, const NamedMesh& named) {
  const Mesh& mesh = *named.mesh;
  constexpr std::size_t kMax = std::numeric_limits<std::uint32_t>::max();
  if (mesh.num_vertices() > kMax || mesh.num_faces() > kMax)
    throw Error(ErrorCode::BudgetExceeded, "too_many_faces",
                "a 3MF object holds at most 2^32-1 vertices and faces");
  std::vector<NMR::MODELMESHVERTEX> vertices(mesh.num_vertices());
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    const Vec3& p = mesh.positions()[v];
    const double xyz[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) {
      const float f = static_cast<float>(xyz[k]);
      if (!std::isfinite(f))
        throw Error(ErrorCode::Internal, "non_finite",
                    "vertex " + std::to_string(v) + " is not finite as a float");
      vertices[v].m_fPosition[k] = f;
    }
  }
  std::vector<NMR::MODELMESHTRIANGLE> triangles(mesh.num_faces());
  const auto corners = mesh.corner_vertices();
  for (std::size_t f = 0; f < triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) triangles[f].m_nIndices[k] = corners[3 * f + k].idx;

  NMR::PLib3MFModelMeshObject* raw = nullptr;
  check(NMR::lib3mf_model_addmeshobject(model, &raw), model, "add mesh");
  const Lib3mfHandle object(raw);
  check(NMR::lib3mf_object_setnameutf8(object.get(), named.name.c_str()), object.get(), "name");
  check(NMR::lib3mf_meshobject_setgeometry(object.get(), vertices.data(),
                                           static_cast<DWORD>(vertices.size()), triangles.data(),
                                           static_cast<DWORD>(triangles.size())),
        object.get(), "geometry");
  NMR::PLib3MFModelBuildItem* item = nullptr;
  check(NMR::lib3mf_model_addbuilditem(model, object.get(), nullptr, &item), model, "build item");
  const Lib3mfHandle release_item(item);
}

}  // namespace

std::string write_3mf(std::span<const NamedMesh> meshes, const std::string& unit) {
  NMR::PLib3MFModel* raw_model = nullptr;
  check(NMR::lib3mf_createmodel(&raw_model), nullptr, "model");
  const Lib3mfHandle model(raw_model);
  check(NMR::lib3mf_model_setunit(model.get(), unit_code(unit)), model.get(), "unit");
  for (const NamedMesh& m : meshes) add_mesh(model.get(), m);
  NMR::PLib3MFModelWriter* raw_writer = nullptr;
  check(NMR::lib3mf_model_querywriter(model.get(), "3mf", &raw_writer), model.get(), "writer");
  const Lib3mfHandle writer(raw_writer);
  ULONG64 size = 0;
  check(NMR::lib3mf_writer_getstreamsize(writer.get(), &size), writer.get(), "size");
  std::string out(size, '\0');
  check(NMR::lib3mf_writer_writetobuffer(writer.get(), reinterpret_cast<BYTE*>(out.data()), size),
        writer.get(), "write");
  return out;
}

}  // namespace stlrefine
