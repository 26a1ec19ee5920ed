// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The curvature report (issue 4 item 4) through the CLI binary: `stlrefine info` carries a
// `curvature` summary and `--curvature out.csv` the per-vertex table. On a sphere of radius
// r the mean curvature is about 1/r and the Gaussian 1/r^2.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "subprocess.h"
#include "test_stl.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string item; std::getline(ss, item, sep);) out.push_back(item);
  return out;
}

TEST(CurvatureReport, SphereMeanCurvatureIsOneOverRadius) {
  constexpr double r = 5.0;
  const IndexedSoup soup = icosphere_soup(3, r);  // 1280 faces, 642 vertices
  std::vector<Triangle> triangles;
  for (const auto& t : soup.triangles) {
    Triangle tri;
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = soup.positions[t[k]];
      tri[k] = {float(p.x), float(p.y), float(p.z)};
    }
    triangles.push_back(tri);
  }
  std::string tmpl = (fs::temp_directory_path() / "stlrefine-curv-XXXXXX").string();
  ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
  const fs::path dir = tmpl;
  const std::string stl = (dir / "sphere.stl").string();
  const std::string csv = (dir / "curv.csv").string();
  std::ofstream(stl, std::ios::binary) << binary_stl(triangles);

  const ProcessResult run = run_process({STLREFINE_CLI, "info", stl, "--curvature", csv}, 60s);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto report = nlohmann::json::parse(run.out);
  const auto& c = report.at("curvature");
  EXPECT_EQ(c.at("valid"), soup.positions.size());
  EXPECT_EQ(c.at("invalid"), 0);
  // Outward orientation: |mean| near 1/r whichever sign convention the fit uses.
  EXPECT_NEAR(std::abs(c.at("mean").at("p50").get<double>()), 1 / r, 0.05 / r);
  EXPECT_NEAR(c.at("gaussian").at("p50").get<double>(), 1 / (r * r), 0.1 / (r * r));
  EXPECT_NEAR(c.at("abs_max").at("p50").get<double>(), 1 / r, 0.1 / r);

  std::ifstream in(csv);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, "vertex,x,y,z,kind,gaussian,mean,k1,k2,valid");
  std::size_t rows = 0, near = 0;
  while (std::getline(in, line)) {
    const auto f = split(line, ',');
    ASSERT_EQ(f.size(), 10u) << line;
    EXPECT_EQ(std::stoul(f[0]), rows);
    const double x = std::stod(f[1]), y = std::stod(f[2]), z = std::stod(f[3]);
    EXPECT_NEAR(std::sqrt(x * x + y * y + z * z), r, 1e-5);
    EXPECT_EQ(f[4], "smooth");
    EXPECT_EQ(f[9], "1");
    const double mean = std::stod(f[6]), k1 = std::stod(f[7]), k2 = std::stod(f[8]);
    EXPECT_GE(k1, k2);
    near += std::abs(std::abs(mean) - 1 / r) < 0.05 / r;
    ++rows;
  }
  EXPECT_EQ(rows, soup.positions.size());
  EXPECT_GE(near, rows * 95 / 100);  // within 5 % of 1/r at (almost) every vertex
  fs::remove_all(dir);
}

TEST(CurvatureReport, CreasedPartHasKindsAndInvalidCorners) {
  const std::string fandisk = STLREFINE_EXAMPLES_DIR "/fandisk.stl";
  std::string csv = (fs::temp_directory_path() / "stlrefine-curv-fandisk-").string();
  csv += std::to_string(::getpid()) + ".csv";
  const ProcessResult run = run_process({STLREFINE_CLI, "info", fandisk, "--curvature", csv}, 60s);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto report = nlohmann::json::parse(run.out);
  EXPECT_GT(report.at("curvature").at("invalid").get<int>(), 0);  // corners at least
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::size_t corners = 0, creases = 0;
  while (std::getline(in, line)) {
    const auto f = split(line, ',');
    ASSERT_EQ(f.size(), 10u);
    if (f[4] == "corner") {
      ++corners;
      EXPECT_EQ(f[9], "0");
    }
    creases += f[4] == "crease";
  }
  EXPECT_EQ(corners, report.at("features").at("corners").get<std::size_t>());
  EXPECT_EQ(creases, report.at("features").at("creases").get<std::size_t>());
  fs::remove(csv);

  // An unwritable table is exit 1, and the report is not printed as success.
  const ProcessResult bad =
      run_process({STLREFINE_CLI, "info", fandisk, "--curvature", "/nonexistent/dir/x.csv"}, 60s);
  EXPECT_EQ(bad.exit_code, 1);
}

}  // namespace
}  // namespace stlrefine::test
