// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_spectral_speed: what the spectral masks cost (issue 5 item 7: at most 10% over
// the plain scheme). loop-g2 against loop and butterfly-g1 against butterfly on the shared
// meshes, single-threaded and on 2 threads: output triangles per second and peak RSS of
// refine() on the ingested mesh. Every child (bench/measure.h) runs one scheme: once cold
// (fresh process; its peak RSS) and then `--warm` times again, of which the fastest wall
// and CPU times count (other jobs on a shared machine can only slow a run down). The two
// schemes of a pair alternate (ABBA) so load falls on both alike; the ratios are medians
// over the repetitions of the ratio of each repetition's two-child sums.
//
// The masks are derived on first use per valence (spectral_stencil.h); the untimed warm-up
// derives both tables for every valence, so the rows are the steady state of a server. The
// one-time derivation is measured on its own (first table below).
//
// Markdown on stdout, progress on stderr. Hand-run, never a test (bench/RESULTS.md,
// "Spectral (Prautzsch-Umlauf)").

#include <sys/resource.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bench/jobs.h"
#include "bench/machine.h"
#include "bench/measure.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "core/schemes/butterfly_g1.h"
#include "core/schemes/loop_g2.h"
#include "core/schemes/scheme.h"

namespace fs = std::filesystem;
using namespace stlrefine;
using namespace stlrefine::bench;

namespace {

struct Case {
  std::string input;
  int levels;
};

struct Options {
  std::string mesh_dir = "/work/shared/meshes";
  std::vector<std::string> cases{"organic/bunny.stl:3",     "organic/armadillo.stl:3",
                                 "cad/fandisk.stl:4",       "organic/spot.stl:4",
                                 "generated/torus.stl:5",   "cad/tray_bottom.stl:4",
                                 "organic/bunny_low.stl:5", "large/dragon_full.stl.gz:2"};
  std::vector<std::string> pairs{"loop:loop-g2", "butterfly:butterfly-g1"};
  std::vector<int> threads{1, 2};
  int reps = 5;
  int warm = 5;
  int timeout = 900;
  std::string tmp_dir = "/tmp/stlrefine_bench";
};

// Derives every mask of both tables and refines a tiny mesh (thread pool, code pages).
class WarmUp final : public Job {
 public:
  explicit WarmUp(std::string scheme) : scheme_(std::move(scheme)) {}
  void run() override {
    for (int n = 3; n <= kSpectralMaxValence; ++n) {
      loop_g2_masks().at(n);
      butterfly_g1_masks().at(n);
    }
    IndexedSoup soup;
    soup.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    soup.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                      {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    RefineParams p;
    p.scheme = scheme_;
    p.levels = 2;
    faces_ = refine(build_mesh(soup).mesh, p).mesh.num_faces();
  }
  std::uint64_t in_faces() const override { return 8; }
  std::uint64_t out_faces() const override { return faces_; }
  std::uint64_t out_vertices() const override { return 0; }

 private:
  std::string scheme_;
  std::uint64_t faces_ = 0;
};

// Derives one table for every valence, in a fresh process: the one-time cost.
class Derive final : public Job {
 public:
  Derive(bool loop, int threads) : loop_(loop), arena_(threads) {}
  void run() override {
    // As SpectralStencil does for the valences a mesh has: side by side.
    std::atomic<int> changed{0};
    arena_.execute([&] {
      tbb::parallel_for(3, kSpectralMaxValence + 1, [&](int n) {
        changed += (loop_ ? loop_g2_masks() : butterfly_g1_masks()).at(n).empty() ? 0 : 1;
      });
    });
    count_ = changed;
  }
  std::uint64_t in_faces() const override { return 0; }
  std::uint64_t out_faces() const override { return count_; }
  std::uint64_t out_vertices() const override { return 0; }

 private:
  bool loop_;
  tbb::task_arena arena_;
  std::uint64_t count_ = 0;
};

fs::path unpacked(const Options& opt, const std::string& input) {
  const fs::path src = fs::path(opt.mesh_dir) / input;
  if (src.extension() != ".gz") return src;
  fs::create_directories(opt.tmp_dir);
  const fs::path dst = fs::path(opt.tmp_dir) / src.stem();
  if (!fs::exists(dst)) {
    const std::string cmd = "gunzip -c '" + src.string() + "' > '" + dst.string() + "'";
    if (std::system(cmd.c_str()) != 0) throw std::runtime_error("cannot unpack " + src.string());
  }
  return dst;
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "stlrefine_spectral_speed: loop-g2 vs loop and butterfly-g1 vs butterfly, triangles/s "
      "and peak RSS, forked runs in ABBA order. Markdown on stdout."};
  app.add_option("mesh_dir", opt.mesh_dir, "Directory of the test meshes");
  app.add_option("--cases", opt.cases, "FILE:LEVELS relative to mesh_dir");
  app.add_option("--pairs", opt.pairs, "PLAIN:MODIFIED scheme pairs");
  app.add_option("--threads", opt.threads)->check(CLI::Range(1, 256));
  app.add_option("--reps", opt.reps, "Repetitions (each pair runs ABBA per repetition)")
      ->check(CLI::Range(1, 100));
  app.add_option("--warm", opt.warm, "Warm reruns per child (the fastest counts)")
      ->check(CLI::Range(1, 100));
  app.add_option("--timeout", opt.timeout);
  app.add_option("--tmp-dir", opt.tmp_dir);
  CLI11_PARSE(app, argc, argv);

  std::cout << "Machine: " << load_averages() << " load at start (" << utc_now() << ")\n\n";
  // The one-time derivation.
  std::cout << "| table (valences 3.." << kSpectralMaxValence
            << ") | threads | derivation s (median of " << opt.reps << ") |\n|---|---|---|\n";
  for (bool loop : {true, false})
    for (int t : opt.threads) {
      std::vector<double> s;
      for (int r = 0; r < opt.reps; ++r) {
        const Outcome o = run_in_child(
            [&] {
              return measure_job([&] { return std::make_unique<Derive>(loop, t); }, nullptr, 0, 0,
                                 1);
            },
            opt.timeout);
        if (o.ok) s.push_back(o.sample.seconds);
      }
      std::cout << "| " << (loop ? "loop-g2" : "butterfly-g1") << " | " << t << " | "
                << fixed(median(s), 3) << " |\n";
    }
  std::cout << "\n| input | L | out tris | thr | plain cold s | modified cold s | cold ratio | "
               "plain warm min s | modified warm min s | **warm ratio** | warm CPU ratio | plain "
               "Mtri/s (warm) | modified Mtri/s (warm) | peak MB plain / modified | others busy "
               "|\n|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  for (const std::string& c : opt.cases) {
    const auto colon = c.rfind(':');
    const Case cs{c.substr(0, colon), std::stoi(c.substr(colon + 1))};
    const fs::path path = unpacked(opt, cs.input);
    for (int threads : opt.threads)
      for (const std::string& pair : opt.pairs) {
        const std::string plain = pair.substr(0, pair.find(':')),
                          modified = pair.substr(pair.find(':') + 1);
        // Per scheme, every child's result; per repetition, the ratios of the sums of its
        // two ABBA children.
        std::map<std::string, std::vector<Sample>> samples;
        std::vector<double> cold_ratios, warm_ratios, cpu_ratios, busy;
        for (int r = 0; r < opt.reps; ++r) {
          const std::vector<std::string> order =
              r % 2 == 0 ? std::vector<std::string>{plain, modified, modified, plain}
                         : std::vector<std::string>{modified, plain, plain, modified};
          std::map<std::string, std::vector<Sample>> rep;
          for (const std::string& scheme : order) {
            std::cerr << cs.input << " L" << cs.levels << " t" << threads << " " << scheme
                      << " rep " << r << "\n";
            const JobFactory job = ours_refine_job(path, scheme, cs.levels, threads, 35);
            const Outcome o = run_in_child(
                [&] {
                  Sample s = measure_job(
                      job, [&] { return std::make_unique<WarmUp>(scheme); }, 0, 0, 1);
                  // Warm: the same refinement again in this process, fastest of `warm`
                  // runs (wall and process CPU), which load from other jobs can only slow.
                  const auto again = job();
                  s.warm_seconds = s.cpu_seconds = 1e300;
                  for (int i = 0; i < opt.warm; ++i) {
                    rusage u0, u1;
                    getrusage(RUSAGE_SELF, &u0);
                    const double t0 = now_seconds();
                    again->run();
                    const double wall = now_seconds() - t0;
                    getrusage(RUSAGE_SELF, &u1);
                    auto secs = [](const timeval& t) { return t.tv_sec + t.tv_usec * 1e-6; };
                    const double cpu = secs(u1.ru_utime) - secs(u0.ru_utime) + secs(u1.ru_stime) -
                                       secs(u0.ru_stime);
                    s.warm_seconds = std::min(s.warm_seconds, wall);
                    s.cpu_seconds = std::min(s.cpu_seconds, cpu);
                  }
                  s.warm_runs = opt.warm;
                  return s;
                },
                opt.timeout);
            if (!o.ok) {
              std::cerr << "  failed: " << o.failure << "\n";
              continue;
            }
            rep[scheme].push_back(o.sample);
            busy.push_back(o.others_busy);
          }
          if (rep[plain].size() == 2 && rep[modified].size() == 2) {
            auto sum = [&](const std::string& scheme, double Sample::*field) {
              return rep[scheme][0].*field + rep[scheme][1].*field;
            };
            cold_ratios.push_back(sum(modified, &Sample::seconds) / sum(plain, &Sample::seconds));
            warm_ratios.push_back(sum(modified, &Sample::warm_seconds) /
                                  sum(plain, &Sample::warm_seconds));
            cpu_ratios.push_back(sum(modified, &Sample::cpu_seconds) /
                                 sum(plain, &Sample::cpu_seconds));
          }
          for (auto& [scheme, v] : rep)
            samples[scheme].insert(samples[scheme].end(), v.begin(), v.end());
        }
        auto med = [&](const std::string& scheme, auto field) {
          std::vector<double> v;
          for (const Sample& x : samples[scheme]) v.push_back(double(x.*field));
          return median(v);
        };
        const double faces = samples[plain].empty() ? 0 : double(samples[plain].front().out_faces);
        const double wp = med(plain, &Sample::warm_seconds),
                     wm = med(modified, &Sample::warm_seconds);
        std::cout << "| " << cs.input << " | " << cs.levels << " | " << fixed(faces / 1e6, 2)
                  << " M | " << threads << " | " << plain << " "
                  << fixed(med(plain, &Sample::seconds), 3) << " | " << modified << " "
                  << fixed(med(modified, &Sample::seconds), 3) << " | "
                  << fixed(median(cold_ratios), 3) << " | " << fixed(wp, 3) << " | " << fixed(wm, 3)
                  << " | **" << fixed(median(warm_ratios), 3) << "** | "
                  << fixed(median(cpu_ratios), 3) << " | " << fixed(faces / wp / 1e6, 2) << " | "
                  << fixed(faces / wm / 1e6, 2) << " | "
                  << fixed(med(plain, &Sample::peak_kb) / 1024, 0) << " / "
                  << fixed(med(modified, &Sample::peak_kb) / 1024, 0) << " | "
                  << fixed(100 * median(busy), 0) << "% |\n"
                  << std::flush;
      }
  }
  std::cout << "\nMachine: " << load_averages() << " load at the end (" << utc_now() << ")\n";
  return 0;
}
