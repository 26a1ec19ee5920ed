// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_bench: our subdivision schemes and STL reader beside the peers a user would
// pick instead (CGAL Loop and Sqrt3, OpenMesh LoopT, ModifiedButterflyT, Sqrt3T and
// InterpolatingSqrt3LGT, CGAL and OpenMesh STL readers), on the same inputs, in one run. Prints
// Markdown to stdout, progress to stderr. Hand-run (see bench/README.md); never a ctest test.
//
// Each (input, algorithm, level, threads, repetition) runs in its own forked child that
// loads the input, converts it, measures its baseline RSS, resets the peak and runs once
// (short cases then rerun until --min-time has passed). The parent never touches TBB.

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bench/jobs.h"
#include "bench/machine.h"
#include "bench/measure.h"

namespace stlrefine::bench {
namespace {

namespace fs = std::filesystem;

struct Options {
  fs::path mesh_dir = "/work/shared/meshes";
  std::vector<std::string> inputs = {"cad/fandisk.stl",       "organic/bunny.stl",
                                     "organic/armadillo.stl", "generated/sphere_fn16.stl",
                                     "cad/tray_bottom.stl",   "large/dragon_full.stl.gz"};
  std::vector<int> levels = {1, 2, 3};
  std::vector<std::string> schemes = {"loop", "butterfly"};
  std::vector<std::string> peers = {"cgal-loop", "openmesh-loop", "openmesh-butterfly"};
  std::vector<int> threads = {1, 2};
  int reps = 3;
  double min_time = 0.5;
  int max_runs = 20;
  double max_out_tris = 60e6;
  double max_mem_gb = 8;
  int timeout = 1800;
  double crease_angle = 35;
  bool no_read = false, no_refine = false, no_pipeline = false;
  bool no_prefault = false;
  double idle = 0.85;
  int idle_wait = 180;
  fs::path tmp_dir = "/tmp/stlrefine_bench";
  std::vector<fs::path> warmup_meshes;  //!< written into tmp_dir at start
  //! Also warm up on this mesh (relative to mesh_dir), after the built-in ones.
  std::string warmup_extra;
};

//! Runs several warm-up jobs in turn (only run() is used).
class WarmUpSequence final : public Job {
 public:
  explicit WarmUpSequence(std::vector<std::unique_ptr<Job>> jobs) : jobs_(std::move(jobs)) {}
  void run() override {
    for (const auto& job : jobs_) job->run();
  }
  std::uint64_t in_faces() const override { return 0; }
  std::uint64_t out_faces() const override { return 0; }
  std::uint64_t out_vertices() const override { return 0; }

 private:
  std::vector<std::unique_ptr<Job>> jobs_;
};

// ------------------------------------------------------------------------- formatting

std::string group(std::uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::string fixed(double x, int precision) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", precision, x);
  return text;
}

//! Three significant digits, for rates and ratios spanning orders of magnitude.
std::string sig3(double x) {
  if (!std::isfinite(x)) return "—";
  const double a = std::fabs(x);
  if (a > 0 && a < 0.1) {
    char text[64];
    std::snprintf(text, sizeof(text), "%.2g", x);
    return text;
  }
  return fixed(x, a >= 100 ? 0 : a >= 10 ? 1 : a >= 1 ? 2 : 3);
}

std::string mib(long kb) {
  return fixed(double(kb) / 1024.0, 1);
}

std::string cell(std::string text) {
  for (char& c : text) {
    if (c == '|' || c == '\n') c = ' ';
  }
  return text;
}

std::string percent(double fraction) {
  return fraction < 0 ? "—" : std::to_string(int(std::lround(fraction * 100))) + "%";
}

std::uint64_t stl_bytes(std::uint64_t faces) {
  return 84 + 50 * faces;
}

// ------------------------------------------------------------------------- results

struct Aggregate {
  bool ok = false;
  std::string failure;
  std::vector<double> seconds;       //!< cold run of each repetition
  std::vector<double> warm_seconds;  //!< median rerun of each repetition that had reruns
  Sample first;                      //!< sample of the first repetition (counts, notes)
  long peak_kb = 0, base_kb = 0;
  double cpu_ratio = 0;
  double others_busy = 0;  //!< most CPU share other processes took during a repetition
  bool peak_reset = true;

  double median_s() const { return median(seconds); }
  bool has_warm() const { return !warm_seconds.empty(); }
  double warm_median_s() const { return median(warm_seconds); }
  double min_s() const { return *std::min_element(seconds.begin(), seconds.end()); }
  double max_s() const { return *std::max_element(seconds.begin(), seconds.end()); }
};

void add_outcome(Aggregate& agg, const Outcome& outcome) {
  agg.others_busy = std::max(agg.others_busy, outcome.others_busy);
  if (!outcome.ok) {
    if (agg.failure.empty()) agg.failure = outcome.failure;
    agg.ok = false;
    return;
  }
  const Sample& s = outcome.sample;
  if (agg.seconds.empty()) {
    agg.first = s;
    agg.ok = true;
  }
  agg.seconds.push_back(s.seconds);
  if (s.warm_runs > 0) agg.warm_seconds.push_back(s.warm_seconds);
  agg.peak_reset = agg.peak_reset && s.peak_reset;
  if (s.peak_kb > agg.peak_kb) {
    agg.peak_kb = s.peak_kb;
    agg.base_kb = s.base_kb;
  }
  const double ratio = s.seconds > 0 ? s.cpu_seconds / s.seconds : 0;
  agg.cpu_ratio = std::max(agg.cpu_ratio, ratio);
}

enum class Family { Loop, Butterfly, Sqrt3, Pipeline };

//! Faces per face and level: 3 for the sqrt3 family (ours and the peers), 4 otherwise.
int growth_of(const std::string& key) {
  return key.find("sqrt3") != std::string::npos ? 3 : 4;
}

std::uint64_t faces_after(std::uint64_t faces, const std::string& key, int level) {
  for (int i = 0; i < level; ++i) faces *= std::uint64_t(growth_of(key));
  return faces;
}

//! Makes the job for a given STL file: the real input, or the tiny warm-up mesh.
using Maker = std::function<JobFactory(const fs::path&)>;

struct RefineCase {
  std::string key;    //!< stable id: "ours-loop", "cgal-loop", "pipeline-butterfly", ...
  std::string label;  //!< shown in the table
  Family family;
  bool ours = false;
  int threads = 1;
  int level = 0;
  Maker maker;
  bool skipped = false;
  std::string skip_reason;
  double predicted_growth_kb = 0;  //!< expected peak - base (for prefaulting)
  Aggregate result;
};

struct ReadCase {
  std::string label, source;
  Maker maker;
  Aggregate result;
};

struct InputResult {
  std::string name;
  fs::path path;
  std::uint64_t file_bytes = 0;
  bool ingest_ok = false;
  std::string ingest_failure;
  Sample info;
  std::string load_before, load_after;
  std::vector<ReadCase> reads;
  std::vector<RefineCase> refines;
};

// ------------------------------------------------------------------------- inputs

//! Resolves an input name to a plain binary STL on disk; .gz files are unpacked with
//! gunzip into tmp_dir once (kept for later runs). Empty path when missing.
fs::path resolve_input(const Options& opt, const std::string& name, std::string& why) {
  const fs::path source = opt.mesh_dir / name;
  if (!fs::exists(source)) {
    why = "not found: " + source.string();
    return {};
  }
  if (source.extension() != ".gz") return source;
  fs::create_directories(opt.tmp_dir);
  const fs::path target = opt.tmp_dir / source.stem();
  const auto plausible = [&] {
    if (!fs::exists(target)) return false;
    const auto size = fs::file_size(target);
    std::ifstream in(target, std::ios::binary);
    char header[84];
    if (size < 84 || !in.read(header, 84)) return false;
    std::uint32_t count = 0;
    std::copy(header + 80, header + 84, reinterpret_cast<char*>(&count));
    return size == 84 + 50ull * count;
  };
  if (!plausible()) {
    std::cerr << "unpacking " << source << " -> " << target << '\n';
    const std::string tmp = target.string() + ".part";
    const std::string command = "gunzip -c '" + source.string() + "' > '" + tmp + "'";
    if (std::system(command.c_str()) != 0) {
      why = "gunzip failed: " + command;
      return {};
    }
    fs::rename(tmp, target);
    if (!plausible()) {
      why = "unpacked file is not a binary STL: " + target.string();
      return {};
    }
  }
  return target;
}

//! Writes triangles as binary STL (normals zero: every reader recomputes them).
void write_binary_stl(const fs::path& path, const std::vector<std::array<float, 3>>& vertices,
                      const std::vector<std::array<int, 3>>& faces) {
  std::string bytes(80, ' ');
  bytes.replace(0, 22, "stlrefine_bench warmup");
  const auto put = [&](const void* data, std::size_t n) {
    bytes.append(static_cast<const char*>(data), n);
  };
  const auto count = std::uint32_t(faces.size());
  put(&count, 4);
  for (const auto& face : faces) {
    const float normal[3] = {0, 0, 0};
    put(normal, sizeof(normal));
    for (const int corner : face) put(vertices[std::size_t(corner)].data(), 12);
    const std::uint16_t attributes = 0;
    put(&attributes, 2);
  }
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

//! The warm-up meshes: every job runs on each once, untimed, before its measured run, so
//! thread pools, code pages, lazy symbols and the allocator's first memory are not timed.
//! A closed octahedron (8 facets, every edge sharp at 35°: our crease paths) and a smooth
//! torus (576 facets, dihedral angles 15° and 30°: our smooth-vertex paths, and arrays
//! large enough for the array pool's first slab). The same for ours and the peers.
std::vector<fs::path> write_warmup_meshes(const fs::path& dir) {
  fs::create_directories(dir);
  const fs::path octahedron = dir / "warmup_octahedron.stl";
  write_binary_stl(
      octahedron, {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}},
      {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}});
  constexpr int kAround = 24, kTube = 12;
  constexpr double kMajor = 2.0, kMinor = 0.7;
  std::vector<std::array<float, 3>> vertices;
  for (int i = 0; i < kAround; ++i) {
    for (int j = 0; j < kTube; ++j) {
      const double theta = 2 * M_PI * i / kAround, phi = 2 * M_PI * j / kTube;
      const double ring = kMajor + kMinor * std::cos(phi);
      vertices.push_back({float(ring * std::cos(theta)), float(ring * std::sin(theta)),
                          float(kMinor * std::sin(phi))});
    }
  }
  const auto at = [](int i, int j) { return (i % kAround) * kTube + j % kTube; };
  std::vector<std::array<int, 3>> faces;  // counter-clockwise seen from outside
  for (int i = 0; i < kAround; ++i) {
    for (int j = 0; j < kTube; ++j) {
      faces.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      faces.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  const fs::path torus = dir / "warmup_torus.stl";
  write_binary_stl(torus, vertices, faces);
  return {octahedron, torus};
}

//! Reads the whole file once so every reader below starts from a warm page cache.
void warm_page_cache(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buffer(1 << 20);
  while (in.read(buffer.data(), std::streamsize(buffer.size())) || in.gcount() > 0) {
  }
}

//! Before each measured process: waits (up to --idle-wait s) until the CPUs were at least
//! --idle idle over one second, so other users' work does not land in our timings.
//! Returns the last idle fraction seen.
double wait_until_idle(const Options& opt) {
  if (opt.idle <= 0) return -1;
  const double start = now_seconds();
  double idle = cpu_idle_fraction(1.0);
  while (idle >= 0 && idle < opt.idle && now_seconds() - start < opt.idle_wait) {
    idle = cpu_idle_fraction(2.0);
  }
  return idle;
}

// ------------------------------------------------------------------------- cases

std::string peer_label(const std::string& key) {
  if (key == "cgal-loop") return "CGAL Loop_subdivision";
  if (key == "openmesh-loop") return "OpenMesh LoopT";
  if (key == "openmesh-butterfly") return "OpenMesh ModifiedButterflyT";
  if (key == "cgal-sqrt3") return "CGAL Sqrt3_subdivision";
  if (key == "openmesh-sqrt3") return "OpenMesh Sqrt3T";
  if (key == "openmesh-sqrt3-lg") return "OpenMesh InterpolatingSqrt3LGT";
  return key;
}

std::vector<RefineCase> make_refine_cases(const Options& opt, int level) {
  std::vector<RefineCase> cases;
  const auto add_ours = [&](const std::string& scheme, Family family) {
    for (const int t : opt.threads) {
      RefineCase c;
      c.key = "ours-" + scheme;
      c.label = "**ours " + scheme + "**";
      c.family = family;
      c.ours = true;
      c.threads = t;
      c.level = level;
      const double crease = opt.crease_angle;
      c.maker = [=](const fs::path& path) {
        return ours_refine_job(path, scheme, level, t, crease);
      };
      cases.push_back(std::move(c));
    }
  };
  const auto add_peer = [&](const std::string& key, Family family) {
    if (std::find(opt.peers.begin(), opt.peers.end(), key) == opt.peers.end()) return;
    if (key.rfind("openmesh", 0) == 0 && !have_openmesh()) return;
    RefineCase c;
    c.key = key;
    c.label = peer_label(key);
    c.family = family;
    c.level = level;
    c.maker = [key, level](const fs::path& path) {
      return key == "cgal-loop"           ? cgal_loop_job(path, level)
             : key == "openmesh-loop"     ? openmesh_loop_job(path, level)
             : key == "cgal-sqrt3"        ? cgal_sqrt3_job(path, level)
             : key == "openmesh-sqrt3"    ? openmesh_sqrt3_job(path, level)
             : key == "openmesh-sqrt3-lg" ? openmesh_sqrt3_lg_job(path, level)
                                          : openmesh_butterfly_job(path, level);
    };
    cases.push_back(std::move(c));
  };
  const bool loop = std::count(opt.schemes.begin(), opt.schemes.end(), "loop") > 0;
  const bool butterfly = std::count(opt.schemes.begin(), opt.schemes.end(), "butterfly") > 0;
  if (loop) add_ours("loop", Family::Loop);
  add_peer("cgal-loop", Family::Loop);
  add_peer("openmesh-loop", Family::Loop);
  if (butterfly) add_ours("butterfly", Family::Butterfly);
  add_peer("openmesh-butterfly", Family::Butterfly);
  const auto wanted = [&](const char* scheme) {
    return std::count(opt.schemes.begin(), opt.schemes.end(), scheme) > 0;
  };
  if (wanted("sqrt3")) add_ours("sqrt3", Family::Sqrt3);
  add_peer("cgal-sqrt3", Family::Sqrt3);
  add_peer("openmesh-sqrt3", Family::Sqrt3);
  if (wanted("sqrt3-interp")) add_ours("sqrt3-interp", Family::Sqrt3);
  add_peer("openmesh-sqrt3-lg", Family::Sqrt3);
  if (wanted("sqrt3-unified")) add_ours("sqrt3-unified", Family::Sqrt3);
  // Other schemes of ours (not compared with a peer).
  for (const std::string& scheme : opt.schemes) {
    if (scheme != "loop" && scheme != "butterfly" && scheme.rfind("sqrt3", 0) != 0)
      add_ours(scheme, Family::Butterfly);
  }
  if (!opt.no_pipeline) {
    for (const std::string& scheme : opt.schemes) {
      RefineCase c;
      c.key = "pipeline-" + scheme;
      c.label = "ours " + scheme + ", whole request";
      c.family = Family::Pipeline;
      c.ours = true;
      c.threads = 1;
      c.level = level;
      const double crease = opt.crease_angle;
      c.maker = [=](const fs::path& path) {
        return ours_pipeline_job(path, scheme, level, 1, crease);
      };
      cases.push_back(std::move(c));
    }
  }
  return cases;
}

std::string case_id(const RefineCase& c) {
  return c.key + "/t" + std::to_string(c.threads);
}

//! Decides whether a case would be too big, from the face count and from the previous
//! level's measured peak of the same case (4x its growth over the baseline).
void decide_skip(const Options& opt, RefineCase& c, std::uint64_t in_faces,
                 const std::map<std::string, RefineCase>& previous) {
  const double out = double(in_faces) * std::pow(double(growth_of(c.key)), c.level);
  if (out > opt.max_out_tris) {
    c.skipped = true;
    c.skip_reason =
        "output " + fixed(out / 1e6, 1) + " M tris > " + fixed(opt.max_out_tris / 1e6, 0) + " M";
    return;
  }
  const auto it = previous.find(case_id(c));
  double predicted_kb = out * 200.0 / 1024.0;  // no history: assume 200 B per output tri
  c.predicted_growth_kb = predicted_kb;
  std::string basis = "200 B per output triangle";
  if (it != previous.end()) {
    const RefineCase& p = it->second;
    if (p.skipped) {
      c.skipped = true;
      c.skip_reason = "level " + std::to_string(p.level) + " skipped";
      return;
    }
    if (!p.result.ok) {
      c.skipped = true;
      c.skip_reason = "failed at level " + std::to_string(p.level);
      return;
    }
    c.predicted_growth_kb = 4.0 * double(p.result.peak_kb - p.result.base_kb);
    predicted_kb = double(p.result.base_kb) + c.predicted_growth_kb;
    basis = "4x the level-" + std::to_string(p.level) + " growth";
  }
  const double limit_kb = opt.max_mem_gb * 1024 * 1024;
  const double available_kb = 0.8 * double(mem_available_kb());
  if (predicted_kb > limit_kb) {
    c.skipped = true;
    c.skip_reason = "predicted peak " + fixed(predicted_kb / 1048576.0, 1) + " GiB (" + basis +
                    ") > " + fixed(opt.max_mem_gb, 0) + " GiB";
  } else if (available_kb > 0 && predicted_kb > available_kb) {
    c.skipped = true;
    c.skip_reason = "predicted peak " + fixed(predicted_kb / 1048576.0, 1) +
                    " GiB > 80% of the memory available now";
  }
}

//! One repetition of one case: waits for idle CPUs, runs it in a child, records it.
Outcome measure_case(const Options& opt, const Maker& maker, const fs::path& path, double growth_kb,
                     Aggregate& result) {
  std::size_t prefault = 0;
  if (!opt.no_prefault) {
    const double cap_kb = 0.5 * double(std::max(0L, mem_available_kb()));
    prefault = std::size_t(std::min(1.1 * growth_kb, cap_kb) * 1024.0);
  }
  wait_until_idle(opt);
  const Outcome outcome = run_in_child(
      [&] {
        std::vector<JobFactory> warm_ups;
        for (const fs::path& mesh : opt.warmup_meshes) warm_ups.push_back(maker(mesh));
        if (!opt.warmup_extra.empty()) warm_ups.push_back(maker(opt.mesh_dir / opt.warmup_extra));
        const JobFactory warm_up = [warm_ups] {
          std::vector<std::unique_ptr<Job>> jobs;
          for (const JobFactory& make : warm_ups) jobs.push_back(make());
          return std::unique_ptr<Job>(std::make_unique<WarmUpSequence>(std::move(jobs)));
        };
        return measure_job(maker(path), warm_up, prefault, opt.min_time, opt.max_runs);
      },
      opt.timeout);
  add_outcome(result, outcome);
  return outcome;
}

void run_reads(const Options& opt, InputResult& input) {
  const auto ours = [](OurRead variant) {
    return [variant](const fs::path& path) { return ours_read_job(path, variant); };
  };
  const auto add = [&](const char* label, const char* source, Maker maker) {
    input.reads.push_back({label, source, std::move(maker), {}});
  };
  add("ours read_stl + weld", "memory buffer", ours(OurRead::Buffer));
  add("ours read_stl_file + weld", "file", ours(OurRead::File));
  add("ours read_stl_file + weld + build_mesh", "file", ours(OurRead::FileAndBuild));
  add("CGAL IO::read_STL (soup)", "file", cgal_read_soup_job);
  add("CGAL IO::read_polygon_mesh (Surface_mesh)", "file", cgal_read_mesh_job);
  add("CGAL PMP::IO::read_polygon_mesh (repair + orient)", "file", cgal_read_mesh_repair_job);
  if (have_openmesh()) add("OpenMesh IO::read_mesh (TriMesh)", "file", openmesh_read_job);
  warm_page_cache(input.path);
  for (int rep = 0; rep < opt.reps; ++rep) {
    for (ReadCase& c : input.reads) {
      if (rep > 0 && !c.result.ok) continue;
      const double growth_kb = std::max(65536.0, 12.0 * double(input.file_bytes) / 1024.0);
      const Outcome outcome = measure_case(opt, c.maker, input.path, growth_kb, c.result);
      std::cerr << "  [" << input.name << "] read " << c.label << " rep " << rep + 1 << '/'
                << opt.reps << ": "
                << (outcome.ok ? fixed(outcome.sample.seconds, 4) + " s" : outcome.failure) << '\n';
    }
  }
}

void run_refines(const Options& opt, InputResult& input) {
  std::map<std::string, RefineCase> previous;  // the same case one level down
  std::vector<int> levels = opt.levels;
  std::sort(levels.begin(), levels.end());
  for (const int level : levels) {
    const std::size_t begin = input.refines.size();
    for (RefineCase& c : make_refine_cases(opt, level)) {
      decide_skip(opt, c, input.info.out_faces, previous);
      input.refines.push_back(std::move(c));
    }
    // Repetitions round-robin over the cases, so a drift in machine load hits all alike.
    for (int rep = 0; rep < opt.reps; ++rep) {
      for (std::size_t i = begin; i < input.refines.size(); ++i) {
        RefineCase& c = input.refines[i];
        if (c.skipped || (rep > 0 && !c.result.ok)) continue;
        const Outcome outcome =
            measure_case(opt, c.maker, input.path, c.predicted_growth_kb, c.result);
        std::cerr << "  [" << input.name << " L" << level << "] " << c.label << " t" << c.threads
                  << " rep " << rep + 1 << '/' << opt.reps << ": "
                  << (outcome.ok ? fixed(outcome.sample.seconds, 4) + " s, peak " +
                                       mib(outcome.sample.peak_kb) + " MiB"
                                 : outcome.failure)
                  << '\n';
      }
    }
    for (std::size_t i = begin; i < input.refines.size(); ++i) {
      previous[case_id(input.refines[i])] = input.refines[i];
    }
  }
}

// ------------------------------------------------------------------------- tables

//! Output triangles per second of the cold runs (median), NAN when failed.
double rate(const RefineCase& c) {
  if (c.skipped || !c.result.ok) return NAN;
  return double(c.result.first.out_faces) / c.result.median_s();
}
//! Same for the warm reruns, NAN when there were none.
double warm_rate(const RefineCase& c) {
  if (c.skipped || !c.result.ok || !c.result.has_warm()) return NAN;
  return double(c.result.first.out_faces) / c.result.warm_median_s();
}

const RefineCase* find_case(const InputResult& input, const std::string& key, int level,
                            int threads) {
  for (const RefineCase& c : input.refines) {
    if (c.key == key && c.level == level && c.threads == threads) return &c;
  }
  return nullptr;
}

//! The peers a case of ours is judged against (single-threaded), with short names.
std::vector<std::pair<std::string, std::string>> peers_of(const std::string& key) {
  if (key == "ours-loop") return {{"cgal-loop", "CGAL"}, {"openmesh-loop", "OM"}};
  if (key == "ours-butterfly") return {{"openmesh-butterfly", "OM"}};
  if (key == "ours-sqrt3") return {{"cgal-sqrt3", "CGAL"}, {"openmesh-sqrt3", "OM"}};
  if (key == "ours-sqrt3-interp" || key == "ours-sqrt3-unified")
    return {{"openmesh-sqrt3-lg", "OM LG"}, {"openmesh-sqrt3", "OM Sqrt3T"}};
  return {};
}

//! "2.13× CGAL (warm 0.52×)": cold ratio, and the warm one when both have reruns.
std::string ratio_text(const RefineCase& ours, const RefineCase& peer) {
  std::string text = sig3(rate(ours) / rate(peer)) + "×";
  const double warm = warm_rate(ours) / warm_rate(peer);
  if (std::isfinite(warm)) text += " (warm " + sig3(warm) + "×)";
  return text;
}

std::string speedup_text(const InputResult& input, const RefineCase& c) {
  if (!c.ours || c.family == Family::Pipeline || !c.result.ok) return "";
  std::string text;
  for (const auto& [key, name] : peers_of(c.key)) {
    const RefineCase* peer = find_case(input, key, c.level, 1);
    if (peer == nullptr || peer->skipped || !peer->result.ok) continue;
    text += (text.empty() ? "" : ", ") + ratio_text(c, *peer) + " " + name;
  }
  return text;
}

double rss_ratio(const InputResult& input, const RefineCase& c) {
  return double(c.result.peak_kb) * 1024.0 /
         double(input.file_bytes + stl_bytes(c.result.first.out_faces));
}

void print_input(std::ostream& out, const InputResult& input, const Options& opt) {
  out << "\n### " << input.name << "\n\n";
  out << group(input.file_bytes) << " bytes, " << group((input.file_bytes - 84) / 50)
      << " facets in the file";
  if (!input.ingest_ok) {
    out << ". **Our ingest failed: " << input.ingest_failure
        << "** (nothing else measured: the peers get our ingested mesh).\n";
    return;
  }
  out << "; after our ingest: " << group(input.info.out_faces) << " faces, "
      << group(input.info.out_vertices) << " vertices; " << input.info.note << ".\n";
  out << "Load average before / after this input: " << input.load_before << " / "
      << input.load_after << ".\n";

  if (!input.reads.empty()) {
    out << "\n**Binary STL read** (MB = 10^6 bytes of file per wall second, median of " << opt.reps
        << " processes, first call in each; page cache warm):\n\n";
    out << "| reader | reads from | MB/s | median s | warm MB/s | faces | vertices "
           "| peak RSS MiB | others' CPU | note |\n";
    out << "|---|---|--:|--:|--:|--:|--:|--:|--:|---|\n";
    for (const ReadCase& c : input.reads) {
      out << "| " << c.label << " | " << c.source << " | ";
      if (!c.result.ok) {
        out << "— | — | — | — | — | — | — | **" << cell(c.result.failure) << "** |\n";
        continue;
      }
      const Sample& s = c.result.first;
      const double mb = double(input.file_bytes) / 1e6;
      out << fixed(mb / c.result.median_s(), 1) << " | " << sig3(c.result.median_s()) << " | "
          << (c.result.has_warm() ? fixed(mb / c.result.warm_median_s(), 1) : "—") << " | "
          << group(s.out_faces) << " | " << group(s.out_vertices) << " | " << mib(c.result.peak_kb)
          << " | " << percent(c.result.others_busy) << " | " << cell(s.note) << " |\n";
    }
  }

  if (!input.refines.empty()) {
    out << "\n**Refinement** (M output triangles per wall second, median of " << opt.reps
        << " processes, cold = the first run in a fresh process, warm = reruns in the same "
           "process when the first took < "
        << opt.min_time
        << " s; peak RSS of the cold run, base = RSS with the input loaded; "
           "ratio = peak / (input + output binary STL bytes)):\n\n";
    out << "| L | algorithm | thr | out tris | M tris/s | median s (min–max) | warm M tris/s "
           "| vs peer (1 thr) | peak MiB | base MiB | Δ MiB | ratio | CPU/wall | others' CPU "
           "| convert s | note |\n";
    out << "|--:|---|--:|--:|--:|--:|--:|---|--:|--:|--:|--:|--:|--:|--:|---|\n";
    for (const RefineCase& c : input.refines) {
      out << "| " << c.level << " | " << c.label << " | " << c.threads << " | ";
      if (c.skipped) {
        out << group(faces_after(input.info.out_faces, c.key, c.level))
            << " | — | — | — | — | — | — | — | — | — | — | — | — | skipped: " << cell(c.skip_reason)
            << " |\n";
        continue;
      }
      if (!c.result.ok) {
        out << "— | — | — | — | — | — | — | — | — | — | — | — | **" << cell(c.result.failure)
            << "** |\n";
        continue;
      }
      const Sample& s = c.result.first;
      const Aggregate& r = c.result;
      const std::uint64_t expected = faces_after(s.in_faces, c.key, c.level);
      std::string note = s.note;
      if (s.out_faces != expected) {
        note = "output faces " + group(s.out_faces) + " != " + std::to_string(growth_of(c.key)) +
               "^L x input " + group(expected) + (note.empty() ? "" : "; ") + note;
      }
      out << group(s.out_faces) << " | " << fixed(rate(c) / 1e6, 2) << " | " << sig3(r.median_s())
          << " (" << sig3(r.min_s()) << "–" << sig3(r.max_s()) << ") | "
          << (r.has_warm() ? fixed(warm_rate(c) / 1e6, 2) : "—") << " | " << speedup_text(input, c)
          << " | " << mib(r.peak_kb) << " | " << mib(r.base_kb) << " | "
          << mib(r.peak_kb - r.base_kb) << " | " << fixed(rss_ratio(input, c), 2) << " | "
          << fixed(r.cpu_ratio, 2) << " | " << percent(r.others_busy) << " | "
          << (c.ours ? std::string("—") : sig3(s.convert_seconds)) << " | " << cell(note) << " |\n";
    }
  }
}

//! "skip" / "fail" for a case without a rate, "" otherwise (also for a missing case).
std::string state_text(const RefineCase* c) {
  if (c == nullptr) return "";
  if (c->skipped) return "skip";
  if (!c->result.ok) return "fail";
  return {};
}
std::string rate_text(const RefineCase* c) {
  const std::string s = state_text(c);
  return c == nullptr || !s.empty() ? s : fixed(rate(*c) / 1e6, 2);
}
std::string ratio_cell(const RefineCase* a, const RefineCase* b) {
  if (a == nullptr || b == nullptr || !state_text(a).empty() || !state_text(b).empty()) return "";
  return ratio_text(*a, *b);
}
std::string rss_text(const InputResult& input, const RefineCase* c) {
  const std::string s = state_text(c);
  return c == nullptr || !s.empty() ? s : fixed(rss_ratio(input, *c), 2);
}
std::string peak_text(const RefineCase* c) {
  const std::string s = state_text(c);
  return c == nullptr || !s.empty() ? s : mib(c->result.peak_kb);
}

bool has_family(const std::vector<InputResult>& inputs, Family family) {
  for (const InputResult& input : inputs)
    for (const RefineCase& c : input.refines)
      if (c.family == family) return true;
  return false;
}

void print_summary(std::ostream& out, const std::vector<InputResult>& inputs, const Options& opt) {
  std::vector<int> levels = opt.levels;
  std::sort(levels.begin(), levels.end());
  out << "\n## Targets (single-threaded)\n\n";
  if (has_family(inputs, Family::Loop) || has_family(inputs, Family::Butterfly)) {
    out << "M output triangles per second, cold runs (median); ratio = ours / peer, with the "
           "warm-rerun ratio in brackets where both were rerun. Targets: loop ≥ 2× CGAL Loop, "
           "butterfly ≥ 4× OpenMesh modified butterfly. Request RSS = peak RSS of the whole "
           "request (STL bytes in memory → read, weld, ingest, refine, write STL) / (input + "
           "output STL bytes), target ≤ 1.5; refine RSS = the same for refine() alone on the "
           "loaded mesh.\n\n";
    out << "| input | L | ours loop | CGAL Loop | ratio | OM Loop | ratio | ours butterfly "
           "| OM butterfly | ratio | refine RSS loop | refine RSS butterfly | request RSS loop "
           "| request RSS butterfly |\n";
    out << "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
    for (const InputResult& input : inputs) {
      for (const int level : levels) {
        const auto get = [&](const std::string& key) { return find_case(input, key, level, 1); };
        const RefineCase* loop = get("ours-loop");
        const RefineCase* cgal = get("cgal-loop");
        const RefineCase* om_loop = get("openmesh-loop");
        const RefineCase* bfly = get("ours-butterfly");
        const RefineCase* om_bfly = get("openmesh-butterfly");
        if (!loop && !cgal && !bfly) continue;
        out << "| " << input.name << " | " << level << " | " << rate_text(loop) << " | "
            << rate_text(cgal) << " | " << ratio_cell(loop, cgal) << " | " << rate_text(om_loop)
            << " | " << ratio_cell(loop, om_loop) << " | " << rate_text(bfly) << " | "
            << rate_text(om_bfly) << " | " << ratio_cell(bfly, om_bfly) << " | "
            << rss_text(input, loop) << " | " << rss_text(input, bfly) << " | "
            << rss_text(input, get("pipeline-loop")) << " | "
            << rss_text(input, get("pipeline-butterfly")) << " |\n";
      }
    }
  }
  if (has_family(inputs, Family::Sqrt3)) {
    out << "\nsqrt3 family: M output triangles per second, cold runs (median); ratio = ours / "
           "peer (warm-rerun ratio in brackets). Targets: sqrt3 ≥ 2× CGAL Sqrt3_subdivision, "
           "sqrt3-interp ≥ 4× OpenMesh InterpolatingSqrt3LGT. Peak RSS of the refinement "
           "process in MiB.\n\n";
    out << "| input | L | ours sqrt3 | CGAL Sqrt3 | ratio | OM Sqrt3T | ratio | ours "
           "sqrt3-interp | OM LG | ratio | vs OM Sqrt3T | ours sqrt3-unified | vs OM LG | "
           "peak MiB ours sqrt3 / CGAL / ours interp / OM LG / ours unified |\n";
    out << "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
    for (const InputResult& input : inputs) {
      for (const int level : levels) {
        const auto get = [&](const std::string& key) { return find_case(input, key, level, 1); };
        const RefineCase* kob = get("ours-sqrt3");
        const RefineCase* cgal = get("cgal-sqrt3");
        const RefineCase* om = get("openmesh-sqrt3");
        const RefineCase* lg = get("ours-sqrt3-interp");
        const RefineCase* om_lg = get("openmesh-sqrt3-lg");
        const RefineCase* ll = get("ours-sqrt3-unified");
        if (!kob && !lg && !ll) continue;
        out << "| " << input.name << " | " << level << " | " << rate_text(kob) << " | "
            << rate_text(cgal) << " | " << ratio_cell(kob, cgal) << " | " << rate_text(om) << " | "
            << ratio_cell(kob, om) << " | " << rate_text(lg) << " | " << rate_text(om_lg) << " | "
            << ratio_cell(lg, om_lg) << " | " << ratio_cell(lg, om) << " | " << rate_text(ll)
            << " | " << ratio_cell(ll, om_lg) << " | " << peak_text(kob) << " / " << peak_text(cgal)
            << " / " << peak_text(lg) << " / " << peak_text(om_lg) << " / " << peak_text(ll)
            << " |\n";
      }
    }
  }

  out << "\nBinary STL read, MB/s, first call in a fresh process (target: ours read + weld "
         "≥ 300 MB/s):\n\n";
  bool header = false;
  for (const InputResult& input : inputs) {
    if (input.reads.empty()) continue;
    if (!header) {
      out << "| input | MB |";
      for (const ReadCase& c : input.reads) out << ' ' << c.label << " |";
      out << "\n|---|--:|";
      for (std::size_t i = 0; i < input.reads.size(); ++i) out << "--:|";
      out << '\n';
      header = true;
    }
    out << "| " << input.name << " | " << fixed(double(input.file_bytes) / 1e6, 2);
    for (const ReadCase& c : input.reads) {
      out << " | "
          << (c.result.ok ? fixed(double(input.file_bytes) / c.result.median_s() / 1e6, 1)
                          : std::string("fail"));
    }
    out << " |\n";
  }
}

int run(Options opt, const std::string& command_line) {
  std::ostream& out = std::cout;
  opt.warmup_meshes = write_warmup_meshes(opt.tmp_dir);
  out << "# stlrefine_bench\n\n";
  out << "Command: `" << command_line << "`\n\n";
  out << machine_markdown();
  if (!have_openmesh()) out << "- OpenMesh was not found at configure time: no OpenMesh rows\n";
  out << "\nEvery refinement gets the mesh our ingest (read_stl_file + weld + build_mesh) "
         "makes from the file; peers get it converted to their own structure "
         "(\"convert s\", untimed). Peers are single-threaded; \"thr\" is "
         "RefineParams::threads for ours. OpenMesh meshes use double points. Ours detects "
         "creases at "
      << opt.crease_angle
      << "° and applies crease rules; the peers' uniform schemes do not. CPU/wall = CPU "
         "time of the process (all threads) / wall time of the first run. Others' CPU = the "
         "largest share of all CPU time that other processes used while a repetition's "
         "process ran (interference; each process starts only after the CPUs were "
      << int(opt.idle * 100) << "% idle for a second, waiting at most " << opt.idle_wait
      << " s; — for processes too short to tell)."
      << (opt.no_prefault ? ""
                          : " Before its measured run each process touches and releases the "
                            "memory the run is expected to need, so no algorithm pays this "
                            "VM's cost of first-touching guest memory the host has not backed "
                            "yet (see bench/measure.h).")
      << "\n";
  out.flush();

  std::vector<InputResult> inputs;
  for (const std::string& name : opt.inputs) {
    InputResult input;
    input.name = name;
    std::string why;
    input.path = resolve_input(opt, name, why);
    if (input.path.empty()) {
      out << "\n### " << name << "\n\nSkipped: " << why << "\n";
      std::cerr << "skipping " << name << ": " << why << '\n';
      continue;
    }
    input.file_bytes = fs::file_size(input.path);
    input.load_before = load_averages();
    std::cerr << "[" << name << "] " << input.path << ", load " << input.load_before << '\n';

    const fs::path path = input.path;
    const double crease = opt.crease_angle;
    const Outcome info = run_in_child([&] { return describe_input(path, crease); }, opt.timeout);
    input.ingest_ok = info.ok;
    input.ingest_failure = info.failure;
    input.info = info.sample;
    if (input.ingest_ok) {
      if (!opt.no_read) run_reads(opt, input);
      if (!opt.no_refine) run_refines(opt, input);
    }
    input.load_after = load_averages();
    print_input(out, input, opt);
    out.flush();
    inputs.push_back(std::move(input));
  }
  print_summary(out, inputs, opt);
  out << "\nFinished " << utc_now() << "; load average at the end: " << load_averages() << "\n";
  return 0;
}

}  // namespace
}  // namespace stlrefine::bench

int main(int argc, char** argv) {
  using stlrefine::bench::Options;
  Options opt;
  CLI::App app{
      "stlrefine_bench: our subdivision schemes and STL reader beside CGAL and "
      "OpenMesh. Markdown on stdout, progress on stderr."};
  std::string mesh_dir = opt.mesh_dir.string(), tmp_dir = opt.tmp_dir.string();
  app.add_option("mesh_dir", mesh_dir, "Directory of the test meshes")->capture_default_str();
  app.add_option("--inputs", opt.inputs, "Input files relative to mesh_dir (.gz is unpacked)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--levels", opt.levels, "Subdivision levels")
      ->delimiter(',')
      ->check(CLI::Range(1, 8))
      ->capture_default_str();
  app.add_option("--schemes", opt.schemes, "Our schemes")->delimiter(',')->capture_default_str();
  app.add_option("--peers", opt.peers,
                 "Peers: cgal-loop, openmesh-loop, openmesh-butterfly, cgal-sqrt3, "
                 "openmesh-sqrt3, openmesh-sqrt3-lg, none")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--threads", opt.threads, "RefineParams::threads values for ours")
      ->delimiter(',')
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--reps", opt.reps, "Repetitions (each in a fresh process); median reported")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--min-time", opt.min_time,
                 "When the first (cold) run took less, rerun in the same process (warm) "
                 "until this many seconds of reruns")
      ->capture_default_str();
  app.add_option("--max-runs", opt.max_runs, "At most this many runs per process")
      ->capture_default_str();
  app.add_option("--max-out-tris", opt.max_out_tris, "Skip cases with more output triangles")
      ->capture_default_str();
  app.add_option("--max-mem-gb", opt.max_mem_gb, "Skip cases predicted to need more (GiB)")
      ->capture_default_str();
  app.add_option("--timeout", opt.timeout, "Seconds before a case's process is killed")
      ->capture_default_str();
  app.add_option("--crease-angle", opt.crease_angle, "Our crease angle (degrees)")
      ->capture_default_str();
  app.add_flag("--no-read", opt.no_read, "Skip the STL read comparison");
  app.add_flag("--no-refine", opt.no_refine, "Skip the refinement comparison");
  app.add_flag("--no-pipeline", opt.no_pipeline, "Skip the whole-request rows");
  app.add_flag("--no-prefault", opt.no_prefault,
               "Do not touch and release the expected amount of memory before each measured "
               "run (see measure.h)");
  app.add_option("--idle", opt.idle,
                 "Before each measured process, wait until this share of all CPU time was "
                 "idle over a second (0: do not wait)")
      ->capture_default_str();
  app.add_option("--idle-wait", opt.idle_wait, "Longest wait for --idle (s), then run anyway")
      ->capture_default_str();
  app.add_option("--tmp-dir", tmp_dir, "Where .gz inputs are unpacked")->capture_default_str();
  app.add_option("--warmup-extra", opt.warmup_extra,
                 "Also warm up every job on this mesh (relative to mesh_dir), after the "
                 "built-in octahedron and torus, untimed");
  CLI11_PARSE(app, argc, argv);
  opt.mesh_dir = mesh_dir;
  opt.tmp_dir = tmp_dir;
  if (opt.peers.size() == 1 && opt.peers[0] == "none") opt.peers.clear();

  std::string command_line;
  for (int i = 0; i < argc; ++i) command_line += (i ? " " : "") + std::string(argv[i]);
  return stlrefine::bench::run(opt, command_line);
}
