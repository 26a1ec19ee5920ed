// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_adaptive_bench: Labsik and Greiner's adaptive comparison (section 6: the cat,
// 728 triangles, refined adaptively at a dihedral criterion of 20 and 10 degrees to 9358 and
// 34228 triangles by interpolatory sqrt3 against 13364 and 49908 by the modified butterfly,
// "a reduction by about 30%") on our meshes: triangles made by adaptive sqrt3-interp and
// by adaptive butterfly (red-green 1-to-4) at the same dihedral criterion, next to the
// uniform counts at the levels they reached. Markdown on stdout. Hand-run, never a test.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "core/features/features.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/mesh/indexed_soup.h"
#include "core/refine.h"
#include "core/schemes/adaptive_split4.h"
#include "core/schemes/adaptive_sqrt3.h"
#include "core/schemes/scheme.h"

namespace fs = std::filesystem;
using namespace stlrefine;

namespace {

using Clock = std::chrono::steady_clock;

struct Options {
  std::string mesh_dir = "/work/shared/meshes";
  //! Files relative to mesh_dir, or "icosphere" (generated here: 80 faces, radius 10).
  std::vector<std::string> inputs{"icosphere", "generated/sphere_fn16.stl", "organic/bunny_low.stl",
                                  "organic/spot.stl", "cad/fandisk.stl"};
  std::vector<double> angles{20, 10};
  int sqrt3_cap = 8;
  int split4_cap = 6;
  double crease_angle = 35;
};

struct Run {
  std::size_t faces = 0;
  int levels = 0;
  std::size_t over_at_cap = 0;  // faces (sqrt3) or edges (1-to-4) still over the angle
  std::size_t by_criterion = 0, by_closure = 0;
  double seconds = 0;
};

// An icosahedron split 1-to-4 once, projected onto the sphere of radius 10 (80 faces): a sphere
// with well-shaped triangles (valence 5 and 6), unlike OpenSCAD's sphere_fn16 with its fans.
IndexedSoup icosphere() {
  const double t = (1 + std::sqrt(5.0)) / 2;
  IndexedSoup soup;
  soup.positions = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  soup.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int round = 0; round < 1; ++round) {
    std::vector<std::array<std::uint32_t, 3>> next;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> mids;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const std::uint64_t key = (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
      for (const auto& [k, v] : mids)
        if (k == key) return v;
      soup.positions.push_back(0.5 * (soup.positions[a] + soup.positions[b]));
      const auto v = static_cast<std::uint32_t>(soup.positions.size() - 1);
      mids.emplace_back(key, v);
      return v;
    };
    for (const auto& [a, b, c] : soup.triangles) {
      const std::uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      next.insert(next.end(), {{a, ab, ca}, {ab, b, bc}, {ca, bc, c}, {ab, bc, ca}});
    }
    soup.triangles = std::move(next);
  }
  for (Vec3& p : soup.positions) p = 10.0 * normalized(p);
  return soup;
}

Run run_sqrt3(const Level& input, double angle, int cap, Sqrt3Closure closure) {
  const auto scheme = make_scheme("sqrt3-interp");
  const auto t0 = Clock::now();
  AdaptiveSqrt3 adaptive(input, *adaptive_sqrt3_scheme(*scheme), {angle, 0, cap, closure});
  adaptive.run(std::uint64_t{1} << 31);
  const Level out = adaptive.result();
  Run r;
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.faces = out.mesh.num_faces();
  r.levels = adaptive.stats().levels;
  r.over_at_cap = adaptive.stats().over_criterion_at_cap;
  r.by_criterion = adaptive.stats().refined_by_criterion;
  r.by_closure = adaptive.stats().refined_by_closure;
  return r;
}

Run run_butterfly(const Level& input, double angle, int cap) {
  const auto scheme = make_scheme("butterfly");
  const Split4Stencil& stencil = *adaptive_scheme(*scheme);
  const auto t0 = Clock::now();
  AdaptiveSplit4 adaptive(input);
  StepStats stats;
  Run r;
  for (int i = 1; i <= cap; ++i) {
    AdaptiveStepStats step;
    if (!adaptive.step(stencil, 0, std::uint64_t{1} << 31, stats, step, angle)) break;
    r.levels = i;
    r.by_criterion += step.red_by_tolerance;
    r.by_closure += step.red_by_closure;
  }
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.faces = adaptive.level().mesh.num_faces();
  if (r.levels == cap)
    r.over_at_cap = count_edges_over_tolerance(adaptive.level(), stencil, 0, angle);
  return r;
}

std::string thousands(std::size_t n) {
  const std::string digits = std::to_string(n);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out.push_back(',');
    out.push_back(digits[i]);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "Adaptive sqrt3-interp vs adaptive butterfly at the same dihedral criterion "
      "(Labsik-Greiner section 6). Markdown on stdout."};
  app.add_option("mesh_dir", o.mesh_dir, "Directory of the test meshes")->capture_default_str();
  app.add_option("--inputs", o.inputs, "Input files relative to mesh_dir")->capture_default_str();
  app.add_option("--angles", o.angles, "Dihedral criteria (degrees)")->capture_default_str();
  app.add_option("--sqrt3-cap", o.sqrt3_cap, "max_level of sqrt3-interp")->capture_default_str();
  app.add_option("--split4-cap", o.split4_cap, "max_level of butterfly")->capture_default_str();
  app.add_option("--crease-angle", o.crease_angle, "Crease angle (degrees)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::cout << "sqrt3-interp max_level " << o.sqrt3_cap << ", butterfly max_level " << o.split4_cap
            << ", crease angle " << o.crease_angle
            << "°. Refined = triangles (sqrt3) or red triangles (butterfly) split because the "
               "criterion asked + to close the mesh; over at cap = faces (sqrt3) or edges "
               "(butterfly) still over the angle at the level cap.\n\n"
            << "| input | faces | angle | sqrt3-interp | levels | over at cap | refined | s | "
               "edge closure | butterfly | levels | over at cap | refined | s | sqrt3 / "
               "butterfly | edge closure / butterfly |\n"
               "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  for (const std::string& name : o.inputs) {
    std::cerr << "reading " << name << '\n';
    const Mesh mesh = name == "icosphere"
                          ? build_mesh(icosphere()).mesh
                          : build_mesh(weld(read_stl_file(fs::path(o.mesh_dir) / name))).mesh;
    const Level input{mesh, detect_features(mesh, {o.crease_angle})};
    for (double angle : o.angles) {
      std::cerr << "  " << name << " at " << angle << " degrees\n";
      const Run s = run_sqrt3(input, angle, o.sqrt3_cap, Sqrt3Closure::Stencil);
      const Run e = run_sqrt3(input, angle, o.sqrt3_cap, Sqrt3Closure::EdgeNeighbours);
      const Run b = run_butterfly(input, angle, o.split4_cap);
      char line[512];
      std::snprintf(line, sizeof line,
                    "| %s | %s | %g° | %s | %d | %zu | %zu + %zu | %.3f | %s | %s | %d | %zu | "
                    "%zu + %zu | %.3f | %.2f | %.2f |",
                    name.c_str(), thousands(mesh.num_faces()).c_str(), angle,
                    thousands(s.faces).c_str(), s.levels, s.over_at_cap, s.by_criterion,
                    s.by_closure, s.seconds, thousands(e.faces).c_str(), thousands(b.faces).c_str(),
                    b.levels, b.over_at_cap, b.by_criterion, b.by_closure, b.seconds,
                    double(s.faces) / double(b.faces), double(e.faces) / double(b.faces));
      std::cout << line << std::endl;
    }
  }
  return 0;
}
