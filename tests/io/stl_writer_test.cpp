// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "tests/io/io_test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

float float_at(const std::string& bytes, std::size_t offset) {
  float v;
  std::memcpy(&v, bytes.data() + offset, 4);
  return v;
}

//! The mesh's corners rounded to float, face by face: what an STL of it must hold.
std::vector<float> expected_coords(const Mesh& mesh) {
  std::vector<float> out;
  for (const VertexId v : mesh.corner_vertices()) {
    const Vec3& p = mesh.position(v);
    out.insert(out.end(),
               {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
  }
  return out;
}

//! A closed sphere whose positions are not representable as float.
Mesh sphere() {
  return to_mesh(icosphere_soup(2, 10.0 / 3.0));
}

TEST(StlWriter, BinaryRoundTripKeepsPositions) {
  const Mesh mesh = sphere();
  const std::string bytes = write_stl(mesh);
  ASSERT_EQ(bytes.size(), 84 + 50 * mesh.num_faces());
  const TriangleSoup soup = read_stl(span_of(bytes));
  EXPECT_EQ(soup.format, StlFormat::Binary);
  EXPECT_EQ(soup.name, "stlrefine");
  EXPECT_EQ(soup.coords, expected_coords(mesh));
  EXPECT_EQ(weld(soup).positions.size(), mesh.num_vertices());
}

TEST(StlWriter, AsciiRoundTripKeepsPositions) {
  const Mesh mesh = sphere();
  const std::string text = write_stl(mesh, StlFormat::Ascii, "ball");
  EXPECT_EQ(text.rfind("solid ball\n", 0), 0u);
  EXPECT_EQ(text.substr(text.size() - 14), "endsolid ball\n");
  const TriangleSoup soup = read_stl(span_of(text));
  EXPECT_EQ(soup.format, StlFormat::Ascii);
  EXPECT_EQ(soup.name, "ball");
  // Shortest round-trip floats: the same bits as the binary file.
  EXPECT_EQ(soup.coords, expected_coords(mesh));
  EXPECT_EQ(soup.coords, read_stl(span_of(write_stl(mesh))).coords);
}

TEST(StlWriter, RoundTripsTheGearwheelBitExactly) {
  const TriangleSoup original = read_stl_file(data_file("gearwheel.stl"));
  const Mesh mesh = build_mesh(weld(original)).mesh;
  for (const StlFormat format : {StlFormat::Binary, StlFormat::Ascii}) {
    SCOPED_TRACE(to_string(format));
    const IndexedSoup again = weld(read_stl(span_of(write_stl(mesh, format))));
    ASSERT_EQ(again.positions.size(), mesh.num_vertices());
    ASSERT_EQ(again.triangles.size(), mesh.num_faces());
    // The positions are floats already, so every corner comes back bit-exactly.
    const auto corners = mesh.corner_vertices();
    for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
      for (std::size_t k = 0; k < 3; ++k) {
        ASSERT_EQ(again.positions[again.triangles[f][k]], mesh.position(corners[3 * f + k]));
      }
    }
  }
}

TEST(StlWriter, WritesUnitNormalsOfTheRoundedTriangles) {
  const Mesh mesh = sphere();
  const std::string bytes = write_stl(mesh);
  for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
    const std::size_t at = 84 + 50 * f;
    const Vec3 n(float_at(bytes, at), float_at(bytes, at + 4), float_at(bytes, at + 8));
    Vec3 p[3];
    for (int k = 0; k < 3; ++k) {
      const std::size_t c = at + 12 + 12 * k;
      p[k] = Vec3(float_at(bytes, c), float_at(bytes, c + 4), float_at(bytes, c + 8));
    }
    const Vec3 expected = normalized(triangle_normal(p[0], p[1], p[2]));
    EXPECT_NEAR(norm(n), 1.0, 1e-6);
    EXPECT_NEAR(distance(n, expected), 0.0, 1e-6);
    EXPECT_EQ(bytes[at + 48], 0);  // attribute byte count
    EXPECT_EQ(bytes[at + 49], 0);
  }
}

TEST(StlWriter, WritesZeroNormalForZeroAreaFaces) {
  const Mesh mesh =
      build_mesh(weld(read_stl_file(data_file("malformed/degenerate_tjunction.stl")))).mesh;
  const std::string bytes = write_stl(mesh);
  std::size_t zero_area = 0;
  for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
    if (norm(mesh.face_normal(FaceId(static_cast<std::uint32_t>(f)))) != 0) continue;
    ++zero_area;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(float_at(bytes, 84 + 50 * f + 4 * k), 0.0f);
  }
  EXPECT_EQ(zero_area, 1u);
}

TEST(StlWriter, BinaryHeaderNeverStartsWithSolid) {
  const std::string bytes = write_stl(sphere(), StlFormat::Binary, "solid part");
  EXPECT_EQ(bytes.substr(0, 17), "binary solid part");
  EXPECT_EQ(read_stl(span_of(bytes)).name, "binary solid part");
  const std::string plain = write_stl(sphere(), StlFormat::Binary, "part 7");
  EXPECT_EQ(read_stl(span_of(plain)).name, "part 7");
}

TEST(StlWriter, SanitisesTheSolidName) {
  const std::string text = write_stl(sphere(), StlFormat::Ascii, "  two\nlines\x01 ");
  EXPECT_EQ(text.rfind("solid two_lines_\n", 0), 0u);
  EXPECT_EQ(read_stl(span_of(text)).name, "two_lines_");
}

TEST(StlWriter, WritesAnEmptyMesh) {
  const std::string bytes = write_stl(Mesh());
  ASSERT_EQ(bytes.size(), 84u);
  EXPECT_EQ(float_at(bytes, 80), 0.0f);
  EXPECT_EQ(write_stl(Mesh(), StlFormat::Ascii, "e"), "solid e\nendsolid e\n");
}

TEST(StlWriter, RefusesPositionsBeyondFloat) {
  Mesh mesh = sphere();
  mesh.mutable_positions()[0] = Vec3(1e300, 0, 0);
  try {
    write_stl(mesh);
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Internal);
    EXPECT_EQ(e.reason(), "non_finite");
  }
}

class StlWriterFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("stlrefine_io_test_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(StlWriterFile, WritesAtomicallyAndReplaces) {
  const std::filesystem::path path = dir_ / "out.stl";
  const Mesh mesh = sphere();
  write_stl_file(path, mesh, StlFormat::Ascii, "first");
  EXPECT_EQ(read_stl_file(path).name, "first");
  write_stl_file(path, mesh);  // replaces the ASCII file
  const TriangleSoup soup = read_stl_file(path);
  EXPECT_EQ(soup.format, StlFormat::Binary);
  EXPECT_EQ(soup.coords, expected_coords(mesh));
  // Only the target is left: no temporary files.
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1u);
}

TEST_F(StlWriterFile, ReportsAMissingDirectory) {
  try {
    write_stl_file(dir_ / "missing" / "out.stl", sphere());
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    EXPECT_EQ(e.field(), "path");
  }
}

}  // namespace
}  // namespace stlrefine::test
