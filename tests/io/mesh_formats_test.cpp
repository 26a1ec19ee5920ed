// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// OBJ, PLY and 3MF readers, the format sniffer and the 3MF writer (core/io/mesh_formats.h):
// each reader on small files written here, and on every kind of bad input it refuses.

#include "core/io/mesh_formats.h"

#include <gtest/gtest.h>
#include <zip.h>

#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "core/mesh/build_mesh.h"
#include "tests/io/allocation_probe.h"
#include "tests/io/io_test_util.h"

namespace stlrefine::test {
namespace {

using Tri = std::array<std::uint32_t, 3>;
using Pos = std::array<double, 3>;

// A 10 mm cube, outward facing.
const std::vector<Pos> kCubeV = {{0, 0, 0},  {10, 0, 0},  {10, 10, 0},  {0, 10, 0},
                                 {0, 0, 10}, {10, 0, 10}, {10, 10, 10}, {0, 10, 10}};
const std::vector<Tri> kCubeT = {{0, 3, 2}, {0, 2, 1}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                 {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};

//! The soup the STL path makes of the cube: 9 floats per triangle, in order.
std::vector<float> cube_coords(double scale = 1, Pos offset = {0, 0, 0}) {
  std::vector<float> out;
  for (const Tri& t : kCubeT)
    for (const std::uint32_t v : t)
      for (int k = 0; k < 3; ++k)
        out.push_back(static_cast<float>(kCubeV[v][k] * scale + offset[k]));
  return out;
}

std::string cube_obj() {
  std::string s = "# a cube\no cube\n";
  for (const Pos& p : kCubeV)
    s += "v " + std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) +
         "\n";
  for (const Tri& t : kCubeT)
    s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " +
         std::to_string(t[2] + 1) + "\n";
  return s;
}

std::string cube_ply_ascii() {
  std::string s =
      "ply\nformat ascii 1.0\ncomment test\nelement vertex 8\nproperty float x\nproperty "
      "float y\nproperty float z\nelement face 12\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  for (const Pos& p : kCubeV)
    s += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
  for (const Tri& t : kCubeT)
    s += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) +
         "\n";
  return s;
}

template <class T>
void put(std::string& out, T v, bool big) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

//! Binary PLY with the coordinates as doubles among other properties, in the order
//! nx, z, x, red, y; faces with an int count and uint indices, plus a flags byte.
std::string cube_ply_binary(bool big, std::uint32_t vertex_count = 8) {
  std::string s = std::string("ply\nformat ") +
                  (big ? "binary_big_endian" : "binary_little_endian") + " 1.0\nelement vertex " +
                  std::to_string(vertex_count) +
                  "\nproperty float nx\nproperty double z\nproperty double x\nproperty uchar "
                  "red\nproperty double y\nelement face 12\nproperty list int uint "
                  "vertex_indices\nproperty uchar flags\nend_header\n";
  for (const Pos& p : kCubeV) {
    put<float>(s, 0.5f, big);
    put<double>(s, p[2], big);
    put<double>(s, p[0], big);
    put<std::uint8_t>(s, 200, big);
    put<double>(s, p[1], big);
  }
  for (const Tri& t : kCubeT) {
    put<std::int32_t>(s, 3, big);
    for (const std::uint32_t v : t) put<std::uint32_t>(s, v, big);
    put<std::uint8_t>(s, 1, big);
  }
  return s;
}

//! A zip holding the given files (libzip's default method, or deflate at level 9).
std::string zip_of(const std::vector<std::pair<std::string, std::string>>& files,
                   bool deflate = false) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* buffer = zip_source_buffer_create(nullptr, 0, 0, &error);
  zip_t* archive = zip_open_from_source(buffer, ZIP_TRUNCATE, &error);
  EXPECT_NE(archive, nullptr);
  zip_source_keep(buffer);
  for (const auto& [name, data] : files) {
    zip_source_t* s = zip_source_buffer(archive, data.data(), data.size(), 0);
    const zip_int64_t index = zip_file_add(archive, name.c_str(), s, ZIP_FL_OVERWRITE);
    if (deflate)
      zip_set_file_compression(archive, static_cast<zip_uint64_t>(index), ZIP_CM_DEFLATE, 9);
  }
  zip_close(archive);
  zip_source_open(buffer);
  zip_source_seek(buffer, 0, SEEK_END);
  const zip_int64_t size = zip_source_tell(buffer);
  zip_source_seek(buffer, 0, SEEK_SET);
  std::string out(static_cast<std::size_t>(size), '\0');
  zip_source_read(buffer, out.data(), static_cast<zip_uint64_t>(size));
  zip_source_close(buffer);
  zip_source_free(buffer);
  zip_error_fini(&error);
  return out;
}

//! A 3MF package around a model's XML.
std::string package_3mf(const std::string& model) {
  return zip_of(
      {{"[Content_Types].xml",
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?><Types "
        "xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\"><Default "
        "Extension=\"rels\" "
        "ContentType=\"application/vnd.openxmlformats-package.relationships+xml\"/><Default "
        "Extension=\"model\" "
        "ContentType=\"application/vnd.ms-package.3dmanufacturing-3dmodel+xml\"/></Types>"},
       {"_rels/.rels",
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?><Relationships "
        "xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\"><Relationship "
        "Target=\"/3D/3dmodel.model\" Id=\"rel0\" "
        "Type=\"http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel\"/></"
        "Relationships>"},
       {"3D/3dmodel.model", model}});
}

//! A <mesh> element of the cube, with vertex `bad` replaced when given.
std::string cube_mesh_xml(const std::string& extra_vertex = "", const std::string& extra_tri = "") {
  std::string s = "<mesh><vertices>";
  for (const Pos& p : kCubeV)
    s += "<vertex x=\"" + std::to_string(p[0]) + "\" y=\"" + std::to_string(p[1]) + "\" z=\"" +
         std::to_string(p[2]) + "\"/>";
  s += extra_vertex + "</vertices><triangles>";
  for (const Tri& t : kCubeT)
    s += "<triangle v1=\"" + std::to_string(t[0]) + "\" v2=\"" + std::to_string(t[1]) + "\" v3=\"" +
         std::to_string(t[2]) + "\"/>";
  return s + extra_tri + "</triangles></mesh>";
}

std::string model_xml(const std::string& unit, const std::string& resources,
                      const std::string& build) {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?><model unit=\"" + unit +
         "\" xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\"><resources>" +
         resources + "</resources><build>" + build + "</build></model>";
}

Error expect_refused(const std::string& bytes, const char* reason,
                     const StlReadOptions& options = {}) {
  try {
    read_mesh(span_of(bytes), options);
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::MalformedStl) << e.what();
    EXPECT_EQ(e.reason(), reason) << e.what();
    EXPECT_TRUE(e.byte_offset() || e.line()) << "unlocated: " << e.what();
    return e;
  }
  ADD_FAILURE() << "accepted; expected " << reason;
  return Error(ErrorCode::Internal, "none", "none");
}

bool mentions(const Error& e, const std::string& text) {
  return std::string(e.what()).find(text) != std::string::npos;
}

// ---- sniffer ------------------------------------------------------------------------------

TEST(MeshSniff, PicksTheFormatByContent) {
  EXPECT_EQ(sniff_mesh_format(span_of(cube_obj())), MeshFormat::Obj);
  EXPECT_EQ(sniff_mesh_format(span_of("v 1 2 3\nf 1 1 1\n")), MeshFormat::Obj);
  EXPECT_EQ(sniff_mesh_format(span_of("\n\n  mtllib a.mtl\n")), MeshFormat::Obj);
  EXPECT_EQ(sniff_mesh_format(span_of(cube_ply_ascii())), MeshFormat::Ply);
  EXPECT_EQ(sniff_mesh_format(span_of(cube_ply_binary(true))), MeshFormat::Ply);
  EXPECT_EQ(sniff_mesh_format(span_of(std::string("PK\x03\x04 anything"))), MeshFormat::ThreeMf);
  EXPECT_EQ(sniff_mesh_format(span_of("solid x\nendsolid x\n")), MeshFormat::Stl);
  // A binary STL whose header happens to read like OBJ is binary (control bytes follow).
  const Bytes stl = binary_stl({{0, 0, 0, 1, 0, 0, 0, 1, 0}}, "v 1 2 3 exported");
  EXPECT_EQ(sniff_mesh_format(stl), MeshFormat::Stl);
  EXPECT_EQ(sniff_mesh_format({}), MeshFormat::Stl);
  EXPECT_EQ(sniff_mesh_format(span_of("hello world\n")), MeshFormat::Stl);
  // read_mesh goes on to read_stl for the rest: its refusal.
  expect_refused("hello world\n", "not_stl");
}

// ---- OBJ ----------------------------------------------------------------------------------

TEST(ObjReader, ReadsTheCubeAsTheStlPathWould) {
  const MeshInput in = read_mesh(span_of(cube_obj()));
  EXPECT_EQ(in.format, MeshFormat::Obj);
  EXPECT_EQ(in.soup.coords, cube_coords());
  ASSERT_EQ(in.parts.size(), 1u);
  EXPECT_EQ(in.parts[0].name, "cube");
  EXPECT_EQ(in.parts[0].triangle_count, 12u);
  EXPECT_FALSE(in.unit);
  const IngestResult mesh = build_mesh(weld(in.soup));
  EXPECT_EQ(mesh.mesh.num_vertices(), 8u);
  EXPECT_EQ(mesh.mesh.num_faces(), 12u);
}

TEST(ObjReader, FansPolygonsAndTakesEveryCornerForm) {
  // A quad with v/vt/vn corners, negative indices, CRLF, a w coordinate and stray statements.
  const std::string obj =
      "mtllib x.mtl\r\nv 0 0 0 1\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\nvt 0 0\r\nvn 0 0 1\r\n"
      "g side\r\nusemtl red\r\ns off\r\nf 1/1/1 2/1/1 3//1 4/1\r\nf -4 -2 -1\r\nl 1 2\r\n";
  const MeshInput in = read_mesh(span_of(obj));
  ASSERT_EQ(in.soup.triangle_count(), 3u);
  const std::vector<float> expected = {0, 0, 0, 1, 0, 0, 1, 1, 0,   // fan (1, 2, 3)
                                       0, 0, 0, 1, 1, 0, 0, 1, 0,   // fan (1, 3, 4)
                                       0, 0, 0, 1, 1, 0, 0, 1, 0};  // -4 -2 -1 = 1 3 4
  EXPECT_EQ(in.soup.coords, expected);
}

TEST(ObjReader, RefusesBadInputPrecisely) {
  const std::string v3 = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_EQ(*expect_refused(v3 + "f 1 2\n", "syntax").line(), 4u);
  expect_refused(v3 + "f 1 2 x\n", "syntax");
  expect_refused(v3 + "f 1/2/3/4 2 3\n", "syntax");
  expect_refused("v 0 zero 0\nf 1 1 1\n", "syntax");
  expect_refused("v 0 0\nf 1 1 1\n", "syntax");
  const Error zero = expect_refused(v3 + "f 0 1 2\n", "bad_index");
  EXPECT_EQ(*zero.line(), 4u);
  expect_refused(v3 + "f 1 2 4\n", "bad_index");
  // A face may name only vertices defined before it.
  expect_refused("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n", "bad_index");
  expect_refused(v3 + "f -1 -2 -4\n", "bad_index");
  expect_refused("v 0 nan 0\n" + v3 + "f 1 2 3\n", "non_finite");
  expect_refused("v 0 1e999 0\n" + v3 + "f 1 2 3\n", "non_finite");
  expect_refused("v 0 1e300 0\n" + v3 + "f 1 2 3\n", "non_finite");  // beyond float
  const Error far = expect_refused("v 0 2e9 0\n" + v3 + "f 1 2 3\n", "coordinate_out_of_range");
  EXPECT_EQ(far.field(), "max_abs_coordinate");
  expect_refused(v3, "zero_triangles");
  expect_refused("# only a comment\n", "zero_triangles");
  StlReadOptions tight;
  tight.max_triangles = 2;
  EXPECT_EQ(expect_refused(v3 + "f 1 2 3 1 2\n", "too_many_triangles", tight).field(),
            "max_triangles");
  std::string many = "v 0 0 0\n";
  for (int i = 0; i < 7; ++i) many += "v 0 0 0\n";
  EXPECT_EQ(expect_refused(many, "too_many_vertices", tight).field(), "max_triangles");
  tight.max_ascii_line_length = 64;
  const Error line =
      expect_refused(v3 + "f 1 2 3" + std::string(100, ' ') + "\n", "line_too_long", tight);
  EXPECT_EQ(line.field(), "max_ascii_line_length");
}

// ---- PLY ----------------------------------------------------------------------------------

TEST(PlyReader, ReadsAsciiAndBothBinaryEndiannesses) {
  for (const std::string& ply : {cube_ply_ascii(), cube_ply_binary(false), cube_ply_binary(true)}) {
    const MeshInput in = read_mesh(span_of(ply));
    EXPECT_EQ(in.format, MeshFormat::Ply);
    EXPECT_EQ(in.soup.coords, cube_coords()) << in.encoding;
    ASSERT_EQ(in.parts.size(), 1u);
  }
  EXPECT_EQ(read_mesh(span_of(cube_ply_binary(true))).encoding, "binary_big_endian");
  EXPECT_EQ(read_mesh(span_of(cube_ply_binary(false))).encoding, "binary_little_endian");
}

TEST(PlyReader, FansPolygons) {
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty "
      "float z\nelement face 1\nproperty list uchar int vertex_index\nend_header\n0 0 0\n1 0 "
      "0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
  const MeshInput in = read_mesh(span_of(ply));
  EXPECT_EQ(in.soup.coords,
            (std::vector<float>{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0}));
}

TEST(PlyReader, RefusesBadHeaders) {
  const std::string head = "ply\nformat ascii 1.0\n";
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string face = "element face 1\nproperty list uchar int vertex_indices\n";
  expect_refused(head + "element vertex 3\n" + xyz + face, "bad_header");  // no end_header
  expect_refused("ply\nformat ascii 2.0\nend_header\n", "bad_header");
  expect_refused("ply\nformat utf16 1.0\nend_header\n", "bad_header");
  expect_refused(
      head + "element vertex 3\nproperty float x\nproperty float y\n" + face + "end_header\n",
      "bad_header");  // no z
  expect_refused(head + "element vertex 3\n" + xyz + "property quad w\n" + face + "end_header\n",
                 "bad_header");                                                      // unknown type
  expect_refused(head + "element vertex 3\n" + xyz + "end_header\n", "bad_header");  // no face
  expect_refused(head + face + "element vertex 3\n" + xyz + "end_header\n", "bad_header");
  expect_refused(head + "element vertex 3\n" + xyz +
                     "element face 1\nproperty list uchar float vertex_indices\nend_header\n",
                 "bad_header");  // float indices
  expect_refused(head + "element vertex x\n" + xyz + face + "end_header\n", "bad_header");
  expect_refused(head + "element vertex 99999999999\n" + xyz + face + "end_header\n", "bad_header");
  expect_refused(head + "bogus line\nend_header\n", "bad_header");
}

TEST(PlyReader, RefusesLyingCountsBeforeAllocating) {
  // 4 billion vertices announced in a few hundred bytes: refused on the header, and nothing
  // near their size is ever asked for.
  {
    AllocationProbe probe(1 << 20);
    const Error e = expect_refused(cube_ply_binary(false, 4'000'000'000u), "too_many_vertices");
    EXPECT_FALSE(probe.refused());
    EXPECT_TRUE(mentions(e, "4000000000")) << e.what();
  }
  // Within the limits but not within the file: 12 MB of positions are never reserved.
  AllocationProbe probe(1 << 20);
  const Error e = expect_refused(cube_ply_binary(false, 1'000'000u), "truncated");
  EXPECT_FALSE(probe.refused());
  EXPECT_TRUE(mentions(e, "1000000 instances")) << e.what();
  StlReadOptions tight;
  tight.max_triangles = 4;
  EXPECT_EQ(expect_refused(cube_ply_binary(false), "too_many_triangles", tight).field(),
            "max_triangles");
  tight.max_triangles = 2;  // 8 vertices > 3 * 2
  EXPECT_EQ(expect_refused(cube_ply_binary(false), "too_many_vertices", tight).field(),
            "max_triangles");
}

TEST(PlyReader, RefusesBadBodies) {
  const std::string good = cube_ply_binary(false);
  // Truncated inside the faces: located at the byte where the value should start.
  const Error cut = expect_refused(good.substr(0, good.size() - 7), "truncated");
  EXPECT_TRUE(cut.byte_offset());
  expect_refused(good + "xx", "trailing_bytes");
  // A face index beyond the vertices; a face with 2 corners; a huge list count.
  const std::size_t faces = good.find("end_header\n") + 11 + 8 * 29;
  std::string bad = good;
  const std::uint32_t big = 8;
  std::memcpy(bad.data() + faces + 4, &big, 4);
  EXPECT_EQ(*expect_refused(bad, "bad_index").byte_offset(), faces + 4);
  bad = good;
  const std::int32_t two = 2;
  std::memcpy(bad.data() + faces, &two, 4);
  expect_refused(bad, "bad_face");
  bad = good;
  const std::int32_t huge = 1'000'000'000;
  std::memcpy(bad.data() + faces, &huge, 4);
  expect_refused(bad, "truncated");
  bad = good;
  const std::int32_t negative = -5;
  std::memcpy(bad.data() + faces, &negative, 4);
  expect_refused(bad, "bad_face");
  // A NaN z in the first vertex (after the 4-byte nx).
  bad = good;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::size_t body = good.find("end_header\n") + 11;
  std::memcpy(bad.data() + body + 4, &nan, 8);
  EXPECT_EQ(*expect_refused(bad, "non_finite").byte_offset(), body + 4);
  const double far = 5e9;
  std::memcpy(bad.data() + body + 4, &far, 8);
  expect_refused(bad, "coordinate_out_of_range");

  // ASCII: located by line.
  const std::string ascii = cube_ply_ascii();
  std::string a = ascii;
  a.replace(a.find("10.000000 0.000000 0.000000"), 9, "inf");
  expect_refused(a, "non_finite");
  a = ascii;
  a.replace(a.find("3 0 3 2"), 7, "3 0 3 9");
  EXPECT_TRUE(expect_refused(a, "bad_index").line());
  a = ascii;
  a.replace(a.find("3 0 3 2"), 7, "3 0 3 2 7");
  expect_refused(a, "syntax");
  a = ascii;
  a.replace(a.find("3 0 3 2"), 7, "3 0 3");
  expect_refused(a, "syntax");
  a = ascii;
  a.replace(a.find("3 0 3 2"), 7, "3 0 3 x");
  expect_refused(a, "syntax");
  a = ascii;
  a.replace(a.find("3 0 3 2"), 7, "3 0 3 1.5");
  expect_refused(a, "syntax");
  expect_refused(ascii + "1 2 3\n", "syntax");
  expect_refused(ascii.substr(0, ascii.size() - 16), "truncated");  // two faces short
}

// ---- 3MF ----------------------------------------------------------------------------------

TEST(ThreeMfReader, AppliesBuildAndComponentTransformsAndKeepsObjectsApart) {
  // Object 1: the cube. Object 2: components, the cube moved by +100 x. The build: the cube
  // moved by +20 z, and object 2 scaled by 2.
  const std::string resources =
      "<object id=\"1\" name=\"cube\" type=\"model\">" + cube_mesh_xml() +
      "</object><object id=\"2\" name=\"assembly\" type=\"model\"><components><component "
      "objectid=\"1\" transform=\"1 0 0 0 1 0 0 0 1 100 0 0\"/></components></object>";
  const std::string build =
      "<item objectid=\"1\" transform=\"1 0 0 0 1 0 0 0 1 0 0 20\"/><item objectid=\"2\" "
      "transform=\"2 0 0 0 2 0 0 0 2 0 0 0\"/>";
  const MeshInput in = read_mesh(span_of(package_3mf(model_xml("millimeter", resources, build))));
  EXPECT_EQ(in.format, MeshFormat::ThreeMf);
  ASSERT_EQ(in.parts.size(), 2u);
  EXPECT_EQ(in.parts[0].name, "cube");
  EXPECT_EQ(in.parts[1].name, "assembly");
  EXPECT_EQ(in.parts[1].first_triangle, 12u);
  EXPECT_EQ(in.parts[1].triangle_count, 12u);
  std::vector<float> expected = cube_coords(1, {0, 0, 20});
  const std::vector<float> second = cube_coords(2, {200, 0, 0});  // 2 * (x + 100)
  expected.insert(expected.end(), second.begin(), second.end());
  EXPECT_EQ(in.soup.coords, expected);
  ASSERT_TRUE(in.unit);
  EXPECT_EQ(in.unit->name, "millimeter");
}

TEST(ThreeMfReader, ReportsEveryUnit) {
  const std::pair<const char*, double> units[] = {{"micron", 0.001},  {"millimeter", 1},
                                                  {"centimeter", 10}, {"inch", 25.4},
                                                  {"foot", 304.8},    {"meter", 1000}};
  for (const auto& [name, mm] : units) {
    const MeshInput in = read_mesh(span_of(package_3mf(
        model_xml(name, "<object id=\"1\" type=\"model\">" + cube_mesh_xml() + "</object>",
                  "<item objectid=\"1\"/>"))));
    ASSERT_TRUE(in.unit) << name;
    EXPECT_EQ(in.unit->name, name);
    EXPECT_DOUBLE_EQ(in.unit->mm, mm);
    EXPECT_EQ(in.parts[0].name, "object 1");  // unnamed
  }
}

TEST(ThreeMfReader, RoundTripsThroughTheWriter) {
  TriangleSoup soup;
  soup.coords = cube_coords();
  const Mesh a = build_mesh(weld(soup)).mesh;
  soup.coords = cube_coords(1, {50, 0, 0});
  const Mesh b = build_mesh(weld(soup)).mesh;
  const NamedMesh meshes[] = {{"left", &a}, {"right", &b}};
  const std::string file = write_3mf(meshes);
  EXPECT_EQ(sniff_mesh_format(span_of(file)), MeshFormat::ThreeMf);
  const MeshInput in = read_mesh(span_of(file));
  ASSERT_EQ(in.parts.size(), 2u);
  EXPECT_EQ(in.parts[0].name, "left");
  EXPECT_EQ(in.parts[1].name, "right");
  EXPECT_EQ(in.unit->name, "millimeter");
  // Same triangles, corner for corner (welded order, as build_mesh numbered them).
  const IngestResult back = build_mesh(weld(in.soup));
  EXPECT_EQ(back.mesh.num_faces(), 24u);
  EXPECT_EQ(back.mesh.num_vertices(), 16u);
  std::vector<float> first(in.soup.coords.begin(), in.soup.coords.begin() + 9 * 12);
  TriangleSoup again;
  again.coords = first;
  const Mesh round = build_mesh(weld(again)).mesh;
  ASSERT_EQ(round.num_vertices(), a.num_vertices());
  for (std::size_t v = 0; v < a.num_vertices(); ++v) {
    EXPECT_EQ(round.positions()[v].x, a.positions()[v].x);
    EXPECT_EQ(round.positions()[v].z, a.positions()[v].z);
  }
}

TEST(ThreeMfReader, RefusesBadPackages) {
  // Zip magic, then garbage; a zip without a model; a model that is not XML.
  expect_refused(std::string("PK\x03\x04 this is no zip at all"), "not_3mf");
  expect_refused(zip_of({{"hello.txt", "hi"}}), "not_3mf");
  expect_refused(package_3mf("not xml <<<"), "not_3mf");
  // No build item; a build of a mesh without triangles.
  expect_refused(
      package_3mf(model_xml(
          "millimeter", "<object id=\"1\" type=\"model\">" + cube_mesh_xml() + "</object>", "")),
      "zero_triangles");
  // A triangle naming a vertex that does not exist.
  const Error index = expect_refused(
      package_3mf(model_xml("millimeter",
                            "<object id=\"1\" type=\"model\">" +
                                cube_mesh_xml("", "<triangle v1=\"0\" v2=\"1\" v3=\"99\"/>") +
                                "</object>",
                            "<item objectid=\"1\"/>")),
      "bad_index");
  EXPECT_TRUE(mentions(index, "names vertex 99 of 8")) << index.what();
  // A transform that throws a vertex beyond max_abs_coordinate.
  const Error far = expect_refused(
      package_3mf(model_xml("millimeter",
                            "<object id=\"1\" type=\"model\">" + cube_mesh_xml() + "</object>",
                            "<item objectid=\"1\" transform=\"1e9 0 0 0 1 0 0 0 1 0 0 0\"/>")),
      "coordinate_out_of_range");
  EXPECT_EQ(far.field(), "max_abs_coordinate");
  StlReadOptions tight;
  tight.max_triangles = 11;
  expect_refused(
      package_3mf(model_xml("millimeter",
                            "<object id=\"1\" type=\"model\">" + cube_mesh_xml() + "</object>",
                            "<item objectid=\"1\"/>")),
      "too_many_triangles", tight);
}

TEST(ThreeMfReader, RefusesAPackageOfTooManyParts) {
  std::vector<std::pair<std::string, std::string>> files;
  for (int i = 0; i <= kMax3mfParts; ++i) files.push_back({"part" + std::to_string(i), "x"});
  const Error e = expect_refused(zip_of(files), "too_large");
  EXPECT_TRUE(mentions(e, std::to_string(kMax3mfParts + 1) + " parts")) << e.what();
}

TEST(ThreeMfReader, RefusesAZipBombOnItsDirectory) {
  // Two parts whose directory entries announce 3 GiB each: refused before lib3mf inflates
  // anything. (Made by patching the sizes of small stored entries; nothing large is built.)
  std::string zip = zip_of(
      {{"3D/3dmodel.model", std::string(64, 'a')}, {"3D/other.model", std::string(64, 'b')}});
  const std::uint32_t three_gib = 0xC0000000u;
  std::size_t at = 0;
  for (int entry = 0; entry < 2; ++entry) {
    at = zip.find("PK\x01\x02", at + 1);
    ASSERT_NE(at, std::string::npos);
    std::memcpy(zip.data() + at + 24, &three_gib, 4);  // uncompressed size
  }
  AllocationProbe probe(64 << 20);
  const Error e = expect_refused(zip, "too_large");
  EXPECT_FALSE(probe.refused());
  EXPECT_TRUE(mentions(e, "inflate to more than " + std::to_string(kMax3mfInflateFloor)))
      << e.what();
}

// ---- 3MF: hostile packages (the reader is ours since lib3mf leaked) -----------------------

//! A package whose model is `resources` and `build` in millimetre.
std::string package_of(const std::string& resources, const std::string& build) {
  return package_3mf(model_xml("millimeter", resources, build));
}

const std::string kCubeObject = "<object id=\"1\" name=\"cube\">" + cube_mesh_xml() + "</object>";

//! The message of a refusal says `what`.
void expect_refused_saying(const std::string& bytes, const char* reason, const std::string& what,
                           const StlReadOptions& options = {}) {
  const Error e = expect_refused(bytes, reason, options);
  EXPECT_TRUE(mentions(e, what)) << "wanted '" << what << "' in: " << e.what();
}

TEST(ThreeMfReader, RefusesDeclaredSizesThatWrapWhenAdded) {
  // Entry b declares (ZIP64) 2^64 - 8 bytes: added to entry a's 64 without saturating, the
  // total wraps to 56 and the directory check let the bomb through.
  std::string zip = zip_of({{"a", std::string(64, 'a')}, {"b", std::string(64, 'b')}});
  std::size_t at = zip.find("PK\x01\x02");
  at = zip.find("PK\x01\x02", at + 1);
  ASSERT_NE(at, std::string::npos);
  std::uint16_t name = 0, extra = 0;
  std::memcpy(&name, zip.data() + at + 28, 2);
  std::memcpy(&extra, zip.data() + at + 30, 2);
  ASSERT_EQ(extra, 0u);  // b is the last entry: only the end record follows
  const std::uint32_t in_zip64 = 0xFFFFFFFFu;
  std::memcpy(zip.data() + at + 24, &in_zip64, 4);
  const std::uint16_t zip64_extra = 12;
  std::memcpy(zip.data() + at + 30, &zip64_extra, 2);
  const std::uint64_t huge = ~std::uint64_t{0} - 7;
  std::string field("\x01\x00\x08\x00", 4);
  field.append(reinterpret_cast<const char*>(&huge), 8);
  zip.insert(at + 46 + name, field);
  const std::size_t end = zip.find("PK\x05\x06");
  ASSERT_NE(end, std::string::npos);
  std::uint32_t directory = 0;
  std::memcpy(&directory, zip.data() + end + 12, 4);
  directory += 12;
  std::memcpy(zip.data() + end + 12, &directory, 4);
  const Error e = expect_refused(zip, "too_large");
  EXPECT_TRUE(mentions(e, "parts inflate to more than")) << e.what();
}

TEST(ThreeMfReader, FindsTheModelWhereRelsSaysAndNowhereElse) {
  const std::string model = model_xml("meter", kCubeObject, "<item objectid=\"1\"/>");
  const std::string types =
      "<?xml version=\"1.0\"?><Types "
      "xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\"/>";
  const auto rels = [](const std::string& target) {
    return "<?xml version=\"1.0\"?><Relationships "
           "xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\"><Relationship "
           "Target=\"" +
           target +
           "\" Id=\"r\" Type=\"http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel\"/>"
           "</Relationships>";
  };
  // Elsewhere than 3D/3dmodel.model, with an escaped space: read from there.
  const MeshInput in = read_mesh(span_of(zip_of({{"[Content_Types].xml", types},
                                                 {"_rels/.rels", rels("/parts/my%20part.model")},
                                                 {"parts/my part.model", model}})));
  EXPECT_EQ(in.unit->name, "meter");
  EXPECT_EQ(in.soup.triangle_count(), 12u);
  // _rels names a part the zip does not hold (the model sits at the usual place).
  expect_refused_saying(
      zip_of({{"_rels/.rels", rels("/3D/elsewhere.model")}, {"3D/3dmodel.model", model}}),
      "not_3mf", "'/3D/elsewhere.model', which the package does not hold");
  // No _rels/.rels; a _rels/.rels without a model relationship.
  expect_refused_saying(zip_of({{"3D/3dmodel.model", model}}), "not_3mf", "no _rels/.rels");
  expect_refused_saying(zip_of({{"_rels/.rels",
                                 "<Relationships xmlns=\"http://schemas.openxmlformats.org/"
                                 "package/2006/relationships\"/>"},
                                {"3D/3dmodel.model", model}}),
                        "not_3mf", "names no 3D model part");
}

TEST(ThreeMfReader, RefusesAPartThatInflatesPastWhatItsDirectoryDeclares) {
  // _rels/.rels really inflates to 2 MiB (over its 1 MiB cap) but its directory entries say
  // 100 bytes: the bytes are counted as they inflate, the declared size is not trusted.
  const std::string rels =
      "<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\">" +
      std::string(2 << 20, ' ') + "</Relationships>";
  std::string zip = zip_of({{"_rels/.rels", rels}}, true);
  ASSERT_LT(zip.size(), 64u << 10);  // deflated: a small upload
  const std::uint32_t small = 100;
  std::memcpy(zip.data() + 22, &small, 4);  // local header's uncompressed size
  const std::size_t central = zip.find("PK\x01\x02");
  ASSERT_NE(central, std::string::npos);
  std::memcpy(zip.data() + central + 24, &small, 4);  // the directory's
  const Error e = expect_refused(zip, "too_large");
  EXPECT_TRUE(mentions(e, "_rels/.rels inflates to more than 1048576 bytes")) << e.what();
}

//! Every entry of `zip` declared `size` bytes inflated (local headers and directory).
void understate_sizes(std::string& zip, std::uint32_t size) {
  for (std::size_t at = zip.find("PK\x03\x04"); at != std::string::npos;
       at = zip.find("PK\x03\x04", at + 1))
    std::memcpy(zip.data() + at + 22, &size, 4);
  for (std::size_t at = zip.find("PK\x01\x02"); at != std::string::npos;
       at = zip.find("PK\x01\x02", at + 1))
    std::memcpy(zip.data() + at + 24, &size, 4);
}

TEST(ThreeMfReader, RefusesABombOnWhatItReallyInflatesTo) {
  // 80 MiB of blanks in the model deflate to ~80 KiB. Honestly declared: over 100 times the
  // package's size (and the 64 MiB floor), refused on the directory. Declared as 1000
  // bytes: refused while inflating.
  const std::string model =
      model_xml("millimeter", kCubeObject + std::string(80 << 20, ' '), "<item objectid=\"1\"/>");
  const std::string rels = zip_of(
      {{"_rels/.rels",
        "<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\">"
        "<Relationship Target=\"/3D/3dmodel.model\" Id=\"r\" "
        "Type=\"http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel\"/>"
        "</Relationships>"},
       {"3D/3dmodel.model", model}},
      true);
  ASSERT_LT(rels.size(), 1u << 20);
  const Error honest = expect_refused(rels, "too_large");
  EXPECT_TRUE(mentions(honest, "parts inflate to more than 67108864 bytes")) << honest.what();
  std::string lying = rels;
  understate_sizes(lying, 1000);
  AllocationProbe probe(std::size_t{16} << 20);
  const Error e = expect_refused(lying, "too_large");
  EXPECT_FALSE(probe.refused());
  EXPECT_TRUE(mentions(e, "3D/3dmodel.model inflates to more than 67108864 bytes")) << e.what();
}

TEST(ThreeMfReader, RefusesHostileXml) {
  // Entity expansion ("billion laughs"): any DOCTYPE is refused before an entity is declared.
  std::string laughs = "<?xml version=\"1.0\"?><!DOCTYPE model [<!ENTITY a \"ha\">";
  for (int i = 1; i < 10; ++i)
    laughs += "<!ENTITY a" + std::to_string(i) + " \"" + std::string(10, '&') + "\">";
  laughs += "]><model>&a9;</model>";
  expect_refused_saying(package_3mf(laughs), "not_3mf", "DOCTYPE");
  // An external entity (a file of the server) likewise.
  expect_refused_saying(
      package_3mf("<?xml version=\"1.0\"?><!DOCTYPE model SYSTEM \"file:///etc/passwd\"><model/>"),
      "not_3mf", "DOCTYPE");
  // An undeclared entity; XML that is not well-formed, with its line.
  expect_refused_saying(package_3mf("<model>&xxe;</model>"), "not_3mf", "undefined entity");
  expect_refused_saying(package_3mf("<model>\n\n<resources></model>"), "not_3mf",
                        "3D/3dmodel.model line 3: not well-formed XML");
  // Nesting deep enough to exhaust a recursive parser.
  std::string deep = "<model xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\">";
  for (int i = 0; i < 100; ++i) deep += "<x>";
  expect_refused_saying(package_3mf(deep), "not_3mf", "nested more than 64 deep");
  // One token of 2 MiB (expat would buffer it whole, however large the bomb).
  AllocationProbe probe(std::size_t{64} << 20);
  expect_refused_saying(package_3mf("<model><!--" + std::string(2 << 20, 'x') + "--></model>"),
                        "too_large", "bytes without an XML element");
  EXPECT_FALSE(probe.refused());
  // Not a model at all.
  expect_refused_saying(package_3mf("<svg/>"), "not_3mf", "root element is <svg>");
  expect_refused_saying(package_3mf("<model xmlns=\"urn:other\"/>"), "not_3mf",
                        "root element is <model> in namespace 'urn:other', not a 3MF <model>");
}

TEST(ThreeMfReader, RefusesBadObjectsAndReferences) {
  const std::string item = "<item objectid=\"1\"/>";
  // A build item naming an object the model lacks; an id defined twice.
  expect_refused_saying(package_of(kCubeObject, "<item objectid=\"7\"/>"), "not_3mf",
                        "names object 7, which the model does not define");
  expect_refused_saying(package_of(kCubeObject + kCubeObject, item), "not_3mf",
                        "object id 1 is defined twice");
  // Component cycles: an object naming itself, two naming each other (3MF defines an
  // object before its use, so either is a reference to an undefined object).
  expect_refused_saying(
      package_of("<object id=\"1\"><components><component objectid=\"1\"/></components></object>",
                 item),
      "not_3mf", "<component> names object 1, which the model does not define before it");
  expect_refused_saying(
      package_of(kCubeObject.substr(0, kCubeObject.size() - 9) +
                     "</object><object id=\"2\"><components><component objectid=\"3\"/>"
                     "</components></object><object id=\"3\"><components><component "
                     "objectid=\"2\"/></components></object>",
                 item),
      "not_3mf", "names object 3");
  // A chain of 40 components: deep, not cyclic.
  std::string chain = kCubeObject;
  for (int i = 2; i <= 40; ++i)
    chain += "<object id=\"" + std::to_string(i) + "\"><components><component objectid=\"" +
             std::to_string(i - 1) + "\"/></components></object>";
  expect_refused_saying(package_of(chain, "<item objectid=\"40\"/>"), "not_3mf",
                        "components nested more than 32 deep");
  // Bad attributes: a missing coordinate, a negative index, a transform of 11 numbers,
  // an unknown unit, a mesh and components in one object, a p:path into another part.
  expect_refused_saying(
      package_of("<object id=\"1\">" + cube_mesh_xml("<vertex x=\"1\" y=\"2\"/>") + "</object>",
                 item),
      "not_3mf", "<vertex> has no z");
  expect_refused_saying(
      package_of("<object id=\"1\">" +
                     cube_mesh_xml("", "<triangle v1=\"-1\" v2=\"1\" v3=\"2\"/>") + "</object>",
                 item),
      "not_3mf", "v1='-1' is not an integer");
  expect_refused_saying(package_of(kCubeObject, "<item objectid=\"1\" transform=\"1 0 0\"/>"),
                        "not_3mf", "is not 12 numbers");
  expect_refused_saying(package_3mf(model_xml("furlong", kCubeObject, item)), "not_3mf",
                        "unknown 3MF unit 'furlong'");
  expect_refused_saying(
      package_of("<object id=\"1\">" + cube_mesh_xml() + cube_mesh_xml() + "</object>", item),
      "not_3mf", "more than one <mesh> or <components>");
  expect_refused_saying(
      package_of(kCubeObject,
                 "<item xmlns:p=\"http://schemas.microsoft.com/3dmanufacturing/production/"
                 "2015/06\" objectid=\"1\" p:path=\"/3D/other.model\"/>"),
      "not_3mf", "in another model part (p:path)");
}

TEST(ThreeMfReader, RefusesNonFiniteCoordinates) {
  for (const char* bad : {"nan", "inf", "-infinity", "1e39"}) {
    const std::string vertex = std::string("<vertex x=\"0\" y=\"") + bad + "\" z=\"0\"/>";
    const std::string mesh = "<object id=\"1\">" + cube_mesh_xml(vertex) + "</object>";
    expect_refused_saying(package_of(mesh, "<item objectid=\"1\"/>"), "non_finite",
                          "object 1, vertex 8: y", {});
  }
}

TEST(ThreeMfReader, BoundsCountsBeforeExpandingTheBuild) {
  StlReadOptions tight;
  tight.max_triangles = 20;
  // Stored triangles count even in an object no build item uses.
  const std::string second = "<object id=\"2\">" + cube_mesh_xml() + "</object>";
  expect_refused(package_of(kCubeObject + second, "<item objectid=\"1\"/>"), "too_many_triangles",
                 tight);
  // Vertices beyond 3 max_triangles in an object of one triangle.
  tight.max_triangles = 2;
  std::string many = "<object id=\"1\"><mesh><vertices>";
  for (int i = 0; i < 7; ++i) many += "<vertex x=\"0\" y=\"0\" z=\"0\"/>";
  many +=
      "</vertices><triangles><triangle v1=\"0\" v2=\"1\" v3=\"2\"/></triangles></mesh></object>";
  expect_refused_saying(package_of(many, "<item objectid=\"1\"/>"), "too_many_vertices",
                        "more than 3 max_triangles (6) vertices", tight);
  // Components instancing the cube 10 times per level, 9 levels: 12e9 triangles from a
  // few KiB, refused on the count before one triangle is expanded.
  std::string tree = kCubeObject;
  for (int level = 2; level <= 10; ++level) {
    tree += "<object id=\"" + std::to_string(level) + "\"><components>";
    for (int i = 0; i < 10; ++i)
      tree += "<component objectid=\"" + std::to_string(level - 1) + "\"/>";
    tree += "</components></object>";
  }
  AllocationProbe probe(std::size_t{64} << 20);
  const Error e = expect_refused(package_of(tree, "<item objectid=\"10\"/>"), "too_many_triangles");
  EXPECT_FALSE(probe.refused());
  EXPECT_EQ(e.field(), "max_triangles");
}

//! Objects first + 1 .. last, each holding `fanout` components of the object before.
std::string component_levels(int first, int last, int fanout) {
  std::string s;
  for (int id = first + 1; id <= last; ++id) {
    s += "<object id=\"" + std::to_string(id) + "\"><components>";
    for (int i = 0; i < fanout; ++i)
      s += "<component objectid=\"" + std::to_string(id - 1) + "\"/>";
    s += "</components></object>";
  }
  return s;
}

//! Seconds `f` takes.
template <class F>
double seconds(F&& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

TEST(ThreeMfReader, RefusesAnInstanceBombOfEmptyObjectsAtOnce) {
  // Object 1: one vertex, no triangle; objects 2..7: 100 components of the one before; the
  // build: object 7. 15 KiB of XML, 10^12 instances of nothing: refused without visiting
  // them (subtrees without triangles are skipped), in well under a second.
  const std::string bomb =
      "<object id=\"1\"><mesh><vertices><vertex x=\"0\" y=\"0\" z=\"0\"/></vertices><triangles>"
      "</triangles></mesh></object>" +
      component_levels(1, 7, 100);
  const std::string file = package_of(bomb, "<item objectid=\"7\"/>");
  EXPECT_LT(seconds([&] { expect_refused(file, "zero_triangles"); }), 1.0);
  // Beside a real object, the empty tree adds nothing and costs nothing.
  MeshInput in;
  EXPECT_LT(seconds([&] {
              in = read_mesh(span_of(package_of(
                  bomb + "<object id=\"8\" name=\"cube\">" + cube_mesh_xml() + "</object>",
                  "<item objectid=\"7\"/><item objectid=\"8\"/>")));
            }),
            1.0);
  EXPECT_EQ(in.soup.coords, cube_coords());
  ASSERT_EQ(in.parts.size(), 1u);
  EXPECT_EQ(in.parts[0].name, "cube");
}

TEST(ThreeMfReader, TransformsOnlyTheVerticesTrianglesUse) {
  // Object 1: 100000 vertices and one triangle; 10^5 instances of it. Transforming every
  // vertex of every instance is 10^10 vertices; only the 3 the triangle uses are.
  std::string mesh = "<object id=\"1\"><mesh><vertices>";
  for (int i = 0; i < 100000; ++i)
    mesh += "<vertex x=\"" + std::to_string(i) + "\" y=\"1\" z=\"2\"/>";
  mesh +=
      "</vertices><triangles><triangle v1=\"99999\" v2=\"7\" v3=\"50000\"/></triangles></mesh>"
      "</object>";
  const std::string file =
      package_of(mesh + component_levels(1, 2, 10) + component_levels(2, 4, 100),
                 "<item objectid=\"4\" transform=\"1 0 0 0 1 0 0 0 1 0 0 10\"/>");
  MeshInput in;
  EXPECT_LT(seconds([&] { in = read_mesh(span_of(file)); }), 1.0);
  ASSERT_EQ(in.soup.triangle_count(), 100000u);
  const std::vector<float> first(in.soup.coords.begin(), in.soup.coords.begin() + 9);
  EXPECT_EQ(first, (std::vector<float>{99999, 1, 12, 7, 1, 12, 50000, 1, 12}));
  // With 10^5 over max_triangles: refused on the count, as fast.
  StlReadOptions tight;
  tight.max_triangles = 99999;
  EXPECT_LT(seconds([&] { expect_refused(file, "too_many_triangles", tight); }), 1.0);
  // A coordinate out of range after the transforms names the vertex as the file numbers it.
  const std::string far =
      "<object id=\"1\"><mesh><vertices><vertex x=\"0\" y=\"0\" z=\"0\"/><vertex x=\"1\" "
      "y=\"0\" z=\"0\"/><vertex x=\"0\" y=\"1\" z=\"0\"/><vertex x=\"0\" y=\"0\" z=\"1\"/>"
      "</vertices><triangles><triangle v1=\"1\" v2=\"2\" v3=\"3\"/></triangles></mesh></object>";
  expect_refused_saying(package_of(far,
                                   "<item objectid=\"1\" transform=\"1 0 0 0 1 0 0 0 1e30 "
                                   "0 0 0\"/>"),
                        "coordinate_out_of_range", "object 1, vertex 3: z");
}

TEST(ThreeMfReader, BoundsTheWorkOfExpandingTheBuild) {
  // 200 build items of a 32-deep chain of components around one triangle: 200 triangles,
  // but 200 * 37 instances, vertices and triangles to expand, over 8 * 200 + 1024.
  StlReadOptions tight;
  tight.max_triangles = 200;
  const std::string triangle =
      "<object id=\"1\"><mesh><vertices><vertex x=\"0\" y=\"0\" z=\"0\"/><vertex x=\"1\" "
      "y=\"0\" z=\"0\"/><vertex x=\"0\" y=\"1\" z=\"0\"/></vertices><triangles><triangle "
      "v1=\"0\" v2=\"1\" v3=\"2\"/></triangles></mesh></object>";
  std::string items;
  for (int i = 0; i < 200; ++i) items += "<item objectid=\"33\"/>";
  const Error e =
      expect_refused(package_of(triangle + component_levels(1, 33, 1), items), "too_large", tight);
  EXPECT_EQ(e.field(), "max_triangles");
  EXPECT_TRUE(mentions(e,
                       "the build (up to object 33) expands to 2625 or more instances, used "
                       "vertices and triangles, more than the 2624 max_triangles 200 allows"))
      << e.what();
  // One such item is well within.
  EXPECT_EQ(read_mesh(span_of(package_of(triangle + component_levels(1, 33, 1),
                                         "<item objectid=\"33\"/>")),
                      tight)
                .soup.triangle_count(),
            1u);
}

TEST(ThreeMfReader, IgnoresExtensionsAndMetadata) {
  // Materials, metadata, an unknown extension element and attributes: the geometry only.
  const std::string model =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?><model unit=\"millimeter\" xml:lang=\"en-US\" "
      "xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\" "
      "xmlns:m=\"http://schemas.microsoft.com/3dmanufacturing/material/2015/02\" "
      "xmlns:x=\"urn:example\"><metadata name=\"Title\">part &amp; co</metadata><resources>"
      "<m:basematerials id=\"5\"><m:base name=\"red\" displaycolor=\"#FF0000\"/>"
      "</m:basematerials><object id=\"1\" name=\"cube\" pid=\"5\" pindex=\"0\">" +
      cube_mesh_xml() +
      "<x:extra><vertex x=\"nan\"/></x:extra></object></resources><build><item objectid=\"1\" "
      "x:note=\"n\"/></build></model>";
  const MeshInput in = read_mesh(span_of(package_3mf(model)));
  EXPECT_EQ(in.soup.coords, cube_coords());
  EXPECT_EQ(in.parts.at(0).name, "cube");
}

}  // namespace
}  // namespace stlrefine::test
