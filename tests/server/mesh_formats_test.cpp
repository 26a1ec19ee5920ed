// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Mesh formats through the request path (issue 19 item 2): the same part as STL, OBJ, PLY
// and 3MF refines to the same geometry; a 3MF's declared unit converts without units= and
// is reported; mesh_format=3mf (and Accept: model/3mf) answers a 3MF with one object per
// input object, through the daemon and the CLI.

#include "core/io/mesh_formats.h"

#include <gtest/gtest.h>

#include <charconv>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "api/params.h"
#include "api/pipeline.h"
#include "api/plan.h"
#include "core/error.h"
#include "core/mesh/build_mesh.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// A box [0, s]^3 (+ offset on x) as indexed triangles, outward facing.
struct Indexed {
  std::vector<Corner> v;
  std::vector<std::array<int, 3>> t;
};

Indexed box(float s, float dx = 0) {
  Indexed b;
  for (int i = 0; i < 8; ++i)
    b.v.push_back({(i & 1) ? s + dx : dx, (i & 2) ? s : 0.0f, (i & 4) ? s : 0.0f});
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    b.t.push_back({q[0], q[1], q[2]});
    b.t.push_back({q[0], q[2], q[3]});
  }
  return b;
}

std::vector<Triangle> triangles(const Indexed& b) {
  std::vector<Triangle> out;
  for (const auto& t : b.t) out.push_back({b.v[t[0]], b.v[t[1]], b.v[t[2]]});
  return out;
}

// Shortest round-trip text, so that every format holds the same floats.
std::string num(float f) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, f);
  return std::string(buf, r.ptr);
}

std::string obj_of(const Indexed& b) {
  std::string s = "o box\n";
  for (const Corner& c : b.v) s += "v " + num(c[0]) + " " + num(c[1]) + " " + num(c[2]) + "\n";
  // Negative (relative) indices, as some exporters write them.
  const int n = static_cast<int>(b.v.size());
  for (const auto& t : b.t)
    s += "f " + std::to_string(t[0] - n) + " " + std::to_string(t[1] - n) + " " +
         std::to_string(t[2] - n) + "\n";
  return s;
}

std::string ply_of(const Indexed& b) {
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(b.v.size()) +
      "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
      std::to_string(b.t.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Corner& c : b.v) s.append(reinterpret_cast<const char*>(c.data()), 12);
  for (const auto& t : b.t) {
    s.push_back(3);
    s.append(reinterpret_cast<const char*>(t.data()), 12);
  }
  return s;
}

Mesh mesh_of(const Indexed& b) {
  IndexedSoup soup;
  for (const Corner& c : b.v) soup.positions.push_back({c[0], c[1], c[2]});
  for (const auto& t : b.t)
    soup.triangles.push_back({static_cast<std::uint32_t>(t[0]), static_cast<std::uint32_t>(t[1]),
                              static_cast<std::uint32_t>(t[2])});
  return build_mesh(soup).mesh;
}

std::string three_mf(const std::vector<std::pair<std::string, Indexed>>& objects,
                     const std::string& unit = "millimeter") {
  std::vector<Mesh> meshes;
  for (const auto& o : objects) meshes.push_back(mesh_of(o.second));
  std::vector<NamedMesh> named;
  for (std::size_t i = 0; i < objects.size(); ++i) named.push_back({objects[i].first, &meshes[i]});
  return write_3mf(named, unit);
}

api::RefinedMesh refine_levels(const std::string& file, int levels = 1) {
  api::RefineRequest request =
      api::parse_refine_params({{"levels", std::to_string(levels)}, {"max_deviation", "off"}}, {});
  return api::run_refine_to_mesh(bytes_of(file), request);
}

TEST(MeshFormats, TheSamePartInEveryFormatRefinesToTheSameGeometry) {
  const Indexed part = box(20);
  const api::RefinedMesh stl = refine_levels(binary_stl(triangles(part)));
  ASSERT_TRUE(stl.stream());
  for (const std::string& file : {obj_of(part), ply_of(part), three_mf({{"box", part}})}) {
    const api::RefinedMesh other = refine_levels(file);
    ASSERT_TRUE(other.stream());
    const std::string format = other.outcome.report["input"]["file_format"];
    ASSERT_EQ(other.mesh.num_vertices(), stl.mesh.num_vertices()) << format;
    ASSERT_EQ(other.mesh.num_faces(), stl.mesh.num_faces()) << format;
    for (std::size_t v = 0; v < stl.mesh.num_vertices(); ++v) {
      const Vec3 a = stl.mesh.positions()[v], b = other.mesh.positions()[v];
      ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z) << format << " vertex " << v;
    }
    const auto ca = stl.mesh.corner_vertices(), cb = other.mesh.corner_vertices();
    ASSERT_TRUE(std::equal(ca.begin(), ca.end(), cb.begin(), cb.end())) << format;
  }
}

// The plan counts an OBJ's triangles (and a PLY's faces) before any work, as it counts an
// STL's: the face budget refuses before ingest, and the memory estimate sees them.
TEST(MeshFormats, ThePlanCountsTheFacesOfEveryTextFormat) {
  const Indexed part = box(20);
  api::RefineRequest request = api::parse_refine_params({{"levels", "1"}}, {});
  EXPECT_EQ(api::plan_refine(request, bytes_of(obj_of(part))).shape.faces, 12u);
  EXPECT_EQ(api::plan_refine(request, bytes_of(ply_of(part))).shape.faces, 12u);
  EXPECT_EQ(api::plan_refine(request, bytes_of("o q\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                               "f 1 2 3 4\n  f\t1 3 4\n"))
                .shape.faces,
            3u);
  request.refine.max_faces = 40;  // 12 faces -> 48 at one level
  const api::RefinePlan plan = api::plan_refine(request, bytes_of(obj_of(part)));
  EXPECT_THROW(api::refuse_over_face_budget(plan), Error);
  EXPECT_GT(plan.memory.peak_bytes,
            api::plan_refine(request, bytes_of(std::string("v 0 0 0\n"))).memory.peak_bytes);
}

TEST(MeshFormats, A3mfInMetresComesOutInMillimetresWithItsUnitReported) {
  const std::string file = three_mf({{"cube", box(0.01f)}}, "meter");
  const nlohmann::ordered_json report = api::run_info(bytes_of(file), {});
  const auto& units = report["input"]["units"];
  EXPECT_EQ(report["input"]["file_format"], "3mf");
  EXPECT_EQ(units["units"], "m");
  EXPECT_EQ(units["declared"], "meter");
  EXPECT_EQ(units["assumed"], false);
  EXPECT_DOUBLE_EQ(units["factor_to_mm"].get<double>(), 1000.0);
  EXPECT_NEAR(units["size_mm"][0].get<double>(), 10.0, 1e-4);
  EXPECT_TRUE(report["warnings"].empty()) << report["warnings"];
  // Sliced in mm: 10 mm at 1 mm layers.
  api::SliceRequest slice = api::parse_slice_params({{"layer_height", "1"}}, {});
  EXPECT_EQ(nlohmann::json::parse(api::run_slice(bytes_of(file), slice).contours)["layers"].size(),
            10u);
  // The declared unit wins over units=, and the report says so.
  api::InfoRequest in_cm;
  in_cm.units.units = api::LengthUnit::Centimetre;
  const nlohmann::ordered_json cm = api::run_info(bytes_of(file), in_cm);
  EXPECT_EQ(cm["input"]["units"]["units"], "m");
  ASSERT_EQ(cm["warnings"].size(), 1u);
  EXPECT_NE(cm["warnings"][0]["message"].get<std::string>().find("units=cm is ignored"),
            std::string::npos);
  // A micron part reads as mm too.
  const nlohmann::ordered_json um =
      api::run_info(bytes_of(three_mf({{"c", box(10000)}}, "micron")), {});
  EXPECT_EQ(um["input"]["units"]["declared"], "micron");
  EXPECT_NEAR(um["input"]["units"]["size_mm"][2].get<double>(), 10.0, 1e-6);
}

TEST(MeshFormats, MeshFormatIsValidatedWithItsName) {
  EXPECT_EQ(api::parse_refine_params({{"mesh_format", "3mf"}}, {}).mesh_format,
            MeshFormat::ThreeMf);
  EXPECT_TRUE(api::parse_refine_params({{"mesh_format", "stl"}}, {}).mesh_format_given);
  for (const api::RawParams& raw : std::vector<api::RawParams>{
           {{"mesh_format", "obj"}}, {{"mesh_format", "3mf"}, {"slice", "0.5"}}}) {
    try {
      api::parse_refine_params(raw, {});
      ADD_FAILURE() << "accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_EQ(e.field(), "mesh_format");
    }
  }
}

TEST(MeshFormats, MultiObject3mfIsRefinedObjectByObject) {
  const std::string file = three_mf({{"left", box(10)}, {"right", box(10, 30)}});
  api::RefineRequest request = api::parse_refine_params({{"mesh_format", "3mf"}}, {});
  const api::RefineOutcome out = api::run_refine(bytes_of(file), request);
  const MeshInput back = read_mesh(bytes_of(out.stl));
  ASSERT_EQ(back.parts.size(), 2u);
  EXPECT_EQ(back.parts[0].name, "left");
  EXPECT_EQ(back.parts[1].name, "right");
  EXPECT_EQ(back.parts[0].triangle_count, 48u);
  EXPECT_EQ(back.parts[1].triangle_count, 48u);
  EXPECT_EQ(back.unit->name, "millimeter");
  EXPECT_EQ(out.report["output"]["format"], "3mf");
  EXPECT_EQ(out.report["output"]["faces"], 96u);
  EXPECT_EQ(out.report["input"]["faces"], 24u);
  ASSERT_EQ(out.report["objects"].size(), 2u);
  EXPECT_EQ(out.report["objects"][1]["name"], "right");
  EXPECT_EQ(out.report["objects"][1]["output_faces"], 48u);
}

class MeshFormatsBinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stlrefine_formats_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream(path("two.3mf"), std::ios::binary)
        << three_mf({{"left", box(10)}, {"right", box(10, 30)}});
    std::ofstream(path("box.obj"), std::ios::binary) << obj_of(box(10));
    std::ofstream(path("bad.obj"), std::ios::binary) << "v 0 0 0\nf 1 2 3\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(MeshFormatsBinaryTest, DaemonAnswersA3mfWithTwoObjects) {
  if (!fs::exists("/usr/bin/curl")) GTEST_SKIP() << "curl is not installed";
  Child daemon({STLREFINED, "--port", "0"});
  const int port = listening_port(daemon);
  ASSERT_GT(port, 0) << daemon.stderr_text();
  const std::string url = "http://127.0.0.1:" + std::to_string(port);
  const auto post = [&](const std::string& file, const std::string& target,
                        std::vector<std::string> headers = {}) {
    std::vector<std::string> argv = {"/usr/bin/curl",
                                     "-sS",
                                     "--data-binary",
                                     std::string("@").append(path(file)),
                                     "-D",
                                     path("headers"),
                                     "-o",
                                     path("body"),
                                     "-w",
                                     "%{http_code}"};
    for (const std::string& h : headers) {
      argv.push_back("-H");
      argv.push_back(h);
    }
    argv.push_back(url + target);
    const ProcessResult r = run_process(argv);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return std::atoi(r.out.c_str());
  };
  const auto two_objects = [&] {
    const std::string body = read_file(path("body"));
    const MeshInput in = read_mesh(bytes_of(body));
    EXPECT_EQ(in.format, MeshFormat::ThreeMf);
    ASSERT_EQ(in.parts.size(), 2u);
    EXPECT_EQ(in.parts[0].name, "left");
    EXPECT_EQ(in.parts[1].name, "right");
    EXPECT_EQ(in.parts[1].triangle_count, 48u);
    EXPECT_NE(read_file(path("headers")).find("Content-Type: model/3mf"), std::string::npos);
  };
  ASSERT_EQ(post("two.3mf", "/v1/refine?mesh_format=3mf", {"Content-Type: model/3mf"}), 200);
  two_objects();
  // Accept alone asks for it; without either the answer stays a binary STL of both parts.
  ASSERT_EQ(post("two.3mf", "/v1/refine", {"Accept: model/3mf"}), 200);
  two_objects();
  ASSERT_EQ(post("two.3mf", "/v1/refine"), 200);
  EXPECT_EQ(read_binary_stl(read_file(path("body"))).size(), 96u);
  EXPECT_NE(read_file(path("headers")).find("\"file_format\":\"3mf\""), std::string::npos);
  // OBJ in, info out; bad OBJ: a 422 naming the reason.
  ASSERT_EQ(post("box.obj", "/v1/info", {"Content-Type: model/obj"}), 200);
  EXPECT_EQ(nlohmann::json::parse(read_file(path("body")))["input"]["file_format"], "obj");
  ASSERT_EQ(post("bad.obj", "/v1/refine"), 422);
  const nlohmann::json problem = nlohmann::json::parse(read_file(path("body")));
  EXPECT_NE(problem.dump().find("bad_index"), std::string::npos) << problem;
  ASSERT_EQ(post("two.3mf", "/v1/refine?mesh_format=ply"), 400);
  EXPECT_EQ(nlohmann::json::parse(read_file(path("body")))["field"], "mesh_format");
  // A job takes it too: its result is result.3mf (tests/server/job_parts_test.cpp follows one).
  ASSERT_EQ(post("two.3mf", "/v1/jobs?mesh_format=3mf"), 202);
  EXPECT_NE(read_file(path("headers")).find("Location: /v1/jobs/"), std::string::npos);
}

TEST_F(MeshFormatsBinaryTest, CliWrites3mfForA3mfName) {
  ProcessResult r = run_process(
      {STLREFINE_CLI, "refine", path("two.3mf"), "-o", path("out.3MF"), "--levels", "1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  MeshInput in = read_mesh(bytes_of(read_file(path("out.3MF"))));
  EXPECT_EQ(in.parts.size(), 2u);
  r = run_process(
      {STLREFINE_CLI, "refine", path("box.obj"), "-o", path("out.bin"), "--mesh-format", "3mf"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_mesh(bytes_of(read_file(path("out.bin")))).format, MeshFormat::ThreeMf);
  r = run_process({STLREFINE_CLI, "refine", path("box.obj"), "-o", path("out.3mf"), "--ascii"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--ascii"), std::string::npos) << r.err;
  r = run_process({STLREFINE_CLI, "refine", path("bad.obj"), "-o", path("x.stl")});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("line 2"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace stlrefine::test
