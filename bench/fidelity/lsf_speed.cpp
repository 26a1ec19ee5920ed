// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_lsf_speed: warm, in-process timing of refine() for a few schemes on one STL
// file (issue 4 item 7, "LSF speed" in bench/RESULTS.md). Each scheme refines the same
// ingested mesh `--reps` times per round; reported is the minimum over `--rounds` of the
// round's median process CPU time and wall time, so other jobs on a shared machine disturb
// the figures less than a single cold run. Also prints a hash of every output coordinate
// (bit-identity checks between builds) and the output face count. With --stencil-only it
// times only the 1-to-4 stencil's points() (LSF's fits, butterfly's masks) on every level
// but the last, without the host around it. Hand-run, never a test.
#include <tbb/task_arena.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "core/schemes/lsf.h"
#include "core/schemes/split4_host.h"

namespace {

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::uint64_t hash_positions(const stlrefine::Mesh& mesh) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the coordinate bytes
  for (const stlrefine::Vec3& p : mesh.positions()) {
    for (double x : {p.x, p.y, p.z}) {
      std::uint64_t bits;
      std::memcpy(&bits, &x, sizeof bits);
      for (int i = 0; i < 8; ++i) h = (h ^ ((bits >> (8 * i)) & 0xff)) * 1099511628211ull;
    }
  }
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stlrefine_lsf_speed: warm refine() timing per scheme"};
  std::string input;
  std::vector<std::string> schemes = {"butterfly", "lsf"};
  int levels = 2, threads = 1, reps = 5, rounds = 3;
  double adaptive_tol = 0;
  bool no_hash = false, stencil_only = false, use_min = false, baseline_kernels = false;
  app.add_option("input", input, "STL file")->required();
  app.add_option("--schemes", schemes, "schemes to time");
  app.add_option("--levels", levels, "uniform levels (the cap in the adaptive mode)");
  app.add_option("--threads", threads, "RefineParams::threads (0 = every core)");
  app.add_option("--reps", reps, "refinements per round");
  app.add_option("--rounds", rounds, "rounds; the minimum of the round medians is reported");
  app.add_option("--adaptive-tol", adaptive_tol, "adaptive mode with this tolerance (mm)");
  app.add_flag("--no-hash", no_hash, "skip the output hash (cleaner instruction counts)");
  app.add_flag("--min", use_min,
               "report the fastest run instead of the minimum of the round medians (a "
               "loaded machine only ever slows a run down)");
  app.add_flag("--baseline-kernels", baseline_kernels,
               "LSF's batch fits on the portable SSE2 kernel even where the CPU has AVX2 "
               "(with --stencil-only: refine() builds its schemes by name)");
  app.add_flag("--stencil-only", stencil_only,
               "time the split4 stencil's points() on levels 0..levels-1 only (uniform)");
  CLI11_PARSE(app, argc, argv);
  if (baseline_kernels && !stencil_only) {
    std::fprintf(stderr, "--baseline-kernels needs --stencil-only\n");
    return 1;
  }
  // --baseline-kernels: lsf's stencil with the baseline kernel (stlrefine::LsfKernel).
  const stlrefine::LsfStencil lsf_baseline(stlrefine::LsfKernel::Baseline);

  const stlrefine::IngestResult ingest =
      stlrefine::build_mesh(stlrefine::weld(stlrefine::read_stl_file(input)));
  struct Row {
    stlrefine::RefineParams params;
    double best_cpu = 1e300, best_wall = 1e300;
    std::size_t faces = 0;
    std::uint64_t hash = 0;
  };
  std::vector<Row> rows;
  // --stencil-only: the levels each scheme refines, made once; hash = the stencil's points.
  std::vector<std::vector<stlrefine::Level>> levels_of;
  for (const std::string& scheme : schemes) {
    Row row;
    row.params.scheme = scheme;
    row.params.levels = levels;
    row.params.threads = threads;
    row.params.max_faces = (std::uint64_t(1) << 31) - 1;
    row.params.adaptive_tol = adaptive_tol;
    row.params.max_level = levels;
    stlrefine::refine(ingest.mesh, row.params);  // warm-up: page faults, TBB pool
    rows.push_back(row);
    if (!stencil_only) continue;
    const auto made = stlrefine::make_scheme(scheme, row.params.scheme_options);
    const auto* split4 =
        dynamic_cast<const stlrefine::HostScheme<stlrefine::Split4Stencil>*>(made.get());
    if (!split4) {
      std::fprintf(stderr, "--stencil-only: %s is not a 1-to-4 scheme\n", scheme.c_str());
      return 1;
    }
    std::vector<stlrefine::Level> chain;
    chain.push_back({stlrefine::Mesh(ingest.mesh),
                     stlrefine::detect_features(ingest.mesh, row.params.features)});
    stlrefine::StepStats stats;
    for (int l = 1; l < levels; ++l) chain.push_back(split4->refine_once(chain.back(), stats));
    levels_of.push_back(std::move(chain));
  }
  // One stencil pass over every level but the last; returns the face count it leads to.
  auto run_stencil = [&](std::size_t i, std::uint64_t* hash) {
    const auto made = stlrefine::make_scheme(rows[i].params.scheme);
    const stlrefine::Split4Stencil& stencil =
        baseline_kernels && rows[i].params.scheme == "lsf"
            ? lsf_baseline
            : dynamic_cast<const stlrefine::HostScheme<stlrefine::Split4Stencil>&>(*made).stencil();
    std::size_t faces = 0;
    std::uint64_t h = 1469598103934665603ull;
    for (const stlrefine::Level& level : levels_of[i]) {
      const stlrefine::Mesh& m = level.mesh;
      stlrefine::BigVector<stlrefine::Vec3> points(m.num_vertices() + m.num_edges());
      const stlrefine::IrregularVertices irregular = stencil.uses_irregular()
                                                         ? stlrefine::irregular_vertices(level)
                                                         : stlrefine::IrregularVertices{};
      stencil.points(level, irregular, std::span<stlrefine::Vec3>(points.data(), m.num_vertices()),
                     std::span<stlrefine::Vec3>(points.data() + m.num_vertices(), m.num_edges()));
      faces = 4 * m.num_faces();
      if (hash) {
        for (const stlrefine::Vec3& p : points) {
          for (double x : {p.x, p.y, p.z}) {
            std::uint64_t bits;
            std::memcpy(&bits, &x, sizeof bits);
            for (int b = 0; b < 8; ++b) h = (h ^ ((bits >> (8 * b)) & 0xff)) * 1099511628211ull;
          }
        }
      }
    }
    if (hash) *hash = h;
    return faces;
  };
  // Only for --stencil-only (refine() makes its own arena).
  std::optional<tbb::task_arena> arena;
  const int concurrency = threads > 0 ? threads : int{tbb::task_arena::automatic};
  if (stencil_only) arena.emplace(concurrency);
  // Rounds interleave the schemes, so a change of load hits all of them alike.
  for (int r = 0; r < rounds; ++r) {
    for (std::size_t k = 0; k < rows.size(); ++k) {
      Row& row = rows[k];
      std::vector<double> cpu, wall;
      for (int i = 0; i < reps; ++i) {
        const double c0 = cpu_seconds();
        const auto w0 = std::chrono::steady_clock::now();
        // The result is freed after the clocks stop (as the refine's caller would, later):
        // freeing the output mesh is as costly as a quarter of a small refine here.
        std::optional<stlrefine::RefineResult> result;
        if (stencil_only)
          row.faces = arena->execute([&] { return run_stencil(k, nullptr); });
        else
          result = stlrefine::refine(ingest.mesh, row.params);
        wall.push_back(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count());
        cpu.push_back(cpu_seconds() - c0);
        if (result) {
          row.faces = result->mesh.num_faces();
          if (!no_hash) row.hash = hash_positions(result->mesh);
        }
      }
      const auto pick = [&](const std::vector<double>& v) {
        return use_min ? *std::min_element(v.begin(), v.end()) : median(v);
      };
      row.best_cpu = std::min(row.best_cpu, pick(cpu));
      row.best_wall = std::min(row.best_wall, pick(wall));
    }
  }
  if (stencil_only && !no_hash)
    for (std::size_t k = 0; k < rows.size(); ++k)
      arena->execute([&] { run_stencil(k, &rows[k].hash); });
  std::printf(
      "| scheme | levels | threads | out faces | CPU s | wall s | CPU / first | wall / first | "
      "hash |\n");
  std::printf("|---|--:|--:|--:|--:|--:|--:|--:|---|\n");
  for (const Row& row : rows) {
    std::printf("| %s | %d | %d | %zu | %.4f | %.4f | %.2f | %.2f | %016llx |\n",
                row.params.scheme.c_str(), levels, threads, row.faces, row.best_cpu, row.best_wall,
                row.best_cpu / rows.front().best_cpu, row.best_wall / rows.front().best_wall,
                static_cast<unsigned long long>(row.hash));
  }
  return 0;
}
