// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The 3MF core model (threemf_model.h): objects are kept as indexed meshes while the XML
// streams by; the build is expanded once the part has ended. 3MF defines every object
// before its use and an object is registered only at its end tag, so components form no
// cycle by construction; each object's nesting depth and expanded triangle count are
// known when it closes, and the build is refused on them before anything is expanded.

#include "core/io/threemf_model.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/io/reader_util.h"
#include "core/io/threemf_xml.h"

namespace stlrefine::io_detail {

namespace {

constexpr std::string_view kCoreNs = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02";
// A component or item with p:path points into another model part (production extension).
constexpr std::string_view kProductionPath =
    "http://schemas.microsoft.com/3dmanufacturing/production/2015/06\npath";

//! x'_i = sum_j m[i][j] x_j + m[i][3].
using Affine = std::array<std::array<double, 4>, 3>;
constexpr Affine kIdentity = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};

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

std::string_view trimmed(std::string_view s) {
  constexpr std::string_view kSpace = " \t\r\n";
  const std::size_t b = s.find_first_not_of(kSpace);
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(kSpace) - b + 1);
}

bool parse_unsigned(std::string_view s, std::uint64_t& v) {
  s = trimmed(s);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size();
}

enum class Kind {
  None,
  Model,
  Resources,
  Object,
  Mesh,
  Vertices,
  Vertex,
  Triangles,
  Triangle,
  Components,
  Component,
  Build,
  Item,
  Ignored,  // another namespace's element, metadata: skipped with what it holds
};

struct Element {
  Kind kind;
  Kind parent;  // the kind it must sit in
  std::string_view name;
};
constexpr Element kElements[] = {
    {Kind::Model, Kind::None, "model"},
    {Kind::Resources, Kind::Model, "resources"},
    {Kind::Build, Kind::Model, "build"},
    {Kind::Object, Kind::Resources, "object"},
    {Kind::Mesh, Kind::Object, "mesh"},
    {Kind::Components, Kind::Object, "components"},
    {Kind::Vertices, Kind::Mesh, "vertices"},
    {Kind::Triangles, Kind::Mesh, "triangles"},
    {Kind::Vertex, Kind::Vertices, "vertex"},
    {Kind::Triangle, Kind::Triangles, "triangle"},
    {Kind::Component, Kind::Components, "component"},
    {Kind::Item, Kind::Build, "item"},
};

struct Instance {
  std::size_t object;  // index into objects
  Affine transform;
};

struct Object {
  std::uint64_t id = 0;
  std::string name;
  bool has_mesh = false;
  bool has_components = false;
  // Once the object has ended, only the vertices its triangles use (numbered anew), and
  // `used` holds the index each had in the file (for messages).
  std::vector<float> vertices;           // 3 per vertex, as the file has them (float)
  std::vector<std::uint32_t> triangles;  // 3 per triangle
  std::vector<std::uint32_t> used;
  std::vector<Instance> components;  // once ended, only those with triangles
  int depth = 0;                     // 0 for a mesh, 1 + the deepest component otherwise
  std::uint64_t expanded = 0;        // triangles once flattened, saturating at max_triangles + 1
  //! What expanding one instance costs (see work_limit), saturating at work_limit + 1.
  std::uint64_t work = 0;
};

//! Keeps only the vertices `o`'s triangles use, in their order, renumbering the triangles.
void drop_unused_vertices(Object& o) {
  constexpr std::uint32_t kUnused = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> renumbered(o.vertices.size() / 3, kUnused);
  for (const std::uint32_t v : o.triangles) renumbered[v] = 0;
  std::uint32_t kept = 0;
  for (std::size_t v = 0; v < renumbered.size(); ++v) {
    if (renumbered[v] == kUnused) continue;
    std::copy_n(o.vertices.begin() + 3 * std::ptrdiff_t(v), 3, o.vertices.begin() + 3 * kept);
    o.used.push_back(static_cast<std::uint32_t>(v));
    renumbered[v] = kept++;
  }
  o.vertices.resize(3 * std::size_t{kept});
  o.vertices.shrink_to_fit();
  for (std::uint32_t& v : o.triangles) v = renumbered[v];
}

}  // namespace

struct ThreeMfModel::Impl : XmlHandler {
  const StlReadOptions& options;
  HardenedXml xml;
  std::vector<Kind> stack;
  int ignored_depth = 0;
  std::optional<DeclaredUnit> unit;
  std::vector<Object> objects;
  std::unordered_map<std::uint64_t, std::size_t> by_id;
  std::vector<Instance> build;
  std::uint64_t stored_vertices = 0;
  std::uint64_t stored_triangles = 0;
  std::uint64_t components = 0;
  Object current;  // the object being read

  Impl(const StlReadOptions& o, std::string part) : options(o), xml(*this, std::move(part)) {}

  std::uint64_t cap() const { return options.max_triangles + 1; }

  // What expanding the build may cost: each instance of an object with triangles in it
  // costs 1, plus the vertices its triangles use and its triangles (each transformed or
  // copied once per instance); objects without triangles are skipped and cost nothing. A
  // build within max_triangles costs at most 4 per triangle and 1 per component level; more
  // is a component tree built to burn time, refused before anything is expanded.
  std::uint64_t work_limit() const {
    return kMax3mfWorkPerTriangle * std::uint64_t{options.max_triangles} + kMax3mfWorkSlack;
  }
  std::uint64_t add_work(std::uint64_t a, std::uint64_t b) const {
    return std::min(a + b, work_limit() + 1);  // a, b <= work_limit() + 1: no overflow
  }

  const char* required(const XmlAttributes& attrs, std::string_view element, const char* name) {
    const char* v = attrs.find(name);
    if (!v) {
      std::string m = "<";
      m.append(element).append("> has no ").append(name);
      throw xml.error(m);
    }
    return v;
  }

  double number(const XmlAttributes& attrs, std::string_view element, const char* name) {
    const char* text = required(attrs, element, name);
    double v = 0;
    if (!parse_double(trimmed(text), v)) {
      std::string m = "<";
      m.append(element).append("> ").append(name).append("=").append(quoted(text));
      throw xml.error(m.append(" is not a number"));
    }
    return v;
  }

  std::uint64_t integer(const XmlAttributes& attrs, std::string_view element, const char* name,
                        std::uint64_t max) {
    const char* text = required(attrs, element, name);
    std::uint64_t v = 0;
    if (!parse_unsigned(text, v) || v > max) {
      std::string m = "<";
      m.append(element).append("> ").append(name).append("=").append(quoted(text));
      throw xml.error(m.append(" is not an integer in [0, ").append(std::to_string(max)) + "]");
    }
    return v;
  }

  // 3MF's "m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32" maps a row vector: x' = x M;
  // rounded to float as lib3mf kept them, so that geometry stays what it was.
  Affine transform(const XmlAttributes& attrs, std::string_view element) {
    const char* text = attrs.find("transform");
    if (!text) return kIdentity;
    std::string_view rest(text);
    double v[12];
    int n = 0;
    std::string_view word;
    for (; n < 13; ++n) {
      while (!rest.empty() &&
             (is_blank(rest.front()) || rest.front() == '\n' || rest.front() == '\r'))
        rest.remove_prefix(1);
      if (rest.empty()) break;
      std::size_t end = 0;
      while (end < rest.size() && !is_blank(rest[end]) && rest[end] != '\n' && rest[end] != '\r')
        ++end;
      word = rest.substr(0, end);
      rest.remove_prefix(end);
      if (n == 12 || !parse_double(word, v[n])) break;
    }
    if (n != 12 || !trimmed(rest).empty()) {
      std::string m = "<";
      m.append(element).append("> transform=").append(quoted(text));
      throw xml.error(m.append(" is not 12 numbers"));
    }
    Affine a{};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) a[i][j] = static_cast<float>(v[3 * j + i]);
      a[i][3] = static_cast<float>(v[9 + i]);
    }
    return a;
  }

  std::size_t defined_object(const XmlAttributes& attrs, std::string_view element) {
    const std::uint64_t id = integer(attrs, element, "objectid", 0x7fffffff);
    if (attrs.find(kProductionPath)) {
      std::string m = "<";
      m.append(element).append("> names object ").append(std::to_string(id));
      throw xml.error(m.append(" in another model part (p:path), which is not read"));
    }
    const auto it = by_id.find(id);
    if (it == by_id.end()) {
      std::string m = "<";
      m.append(element).append("> names object ").append(std::to_string(id));
      throw xml.error(m.append(", which the model does not define before it"));
    }
    return it->second;
  }

  void start(std::string_view ns, std::string_view name, const XmlAttributes& attrs) override {
    if (ignored_depth > 0) {
      ++ignored_depth;
      return;
    }
    const Kind parent = stack.empty() ? Kind::None : stack.back();
    const Element* element = nullptr;
    if (ns == kCoreNs || ns.empty())
      for (const Element& e : kElements)
        if (e.name == name) element = &e;
    if (!element) {
      if (parent == Kind::None) {
        std::string m = "the root element is <";
        m.append(name).append(">");
        if (!ns.empty()) m.append(" in namespace ").append(quoted(ns));
        throw xml.error(m.append(", not a 3MF <model> (namespace ").append(kCoreNs) + ")");
      }
      ++ignored_depth;  // metadata, extensions: nothing of the geometry
      return;
    }
    if (element->parent != parent) {
      std::string m = "<";
      m.append(name).append(parent == Kind::None ? "> is the root element"
                                                 : "> is not where 3MF puts it");
      throw xml.error(m);
    }
    stack.push_back(element->kind);
    switch (element->kind) {
      case Kind::Model:
        return read_unit(attrs);
      case Kind::Object:
        return start_object(attrs);
      case Kind::Mesh:
      case Kind::Components:
        if (current.has_mesh || current.has_components)
          throw xml.error("object " + std::to_string(current.id) +
                          " has more than one <mesh> or <components>");
        (element->kind == Kind::Mesh ? current.has_mesh : current.has_components) = true;
        return;
      case Kind::Vertex:
        return add_vertex(attrs);
      case Kind::Triangle:
        return add_triangle(attrs);
      case Kind::Component:
        if (++components > kMax3mfComponents)
          throw xml.error("more than " + std::to_string(kMax3mfComponents) + " components",
                          "too_large");
        current.components.push_back(
            {defined_object(attrs, "component"), transform(attrs, "component")});
        return;
      case Kind::Item:
        if (build.size() >= kMax3mfBuildItems)
          throw xml.error("more than " + std::to_string(kMax3mfBuildItems) + " build items",
                          "too_large");
        build.push_back({defined_object(attrs, "item"), transform(attrs, "item")});
        return;
      default:
        return;
    }
  }

  void end(std::string_view, std::string_view) override {
    if (ignored_depth > 0) {
      --ignored_depth;
      return;
    }
    if (stack.back() == Kind::Object) end_object();
    stack.pop_back();
  }

  void read_unit(const XmlAttributes& attrs) {
    static const std::pair<std::string_view, double> kUnits[] = {
        {"micron", 0.001}, {"millimeter", 1.0}, {"centimeter", 10.0},
        {"inch", 25.4},    {"foot", 304.8},     {"meter", 1000.0}};
    const char* name = attrs.find("unit");
    if (!name) name = "millimeter";  // 3MF's default
    for (const auto& [n, mm] : kUnits)
      if (n == name) unit = DeclaredUnit{std::string(n), mm};
    if (!unit) throw xml.error("unknown 3MF unit " + quoted(name));
  }

  void start_object(const XmlAttributes& attrs) {
    if (objects.size() >= kMax3mfObjects)
      throw xml.error("more than " + std::to_string(kMax3mfObjects) + " objects", "too_large");
    current = Object{};
    current.id = integer(attrs, "object", "id", 0x7fffffff);
    if (current.id == 0) throw xml.error("<object> id=0 (3MF ids start at 1)");
    if (by_id.count(current.id))
      throw xml.error("object id " + std::to_string(current.id) + " is defined twice");
    if (const char* n = attrs.find("name"))
      current.name.assign(n, std::min<std::size_t>(std::strlen(n), 4096));
  }

  void add_vertex(const XmlAttributes& attrs) {
    if (++stored_vertices > 3 * std::uint64_t{options.max_triangles})
      throw xml
          .error("more than 3 max_triangles (" +
                     std::to_string(3 * std::uint64_t{options.max_triangles}) + ") vertices",
                 "too_many_vertices")
          .with_field("max_triangles");
    // As lib3mf kept them: floats. A value that is none (NaN, inf, beyond float's range) is
    // refused here, where its axis is still known (a transform would smear it into others).
    for (std::size_t k = 0; k < 3; ++k) {
      const double v = number(attrs, "vertex", axis_name(k));
      if (!std::isfinite(v) || std::fabs(v) > double{std::numeric_limits<float>::max()})
        throw xml.error("object " + std::to_string(current.id) + ", vertex " +
                            std::to_string(current.vertices.size() / 3) + ": " + axis_name(k) +
                            " is not a finite float",
                        "non_finite");
      current.vertices.push_back(static_cast<float>(v));
    }
  }

  void add_triangle(const XmlAttributes& attrs) {
    if (++stored_triangles > options.max_triangles) {
      Error e = too_many_triangles(stored_triangles, options);
      throw xml.error(e.what(), "too_many_triangles").with_field("max_triangles");
    }
    const std::uint64_t count = current.vertices.size() / 3;
    for (const char* corner : {"v1", "v2", "v3"}) {
      const std::uint64_t v = integer(attrs, "triangle", corner, 0xffffffff);
      if (v >= count)
        throw xml.error("object " + std::to_string(current.id) + ": triangle " +
                            std::to_string(current.triangles.size() / 3) + " names vertex " +
                            std::to_string(v) + " of " + std::to_string(count),
                        "bad_index");
      current.triangles.push_back(static_cast<std::uint32_t>(v));
    }
  }

  void end_object() {
    drop_unused_vertices(current);
    current.expanded = std::min<std::uint64_t>(current.triangles.size() / 3, cap());
    for (const Instance& c : current.components) {
      const Object& child = objects[c.object];
      current.depth = std::max(current.depth, child.depth + 1);
      current.expanded = std::min(current.expanded + child.expanded, cap());
    }
    if (current.depth > kMax3mfComponentDepth)
      throw xml.error("object " + std::to_string(current.id) + ": components nested more than " +
                      std::to_string(kMax3mfComponentDepth) + " deep");
    // Components that hold no triangle are dropped: expanding them would only cost time.
    std::erase_if(current.components,
                  [&](const Instance& c) { return objects[c.object].expanded == 0; });
    if (current.expanded > 0) {
      current.work = add_work(1, current.used.size() + current.triangles.size() / 3);
      for (const Instance& c : current.components)
        current.work = add_work(current.work, objects[c.object].work);
    }
    by_id.emplace(current.id, objects.size());
    objects.push_back(std::move(current));
    current = Object{};
  }

  // ---- the build, once the part has ended ----

  std::vector<float>* coords = nullptr;

  void expand(const Object& object, const Affine& m) {
    if (object.has_mesh) add_mesh(object, m);
    for (const Instance& c : object.components) expand(objects[c.object], compose(m, c.transform));
  }

  void add_mesh(const Object& object, const Affine& m) {
    const std::size_t count = object.used.size();
    std::vector<float> positions(3 * count);
    const double limit = options.max_abs_coordinate;
    for (std::size_t v = 0; v < count; ++v) {
      const float* p = &object.vertices[3 * v];
      for (std::size_t i = 0; i < 3; ++i) {
        const double x = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
        if (std::isfinite(x) && std::fabs(x) <= limit &&
            std::fabs(x) <= double{std::numeric_limits<float>::max()}) {
          positions[3 * v + i] = static_cast<float>(x);
          continue;
        }
        // The refusal read_stl makes, with where it is.
        const std::string where = "object " + std::to_string(object.id) + ", vertex " +
                                  std::to_string(object.used[v]) + ": " + axis_name(i) +
                                  " (after the build and component transforms)";
        checked_coordinate(x, options, where, [](Error& e) { e.at_byte(0); });
      }
    }
    coords->reserve(coords->size() + 3 * object.triangles.size());
    for (const std::uint32_t index : object.triangles)
      coords->insert(coords->end(), positions.begin() + 3 * std::ptrdiff_t{index},
                     positions.begin() + 3 * std::ptrdiff_t{index} + 3);
  }

  MeshInput finish() {
    MeshInput out;
    out.format = MeshFormat::ThreeMf;
    out.soup.format = StlFormat::Binary;
    out.unit = unit;
    std::uint64_t total = 0;
    for (const Instance& item : build)
      total = std::min(total + objects[item.object].expanded, cap());
    if (total > options.max_triangles) throw too_many_triangles(total, options).at_byte(0);
    std::uint64_t work = 0;
    for (const Instance& item : build) {
      const Object& object = objects[item.object];
      work = add_work(work, object.work);
      if (work <= work_limit()) continue;
      std::string m = object.work > work_limit() ? "object " : "the build (up to object ";
      m.append(std::to_string(object.id))
          .append(object.work > work_limit() ? " expands to " : ") expands to ")
          .append(std::to_string(work))
          .append(" or more instances, used vertices and triangles, more than the ")
          .append(std::to_string(work_limit()))
          .append(" max_triangles ")
          .append(std::to_string(options.max_triangles))
          .append(" allows (")
          .append(std::to_string(kMax3mfWorkPerTriangle))
          .append(" max_triangles + ")
          .append(std::to_string(kMax3mfWorkSlack))
          .append(")");
      throw malformed("too_large", m).with_field("max_triangles").at_byte(0);
    }
    out.soup.coords.reserve(9 * total);
    coords = &out.soup.coords;
    for (std::size_t n = 0; n < build.size(); ++n) {
      const Object& object = objects[build[n].object];
      MeshPart part;
      part.first_triangle = coords->size() / 9;
      part.name = object.name.empty() ? "object " + std::to_string(n + 1) : object.name;
      expand(object, build[n].transform);
      part.triangle_count = coords->size() / 9 - part.first_triangle;
      if (part.triangle_count > 0) out.parts.push_back(std::move(part));
    }
    if (out.soup.coords.empty())
      throw malformed("zero_triangles", "the 3MF's build holds no mesh triangle").at_byte(0);
    return out;
  }
};

ThreeMfModel::ThreeMfModel(const StlReadOptions& options, std::string part)
    : impl_(std::make_unique<Impl>(options, std::move(part))) {}

ThreeMfModel::~ThreeMfModel() = default;

void ThreeMfModel::feed(const char* data, std::size_t size, bool last) {
  impl_->xml.feed(data, size, last);
}

MeshInput ThreeMfModel::finish() {
  return impl_->finish();
}

MeshInput read_3mf_model(std::span<const std::uint8_t> xml, const StlReadOptions& options,
                         const std::string& part) {
  options.validate();
  ThreeMfModel model(options, part);
  model.feed(reinterpret_cast<const char*>(xml.data()), xml.size(), true);
  return model.finish();
}

}  // namespace stlrefine::io_detail
