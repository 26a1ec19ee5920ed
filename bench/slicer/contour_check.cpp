// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_contour_check: every mesh of the shared mesh folder (the large dragon included)
// that is closed after ingest, scaled to millimetres as stlrefine_slice_bench does, sliced
// at the given layer heights and checked by tests/slicer/contour_check.h: closed loops, no
// open polylines, outer ccw / holes cw, nesting as a containment count says, no crossing
// loops, every loop edge a face's own segment in the face's direction. Findings near the
// surface's self-intersections are told apart. Prints a Markdown table; hand-run
// (bench/slicer/README.md). The meshes small enough for ctest are also checked by
// tests/slicer/shared_meshes_test.cpp.

#include "tests/slicer/contour_check.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "slicer/slice.h"

namespace {

namespace fs = std::filesystem;
using namespace stlrefine;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string fmt(const char* format, double x) {
  char text[64];
  std::snprintf(text, sizeof(text), format, x);
  return text;
}

int run(int argc, char** argv) {
  fs::path mesh_dir = "/work/shared/meshes";
  std::vector<double> heights = {0.1};
  fs::path tmp_dir = "/tmp/stlrefine_slice_bench";
  double margin = 0.02;
  CLI::App app{"stlrefine_contour_check: slice every closed shared mesh and check the contours"};
  app.add_option("mesh_dir", mesh_dir, "Folder of the shared meshes");
  app.add_option("--heights", heights, "Layer heights in mm");
  app.add_option("--tmp-dir", tmp_dir, "Where .stl.gz inputs are unpacked");
  app.add_option("--margin", margin, "mm around a self-intersection a finding may lie");
  CLI11_PARSE(app, argc, argv);

  std::vector<std::pair<std::string, fs::path>> files;  // (name relative to mesh_dir, path)
  for (const char* folder : {"cad", "generated", "organic", "malformed", "large"}) {
    if (!fs::exists(mesh_dir / folder)) continue;
    std::vector<fs::path> found;
    for (const auto& e : fs::directory_iterator(mesh_dir / folder)) {
      const std::string n = e.path().filename().string();
      if (n.ends_with(".stl") || n.ends_with(".stl.gz")) found.push_back(e.path());
    }
    std::sort(found.begin(), found.end());
    for (const fs::path& p : found)
      files.emplace_back(std::string(folder) + "/" + p.filename().string(), p);
  }

  std::cout << "| mesh | ×scale | faces | boundary half-edges | h mm | layers | outer | holes | "
               "points | open | loops against their faces (slicer: reversed) | crossing layers "
               "(nesting left ambiguous by them) | other faults | self-intersecting face pairs | "
               "verdict | s |\n";
  std::cout << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  int failures = 0;
  for (const auto& [name, source] : files) {
    std::cerr << "== " << name << '\n';
    const auto t0 = std::chrono::steady_clock::now();
    fs::path path = source;
    if (source.extension() == ".gz") {
      fs::create_directories(tmp_dir);
      path = tmp_dir / source.stem();
      if (!fs::exists(path)) {
        const std::string cmd = "gunzip -c '" + source.string() + "' > '" + path.string() + "'";
        if (std::system(cmd.c_str()) != 0) throw std::runtime_error("gunzip failed: " + cmd);
      }
    }
    const double scale = test::shared_mesh_scale(name);
    Mesh mesh;
    try {
      mesh = build_mesh(weld(read_stl_file(path))).mesh;
    } catch (const Error& e) {
      std::cout << "| " << name << " | | | | | | | | | | | | | | not read: " << e.what()
                << " | |\n";
      continue;
    }
    std::size_t boundary = 0;
    for (const HalfedgeId t : mesh.twins()) boundary += !t.valid();
    std::cout << "| " << name << " | " << scale << " | " << mesh.num_faces() << " | " << boundary
              << " |";
    if (boundary > 0) {
      std::cout << " | | | | | | | | | | open: not checked | |\n";
      continue;
    }
    for (Vec3& p : mesh.mutable_positions()) p *= scale;
    std::vector<test::Box3> boxes;
    bool have_boxes = false;
    for (std::size_t i = 0; i < heights.size(); ++i) {
      if (i > 0) std::cout << "| | | | |";
      slicer::SliceParams params;
      params.layer_height = heights[i];
      const test::ContourCheck c = test::check_contours(mesh, params);
      if (!c.ok() && !have_boxes) {
        boxes = test::self_intersection_boxes(mesh);
        have_boxes = true;
      }
      std::size_t explained = 0;
      double widest = 0;  // the largest gap between an explained finding and its intersection
      std::string first_unexplained;
      for (const test::Finding& f : c.findings) {
        if (test::explained_by(f, boxes, margin)) {
          ++explained;
          widest = std::max(widest, test::gap_to(f, boxes));
          continue;
        }
        if (first_unexplained.empty()) first_unexplained = f.what;
        std::cerr << "  unexplained: " << f.what << " (" << test::gap_to(f, boxes)
                  << " mm from the nearest self-intersection)\n";
      }
      const std::size_t other =
          c.open + c.short_loops + c.wrong_sign + c.wrong_nesting + c.unprobed + c.unmatched;
      std::string verdict = "ok";
      if (explained < c.findings.size()) {
        ++failures;
        verdict = "**FAIL**: " + first_unexplained;
      } else if (!c.ok()) {
        verdict = "ok away from self-intersections (" + std::to_string(explained) +
                  " findings, all within " + fmt("%.4f", widest) + " mm of them)";
      }
      std::cout << " " << heights[i] << " | " << c.layers << " | " << c.outer << " | " << c.holes
                << " | " << c.points << " | " << c.open << " | " << c.against_mesh << " ("
                << c.reversed << ") | " << c.crossing_layers << " (" << c.ambiguous_nesting
                << ") | " << other << " | "
                << (have_boxes ? std::to_string(boxes.size()) : std::string("—")) << " | "
                << verdict << " | " << fmt("%.1f", seconds_since(t0)) << " |\n";
    }
    std::cout.flush();
  }
  return failures == 0 ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "stlrefine_contour_check: " << e.what() << '\n';
    return 1;
  }
}
