// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// 3MF through Debian's lib3mf (1.8, the NMR C interface): every build item's object, mesh
// or components (nested, each with its transform), flattened with the item's transform
// into one part per build item, and the model's unit. The zip's directory is read first
// (libzip) so that a bomb is refused before lib3mf inflates anything.

#include <Model/COM/NMR_DLLInterfaces.h>
#include <zip.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "core/io/mesh_formats.h"
#include "core/io/reader_util.h"

namespace stlrefine {

namespace {

using io_detail::malformed;

//! A row-major affine map: x'_i = sum_j m[i][j] x_j + m[i][3] (lib3mf's MODELTRANSFORM).
using Affine = std::array<std::array<double, 4>, 3>;

constexpr Affine kIdentity = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};

Affine from_lib3mf(const NMR::MODELTRANSFORM& t) {
  Affine a{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) a[i][j] = t.m_fFields[i][j];
  return a;
}

//! outer(inner(x)).
Affine compose(const Affine& outer, const Affine& inner) {
  Affine r{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 4; ++j) {
      double s = j == 3 ? outer[i][3] : 0.0;
      for (int k = 0; k < 3; ++k) s += outer[i][k] * inner[k][j];
      r[i][j] = s;
    }
  }
  return r;
}

//! Releases a lib3mf object when it goes out of scope.
struct Released {
  void operator()(NMR::PLib3MFBase* p) const {
    if (p) NMR::lib3mf_release(p);
  }
};
using Lib3mfHandle = std::unique_ptr<NMR::PLib3MFBase, Released>;

//! The uncompressed size of every part, from the zip's central directory.
void refuse_zip_bomb(std::span<const std::uint8_t> bytes, std::uint64_t limit) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &error);
  if (!source) throw Error(ErrorCode::Internal, "internal", "libzip: cannot wrap the buffer");
  zip_t* archive = zip_open_from_source(source, ZIP_RDONLY, &error);
  if (!archive) {
    zip_source_free(source);
    const std::string why = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw malformed("not_3mf", "this starts like a zip (3MF) but is not a readable zip: " + why)
        .at_byte(0);
  }
  zip_error_fini(&error);
  std::uint64_t total = 0;
  const zip_int64_t entries = zip_get_num_entries(archive, 0);
  // lib3mf 1.8.1 leaks ~160 bytes for each part it opens (scripts/lsan.supp): a package of
  // thousands of parts would make one request leak megabytes.
  if (entries > kMax3mfParts) {
    zip_discard(archive);
    throw malformed("too_large", "the 3MF has " + std::to_string(entries) + " parts, more than " +
                                     std::to_string(kMax3mfParts))
        .at_byte(0);
  }
  for (zip_int64_t i = 0; i < entries; ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(archive, static_cast<zip_uint64_t>(i), 0, &st) == 0 &&
        (st.valid & ZIP_STAT_SIZE))
      total += st.size;
    if (total > limit) {
      zip_discard(archive);
      throw malformed("too_large",
                      "the 3MF's parts inflate to more than " + std::to_string(limit) + " bytes")
          .at_byte(0);
    }
  }
  zip_discard(archive);
}

class ThreeMfReader {
 public:
  ThreeMfReader(std::span<const std::uint8_t> bytes, const StlReadOptions& options)
      : bytes_(bytes), options_(options) {}

  MeshInput read() {
    refuse_zip_bomb(bytes_, kMax3mfUncompressedBytes);
    NMR::PLib3MFModel* raw_model = nullptr;
    check(NMR::lib3mf_createmodel(&raw_model), nullptr, "cannot make a model");
    const Lib3mfHandle model(raw_model);
    NMR::PLib3MFModelReader* raw_reader = nullptr;
    check(NMR::lib3mf_model_queryreader(model.get(), "3mf", &raw_reader), model.get(),
          "no 3MF reader");
    const Lib3mfHandle reader(raw_reader);
    // lib3mf's signature takes a mutable buffer; it only reads it.
    auto* data = const_cast<BYTE*>(reinterpret_cast<const BYTE*>(bytes_.data()));
    if (NMR::lib3mf_reader_readfrombuffer(reader.get(), data, bytes_.size()) != LIB3MF_OK)
      throw malformed("not_3mf", "not a readable 3MF: " + last_error(reader.get())).at_byte(0);

    MeshInput out;
    out.format = MeshFormat::ThreeMf;
    out.soup.format = StlFormat::Binary;
    DWORD unit = 0;
    check(NMR::lib3mf_model_getunit(model.get(), &unit), model.get(), "no unit");
    out.unit = declared_unit(unit);

    NMR::PLib3MFModelBuildItemIterator* raw_items = nullptr;
    check(NMR::lib3mf_model_getbuilditems(model.get(), &raw_items), model.get(), "no build");
    const Lib3mfHandle items(raw_items);
    coords_ = &out.soup.coords;
    BOOL more = false;
    for (std::size_t n = 0;; ++n) {
      check(NMR::lib3mf_builditemiterator_movenext(items.get(), &more), items.get(), "build");
      if (!more) break;
      NMR::PLib3MFModelBuildItem* raw_item = nullptr;
      check(NMR::lib3mf_builditemiterator_getcurrent(items.get(), &raw_item), items.get(),
            "build item");
      const Lib3mfHandle item(raw_item);
      NMR::PLib3MFModelObjectResource* raw_object = nullptr;
      check(NMR::lib3mf_builditem_getobjectresource(item.get(), &raw_object), item.get(),
            "build item object");
      const Lib3mfHandle object(raw_object);
      Affine transform = kIdentity;
      BOOL has = false;
      check(NMR::lib3mf_builditem_hasobjecttransform(item.get(), &has), item.get(), "transform");
      if (has) {
        NMR::MODELTRANSFORM t;
        check(NMR::lib3mf_builditem_getobjecttransform(item.get(), &t), item.get(), "transform");
        transform = from_lib3mf(t);
      }
      MeshPart part;
      part.first_triangle = coords_->size() / 9;
      part.name = object_name(object.get());
      if (part.name.empty()) part.name = "object " + std::to_string(n + 1);
      add_object(object.get(), transform, 0);
      part.triangle_count = coords_->size() / 9 - part.first_triangle;
      if (part.triangle_count > 0) out.parts.push_back(std::move(part));
    }
    if (coords_->empty())
      throw malformed("zero_triangles", "the 3MF's build holds no mesh triangle").at_byte(0);
    return out;
  }

 private:
  static std::string last_error(NMR::PLib3MFBase* instance) {
    DWORD code = 0;
    LPCSTR message = nullptr;
    if (instance) NMR::lib3mf_getlasterror(instance, &code, &message);
    return message ? std::string(message) : "lib3mf error " + std::to_string(code);
  }

  static void check(LIB3MFRESULT r, NMR::PLib3MFBase* instance, const char* what) {
    if (r != LIB3MF_OK)
      throw malformed("not_3mf", std::string("3MF model: ") + what + ": " + last_error(instance))
          .at_byte(0);
  }

  static DeclaredUnit declared_unit(DWORD unit) {
    switch (unit) {
      case NMR::MODELUNIT_MICROMETER:
        return {"micron", 0.001};
      case NMR::MODELUNIT_MILLIMETER:
        return {"millimeter", 1.0};
      case NMR::MODELUNIT_CENTIMETER:
        return {"centimeter", 10.0};
      case NMR::MODELUNIT_INCH:
        return {"inch", 25.4};
      case NMR::MODELUNIT_FOOT:
        return {"foot", 304.8};
      case NMR::MODELUNIT_METER:
        return {"meter", 1000.0};
      default:
        throw malformed("not_3mf", "unknown 3MF unit " + std::to_string(unit)).at_byte(0);
    }
  }

  static std::string object_name(NMR::PLib3MFModelObjectResource* object) {
    ULONG needed = 0;
    if (NMR::lib3mf_object_getnameutf8(object, nullptr, 0, &needed) != LIB3MF_OK || needed == 0)
      return {};
    std::string name(std::min<ULONG>(needed, 4096) + 1, '\0');
    if (NMR::lib3mf_object_getnameutf8(object, name.data(), static_cast<ULONG>(name.size()),
                                       &needed) != LIB3MF_OK)
      return {};
    name.resize(std::strlen(name.c_str()));
    return name;
  }

  void add_object(NMR::PLib3MFModelObjectResource* object, const Affine& transform, int depth) {
    // lib3mf refuses reference cycles; the depth cap keeps a deep but acyclic chain bounded.
    if (depth > 32) throw malformed("not_3mf", "components nested more than 32 deep").at_byte(0);
    BOOL is_mesh = false, is_components = false;
    check(NMR::lib3mf_object_ismeshobject(object, &is_mesh), object, "object");
    check(NMR::lib3mf_object_iscomponentsobject(object, &is_components), object, "object");
    if (is_mesh) return add_mesh(object, transform);
    if (!is_components) return;
    DWORD count = 0;
    check(NMR::lib3mf_componentsobject_getcomponentcount(object, &count), object, "components");
    for (DWORD i = 0; i < count; ++i) {
      NMR::PLib3MFModelComponent* raw_component = nullptr;
      check(NMR::lib3mf_componentsobject_getcomponent(object, i, &raw_component), object,
            "component");
      const Lib3mfHandle component(raw_component);
      NMR::PLib3MFModelObjectResource* raw_child = nullptr;
      check(NMR::lib3mf_component_getobjectresource(component.get(), &raw_child), component.get(),
            "component object");
      const Lib3mfHandle child(raw_child);
      Affine inner = kIdentity;
      BOOL has = false;
      check(NMR::lib3mf_component_hastransform(component.get(), &has), component.get(),
            "component transform");
      if (has) {
        NMR::MODELTRANSFORM t;
        check(NMR::lib3mf_component_gettransform(component.get(), &t), component.get(),
              "component transform");
        inner = from_lib3mf(t);
      }
      add_object(child.get(), compose(transform, inner), depth + 1);
    }
  }

  void add_mesh(NMR::PLib3MFModelMeshObject* mesh, const Affine& m) {
    DWORD vertex_count = 0, triangle_count = 0;
    check(NMR::lib3mf_meshobject_getvertexcount(mesh, &vertex_count), mesh, "vertices");
    check(NMR::lib3mf_meshobject_gettrianglecount(mesh, &triangle_count), mesh, "triangles");
    if (coords_->size() / 9 + triangle_count > options_.max_triangles)
      throw io_detail::too_many_triangles(coords_->size() / 9 + triangle_count, options_)
          .at_byte(0);
    std::vector<NMR::MODELMESHVERTEX> vertices(vertex_count);
    std::vector<NMR::MODELMESHTRIANGLE> triangles(triangle_count);
    if (vertex_count)
      check(NMR::lib3mf_meshobject_getvertices(mesh, vertices.data(), vertex_count, nullptr), mesh,
            "vertices");
    if (triangle_count)
      check(NMR::lib3mf_meshobject_gettriangleindices(mesh, triangles.data(), triangle_count,
                                                      nullptr),
            mesh, "triangles");
    // The transformed positions, checked as read_stl checks a file's floats.
    std::vector<float> positions(3 * std::size_t{vertex_count});
    for (std::size_t v = 0; v < vertex_count; ++v) {
      const float* p = vertices[v].m_fPosition;
      for (std::size_t i = 0; i < 3; ++i) {
        const double x = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
        const std::string where = "vertex " + std::to_string(v) + ": " + io_detail::axis_name(i) +
                                  " (after the build and component transforms)";
        positions[3 * v + i] =
            io_detail::checked_coordinate(x, options_, where, [](Error& e) { e.at_byte(0); });
      }
    }
    coords_->reserve(coords_->size() + 9 * std::size_t{triangle_count});
    for (std::size_t t = 0; t < triangle_count; ++t) {
      for (const DWORD index : triangles[t].m_nIndices) {
        if (index >= vertex_count)
          throw malformed("bad_index", "triangle " + std::to_string(t) + " names vertex " +
                                           std::to_string(index) + " of " +
                                           std::to_string(vertex_count))
              .at_byte(0);
        coords_->insert(coords_->end(), positions.begin() + 3 * std::ptrdiff_t{index},
                        positions.begin() + 3 * std::ptrdiff_t{index} + 3);
      }
    }
  }

  std::span<const std::uint8_t> bytes_;
  const StlReadOptions& options_;
  std::vector<float>* coords_ = nullptr;
};

}  // namespace

MeshInput read_3mf(std::span<const std::uint8_t> bytes, const StlReadOptions& options) {
  options.validate();
  return ThreeMfReader(bytes, options).read();
}

}  // namespace stlrefine
