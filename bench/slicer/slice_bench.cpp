// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_slice_bench: our slicer beside CGAL::Polygon_mesh_slicer (AABB tree built once,
// one call per plane: what a CGAL user writes) on the same meshes and the same planes, in
// one run; and, each as its own process timed from fork to exit, our `stlrefine slice` beside
// Debian's slic3r 1.3 (`--export-svg`) when it is installed. Prints Markdown to stdout,
// progress to stderr. Hand-run (bench/slicer/README.md).
//
// Each (input, layer height, case, repetition) runs in its own forked child (bench/measure.h):
// it loads its input untimed, records its RSS, resets the peak, and runs once. Inputs that
// need scaling (metres -> mm) or refining are prepared once as binary STL in --tmp-dir, so
// the whole-process cases of both sides read the same file.

#include <CGAL/Polygon_mesh_processing/IO/polygon_mesh_io.h>
#include <CGAL/Polygon_mesh_slicer.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/version.h>
#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "bench/machine.h"
#include "bench/measure.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "slicer/cgal_planes.h"
#include "slicer/slice.h"
#include "slicer/writers.h"

namespace stlrefine::bench {

// machine.cpp reports these (stlrefine_bench defines them in its peer jobs).
std::string cgal_version() {
  return CGAL_VERSION_STR;
}
std::string openmesh_version() {
  return "not used";
}

namespace {

namespace fs = std::filesystem;
using Kernel = slicer::cgal::Kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
using CgalSlicer = CGAL::Polygon_mesh_slicer<SurfaceMesh, Kernel>;

struct Options {
  fs::path mesh_dir = "/work/shared/meshes";
  //! FILE[:SCALE[:BUTTERFLY_LEVELS]]; SCALE brings the part to millimetres.
  std::vector<std::string> inputs = {
      "cad/fandisk.stl:10",  "organic/bunny.stl:1000",        "organic/armadillo.stl:100",
      "cad/tray_bottom.stl", "large/dragon_full.stl.gz:1000", "organic/armadillo.stl:100:3"};
  std::vector<double> heights = {0.1, 0.05};
  std::vector<int> threads = {1, 2};
  int reps = 3;
  int timeout = 1800;
  double idle = 0.8;
  int idle_wait = 120;
  bool no_cgal = false, no_whole = false;
  fs::path tmp_dir = "/tmp/stlrefine_slice_bench";
  //! slic3r to run beside us: a path, or a name looked up on PATH; "none" leaves it out.
  std::string slic3r = "slic3r";
  int slic3r_reps = 1;
  int slic3r_threads = 0;  //!< 0: the largest of `threads`
  //! Our command line for the process rows; empty: `stlrefine` next to this program.
  std::string stlrefine;
  bool no_process = false;
};

// ------------------------------------------------------------------------- formatting

std::string fixed(double x, int precision) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", precision, x);
  return text;
}
std::string sig3(double x) {
  if (!std::isfinite(x) || x <= 0) return "—";
  return fixed(x, x >= 100 ? 0 : x >= 10 ? 1 : x >= 1 ? 2 : 3);
}
std::string group(std::uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}
std::string mib(long kb) {
  return fixed(double(kb) / 1024.0, 0);
}

// ------------------------------------------------------------------------- loading

Mesh load_mesh(const fs::path& path) {
  return build_mesh(weld(read_stl_file(path))).mesh;
}

SurfaceMesh to_surface_mesh(const Mesh& mesh) {
  SurfaceMesh sm;
  sm.reserve(SurfaceMesh::size_type(mesh.num_vertices()),
             SurfaceMesh::size_type(3 * mesh.num_faces() / 2),
             SurfaceMesh::size_type(mesh.num_faces()));
  std::vector<SurfaceMesh::Vertex_index> v;
  v.reserve(mesh.num_vertices());
  for (const Vec3& p : mesh.positions()) v.push_back(sm.add_vertex(Kernel::Point_3(p.x, p.y, p.z)));
  for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
    const auto c = mesh.face_vertices(FaceId(std::uint32_t(f)));
    if (sm.add_face(v[c[0].idx], v[c[1].idx], v[c[2].idx]) == SurfaceMesh::null_face())
      throw std::runtime_error("CGAL refused a face of our ingested mesh");
  }
  return sm;
}

//! The planes of a run: the uniform layers of our plan over the mesh's z range.
std::vector<double> plan_heights(double z_min, double z_max, double h) {
  slicer::SliceParams p;
  p.layer_height = h;
  p.z_min = z_min;
  p.z_max = z_max;
  return slicer::plan_layers(Mesh{}, p).heights;
}

// ------------------------------------------------------------------------- jobs

enum class OurMode { Slice, SliceEncode, Whole };

//! Ours: slicing only (layers to a counting callback), slicing + CLI-binary encoding to a
//! counting sink, or the whole process (read + weld + ingest + slice + write the file).
class OurJob final : public Job {
 public:
  OurJob(fs::path path, double h, int threads, OurMode mode, fs::path out)
      : path_(std::move(path)), out_(std::move(out)), mode_(mode) {
    params_.layer_height = h;
    params_.threads = threads;
    if (mode_ != OurMode::Whole) mesh_ = load_mesh(path_);
  }
  void run() override {
    const auto writer = slicer::make_writer(slicer::SliceFormat::CliBinary);
    if (mode_ == OurMode::Whole) {
      const Mesh mesh = load_mesh(path_);
      in_ = mesh.num_faces();
      stats_ = slicer::write_slices_file(out_, mesh, params_, *writer);
      return;
    }
    in_ = mesh_.num_faces();
    if (mode_ == OurMode::Slice) {
      stats_ = slicer::slice(mesh_, params_, [](slicer::Layer&&) {});
    } else {
      stats_ = slicer::write_slices(mesh_, params_, *writer,
                                    [this](std::string_view b) { bytes_ += b.size(); });
    }
  }
  std::uint64_t in_faces() const override { return in_; }
  std::uint64_t out_faces() const override { return stats_.layers; }
  std::uint64_t out_vertices() const override { return stats_.points; }
  std::string note() const override {
    std::ostringstream s;
    s << stats_.outer_loops << " outer, " << stats_.holes << " holes, " << stats_.open_polylines
      << " open";
    if (stats_.degenerate_loops) s << ", " << stats_.degenerate_loops << " degenerate";
    if (stats_.reversed_loops) s << ", " << stats_.reversed_loops << " reversed";
    if (bytes_) s << "; " << fixed(double(bytes_) / 1e6, 1) << " MB CLI";
    if (mode_ == OurMode::Whole)
      s << "; " << fixed(double(fs::file_size(out_)) / 1e6, 1) << " MB CLI file";
    return s.str();
  }

 private:
  fs::path path_, out_;
  OurMode mode_;
  slicer::SliceParams params_;
  Mesh mesh_;
  slicer::SliceStats stats_;
  std::uint64_t in_ = 0, bytes_ = 0;
};

//! CGAL: Polygon_mesh_slicer (its AABB tree built once) called once per plane, the planes
//! being ours (slicer/cgal_planes.h). "Whole" reads the STL with CGAL's repairing reader
//! and writes every polyline to a file in CLI binary encoding.
class CgalJob final : public Job {
 public:
  CgalJob(fs::path path, std::vector<double> heights, bool whole, fs::path out)
      : path_(std::move(path)), out_(std::move(out)), heights_(std::move(heights)), whole_(whole) {
    if (!whole_) {
      const Mesh mesh = load_mesh(path_);
      const double t0 = now_seconds();
      sm_ = to_surface_mesh(mesh);
      convert_ = now_seconds() - t0;
    }
  }
  void run() override {
    double t0 = now_seconds();
    std::ofstream file;
    if (whole_) {
      if (!CGAL::Polygon_mesh_processing::IO::read_polygon_mesh(path_.string(), sm_))
        throw std::runtime_error("CGAL could not read " + path_.string());
      read_s_ = now_seconds() - t0;
      t0 = now_seconds();
      file.open(out_, std::ios::binary);
    }
    in_ = sm_.number_of_faces();
    CgalSlicer slicer(sm_);
    tree_s_ = now_seconds() - t0;
    t0 = now_seconds();
    std::vector<std::vector<Kernel::Point_3>> polylines;
    std::string bytes;
    for (const double z : heights_) {
      polylines.clear();
      slicer(slicer::cgal::layer_plane(z), std::back_inserter(polylines));
      for (const auto& p : polylines) points_ += p.size();
      if (!whole_) continue;
      bytes.clear();
      put<std::uint16_t>(bytes, 127);
      put<float>(bytes, float(z));
      for (const auto& p : polylines) {
        put<std::uint16_t>(bytes, 130);
        put<std::int32_t>(bytes, 1);
        put<std::int32_t>(bytes, p.front() == p.back() ? 1 : 2);
        put<std::int32_t>(bytes, std::int32_t(p.size()));
        for (const auto& q : p) put<float>(bytes, float(q.x())), put<float>(bytes, float(q.y()));
      }
      file.write(bytes.data(), std::streamsize(bytes.size()));
    }
    slice_s_ = now_seconds() - t0;
  }
  std::uint64_t in_faces() const override { return in_; }
  std::uint64_t out_faces() const override { return heights_.size(); }
  std::uint64_t out_vertices() const override { return points_; }
  double convert_seconds() const override { return convert_; }
  std::string note() const override {
    std::ostringstream s;
    if (whole_) s << "read " << fixed(read_s_, 2) << " s, ";
    s << "tree " << fixed(tree_s_, 2) << " s, planes " << fixed(slice_s_, 2) << " s";
    return s.str();
  }

 private:
  template <class T>
  static void put(std::string& out, T value) {
    out.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  fs::path path_, out_;
  std::vector<double> heights_;
  bool whole_;
  SurfaceMesh sm_;
  double convert_ = 0, read_s_ = 0, tree_s_ = 0, slice_s_ = 0;
  std::uint64_t in_ = 0, points_ = 0;
};

// ------------------------------------------------------------------------- slic3r

//! The executable `name` stands for: itself when it contains a '/', else the first match on
//! PATH; empty when there is none.
fs::path find_executable(const std::string& name) {
  if (name.empty() || name == "none") return {};
  if (name.find('/') != std::string::npos) return ::access(name.c_str(), X_OK) == 0 ? name : "";
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const fs::path candidate = fs::path(dir.empty() ? "." : dir) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return {};
}

//! The first line `slic3r --version` prints ("unknown" when it prints nothing).
std::string slic3r_version(const fs::path& exe) {
  const std::string cmd = "'" + exe.string() + "' --version 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return "unknown";
  char line[256] = {};
  const bool got = std::fgets(line, sizeof(line), pipe) != nullptr;
  ::pclose(pipe);
  std::string v = got ? line : "unknown";
  while (!v.empty() && (v.back() == '\n' || v.back() == '\r')) v.pop_back();
  return v;
}

//! What an SVG of layers holds. slic3r: one <g id="layerN" slic3r:z="..."> per layer (z in
//! its scaled integer units: mm x 1e-6, measured from the part's bottom), one <polygon
//! slic3r:type="contour"|"hole" points="x,y x,y ..."> per loop, each point once. Ours: one
//! <g class="layer" data-z="..."> per layer (z in mm), one <path d="M.. L.. Z"> per layer
//! holding every loop.
struct SvgCounts {
  std::uint64_t layers = 0, contours = 0, holes = 0, points = 0, bytes = 0;
  std::vector<double> z;  //!< each layer's plane as written, in the file's own unit
};

SvgCounts count_svg(const fs::path& svg, bool slic3r) {
  std::ifstream in(svg, std::ios::binary);
  if (!in) throw std::runtime_error("no SVG written: " + svg.string());
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  SvgCounts c;
  c.bytes = text.size();
  const auto count = [&](std::string_view what) {
    std::uint64_t n = 0;
    for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1))
      ++n;
    return n;
  };
  const std::string_view z_attr = slic3r ? "slic3r:z=\"" : "data-z=\"";
  for (std::size_t at = text.find(z_attr); at != std::string::npos; at = text.find(z_attr, at)) {
    at += z_attr.size();
    c.z.push_back(std::strtod(text.c_str() + at, nullptr));
  }
  c.layers = c.z.size();
  c.contours = slic3r ? count("slic3r:type=\"contour\"") : 0;
  c.holes = slic3r ? count("slic3r:type=\"hole\"") : 0;
  const std::string_view attr = slic3r ? "points=\"" : " d=\"";
  for (std::size_t at = text.find(attr); at != std::string::npos; at = text.find(attr, at)) {
    at += attr.size();
    const std::size_t end = text.find('"', at);
    if (end == std::string::npos) break;
    const auto first = text.begin() + std::ptrdiff_t(at), last = text.begin() + std::ptrdiff_t(end);
    // slic3r: one comma per point; ours: one M or L command per point.
    c.points += std::uint64_t(slic3r ? std::count(first, last, ',')
                                     : std::count(first, last, 'M') + std::count(first, last, 'L'));
    at = end;
  }
  return c;
}

//! Whether an SVG's layers are our planes: same count, and each z (times `unit`, plus
//! `offset`) within 1e-6 mm of ours. Text for the row's note.
std::string compare_planes(const SvgCounts& c, const std::vector<double>& heights, double unit,
                           double offset) {
  if (c.z.size() != heights.size())
    return "**layer count differs from ours: " + std::to_string(c.z.size()) + " vs " +
           std::to_string(heights.size()) + "**";
  double worst = 0;
  for (std::size_t k = 0; k < heights.size(); ++k)
    worst = std::max(worst, std::fabs(c.z[k] * unit + offset - heights[k]));
  char text[160];
  std::snprintf(text, sizeof(text), "%s our planes (max |dz| %.1e mm)",
                worst <= 1e-6 ? "layers are" : "**layers differ from**", worst);
  return text;
}

//! The last non-empty line of a log file (the program's error, when it fails).
std::string last_line(const fs::path& log) {
  std::ifstream in(log);
  std::string line, last;
  while (std::getline(in, line))
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  return last;
}

//! Runs `args` as its own process (fork + exec, output to `log`) and times it from fork to
//! exit; its CPU time and peak RSS come from wait4. Throws when it fails.
Sample run_process(std::vector<std::string> args, const fs::path& log) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const double t0 = now_seconds();
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // dies with us (a timeout kills us)
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) ::dup2(fd, 1), ::dup2(fd, 2), ::close(fd);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int status = 0;
  rusage usage{};
  while (::wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  Sample s;
  s.seconds = now_seconds() - t0;
  const auto to_s = [](const timeval& t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
  s.cpu_seconds = to_s(usage.ru_utime) + to_s(usage.ru_stime);
  s.peak_kb = s.maxrss_kb = usage.ru_maxrss;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw std::runtime_error(fs::path(args[0]).filename().string() + " " +
                             (WIFEXITED(status)
                                  ? "exited with status " + std::to_string(WEXITSTATUS(status))
                                  : "was killed by signal " + std::to_string(WTERMSIG(status))) +
                             ": " + last_line(log));
  }
  return s;
}

//! `slic3r --export-svg` on `stl`. Layers at z_min + (k + 1/2) h like ours: the first layer
//! is as thick as the others. Then counts what the SVG holds and checks its planes.
Sample run_slic3r(const fs::path& exe, const fs::path& stl, double h, int threads,
                  const std::vector<double>& heights, double z_min, const fs::path& svg,
                  const fs::path& log) {
  fs::remove(svg);
  const std::string height = fixed(h, 4);
  Sample s = run_process(
      {exe.string(), "--no-gui", "--export-svg", "--layer-height", height, "--first-layer-height",
       height, "--threads", std::to_string(threads), "--output", svg.string(), stl.string()},
      log);
  const SvgCounts c = count_svg(svg, true);
  s.out_faces = c.layers;
  s.out_vertices = c.points;
  std::ostringstream note;
  note << compare_planes(c, heights, 1e6, z_min) << "; " << c.contours << " contours, " << c.holes
       << " holes (its SVG has no open polylines); " << fixed(double(c.bytes) / 1e6, 1)
       << " MB SVG; CPU " << fixed(s.cpu_seconds, 1) << " s (user + sys)";
  copy_note(s, note.str());
  return s;
}

//! Our command line, `stlrefine slice IN --layer-height h --format F --threads T -o OUT`, as
//! its own process like slic3r: read, ingest, slice, write, exit.
Sample run_ours_process(const fs::path& exe, const fs::path& stl, double h, int threads,
                        const std::string& format, const std::vector<double>& heights,
                        const fs::path& out, const fs::path& log) {
  fs::remove(out);
  Sample s =
      run_process({exe.string(), "slice", stl.string(), "--layer-height", fixed(h, 4), "--format",
                   format, "--threads", std::to_string(threads), "-o", out.string()},
                  log);
  std::ostringstream note;
  if (format == "svg") {
    const SvgCounts c = count_svg(out, false);
    s.out_faces = c.layers;
    s.out_vertices = c.points;
    note << compare_planes(c, heights, 1, 0) << "; ";
  }
  note << fixed(double(fs::file_size(out)) / 1e6, 1) << " MB " << format << "; CPU "
       << fixed(s.cpu_seconds, 1) << " s (user + sys)";
  copy_note(s, note.str());
  return s;
}

// ------------------------------------------------------------------------- inputs

struct Input {
  std::string spec, name;
  fs::path source, prepared;
  double scale = 1;
  int levels = 0;
  bool ok = false;
  std::string why;
  std::uint64_t file_triangles = 0, faces = 0, vertices = 0;
  double z_min = 0, z_max = 0;
  std::string mesh_note;
};

Input parse_input(const Options& opt, const std::string& spec) {
  Input in;
  in.spec = spec;
  std::stringstream s(spec);
  std::string file, scale, levels;
  std::getline(s, file, ':');
  std::getline(s, scale, ':');
  std::getline(s, levels, ':');
  in.source = opt.mesh_dir / file;
  in.scale = scale.empty() ? 1.0 : std::stod(scale);
  in.levels = levels.empty() ? 0 : std::stoi(levels);
  in.name = file;
  if (in.scale != 1) in.name += " ×" + scale;
  if (in.levels > 0) in.name += ", butterfly L" + levels;
  return in;
}

//! A plain binary STL for the input: unpacked (.gz), scaled and refined as asked, cached in
//! tmp_dir. Refinement uses TBB, so it runs in a child.
void prepare(const Options& opt, Input& in) {
  if (!fs::exists(in.source)) {
    in.why = "not found: " + in.source.string();
    return;
  }
  fs::create_directories(opt.tmp_dir);
  fs::path plain = in.source;
  if (in.source.extension() == ".gz") {
    plain = opt.tmp_dir / in.source.stem();
    if (!fs::exists(plain)) {
      std::cerr << "unpacking " << in.source << '\n';
      const std::string tmp = plain.string() + ".part";
      if (std::system(("gunzip -c '" + in.source.string() + "' > '" + tmp + "'").c_str()) != 0) {
        in.why = "gunzip failed";
        return;
      }
      fs::rename(tmp, plain);
    }
  }
  in.prepared = plain;
  if (in.scale != 1 || in.levels > 0) {
    in.prepared = opt.tmp_dir / (plain.stem().string() + "_x" + fixed(in.scale, 0) + "_bf" +
                                 std::to_string(in.levels) + ".stl");
    if (!fs::exists(in.prepared)) {
      std::cerr << "preparing " << in.prepared << '\n';
      const Outcome o = run_in_child(
          [&] {
            Mesh mesh = load_mesh(plain);
            for (Vec3& p : mesh.mutable_positions()) p *= in.scale;
            if (in.levels > 0) {
              RefineParams rp;
              rp.levels = in.levels;
              rp.max_faces = 100'000'000;
              mesh = refine(std::move(mesh), rp).mesh;
            }
            write_stl_file(in.prepared, mesh);
            return Sample{};
          },
          opt.timeout);
      if (!o.ok) {
        in.why = "preparing failed: " + o.failure;
        return;
      }
    }
  }
  const Outcome o = run_in_child(
      [&] {
        Sample s;
        const TriangleSoup soup = read_stl_file(in.prepared);
        s.in_faces = soup.triangle_count();
        const IngestResult ingest = build_mesh(weld(soup));
        s.out_faces = ingest.mesh.num_faces();
        s.out_vertices = ingest.mesh.num_vertices();
        const slicer::Bounds b = slicer::mesh_bounds(ingest.mesh);
        std::size_t boundary = 0;
        for (const HalfedgeId t : ingest.mesh.twins()) boundary += !t.valid();
        char text[256];
        std::snprintf(text, sizeof(text), "%.17g %.17g %zu", b.min.z, b.max.z, boundary);
        copy_note(s, text);
        return s;
      },
      opt.timeout);
  if (!o.ok) {
    in.why = "ingest failed: " + o.failure;
    return;
  }
  in.file_triangles = o.sample.in_faces;
  in.faces = o.sample.out_faces;
  in.vertices = o.sample.out_vertices;
  std::size_t boundary = 0;
  std::sscanf(o.sample.note, "%lf %lf %zu", &in.z_min, &in.z_max, &boundary);
  in.mesh_note = group(boundary) + " boundary half-edges";
  in.ok = true;
}

fs::path write_warmup_mesh(const fs::path& dir) {
  const fs::path path = dir / "warmup_octahedron.stl";
  const float v[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  const int f[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                       {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  std::string bytes(80, ' ');
  const std::uint32_t count = 8;
  bytes.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& face : f) {
    const float normal[3] = {0, 0, 0};
    bytes.append(reinterpret_cast<const char*>(normal), sizeof(normal));
    for (const int c : face) bytes.append(reinterpret_cast<const char*>(v[c]), sizeof(v[c]));
    bytes.append(2, '\0');
  }
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  return path;
}

double wait_until_idle(const Options& opt) {
  if (opt.idle <= 0) return -1;
  const double start = now_seconds();
  double idle = cpu_idle_fraction(1.0);
  while (idle >= 0 && idle < opt.idle && now_seconds() - start < opt.idle_wait)
    idle = cpu_idle_fraction(2.0);
  return idle;
}

// ------------------------------------------------------------------------- cases

struct Case {
  std::string label;
  int threads = 1;
  bool ours = true;
  std::string kind;  //!< "slice", "encode", "whole"
  std::function<JobFactory(const fs::path& stl, const std::vector<double>& heights, double h)> make;
};

struct Result {
  bool ok = false;
  std::string failure;
  std::vector<double> seconds;
  Sample first;
  long peak_kb = 0, base_kb = 0;
  double others = 0;
};

std::vector<Case> make_cases(const Options& opt) {
  std::vector<Case> cases;
  const fs::path out = opt.tmp_dir / "out.cli";
  for (const int t : opt.threads) {
    cases.push_back({"**ours** slice", t, true, "slice",
                     [t](const fs::path& p, const auto&, double h) -> JobFactory {
                       return [=] {
                         return std::make_unique<OurJob>(p, h, t, OurMode::Slice, fs::path());
                       };
                     }});
  }
  const int tmax = *std::max_element(opt.threads.begin(), opt.threads.end());
  cases.push_back({"**ours** slice + CLI binary encoding", tmax, true, "encode",
                   [tmax](const fs::path& p, const auto&, double h) -> JobFactory {
                     return [=] {
                       return std::make_unique<OurJob>(p, h, tmax, OurMode::SliceEncode,
                                                       fs::path());
                     };
                   }});
  if (!opt.no_cgal)
    cases.push_back({"CGAL Polygon_mesh_slicer (tree + planes)", 1, false, "slice",
                     [](const fs::path& p, const std::vector<double>& zs, double) -> JobFactory {
                       return [=] { return std::make_unique<CgalJob>(p, zs, false, fs::path()); };
                     }});
  if (!opt.no_whole) {
    cases.push_back({"**ours** whole: read + slice + write CLI file", tmax, true, "whole",
                     [tmax, out](const fs::path& p, const auto&, double h) -> JobFactory {
                       return [=] {
                         return std::make_unique<OurJob>(p, h, tmax, OurMode::Whole, out);
                       };
                     }});
    if (!opt.no_cgal)
      cases.push_back(
          {"CGAL whole: read (PMP) + tree + planes + write", 1, false, "whole",
           [out](const fs::path& p, const std::vector<double>& zs, double) -> JobFactory {
             return [=] { return std::make_unique<CgalJob>(p, zs, true, out); };
           }});
  }
  return cases;
}

Result measure(const Options& opt, const JobFactory& make, const JobFactory& warm) {
  Result r;
  for (int rep = 0; rep < opt.reps; ++rep) {
    wait_until_idle(opt);
    const Outcome o = run_in_child([&] { return measure_job(make, warm, 0, 0.0, 1); }, opt.timeout);
    r.others = std::max(r.others, o.others_busy);
    if (!o.ok) {
      r.failure = o.failure;
      r.ok = false;
      return r;
    }
    if (r.seconds.empty()) r.first = o.sample;
    r.seconds.push_back(o.sample.seconds);
    r.peak_kb = std::max(r.peak_kb, o.sample.peak_kb);
    r.base_kb = o.sample.base_kb;
    r.ok = true;
  }
  return r;
}

//! A separate program, `reps` processes, each after waiting for idle CPUs like ours.
Result measure_process(const Options& opt, int reps, const std::function<Sample()>& run_once) {
  Result r;
  for (int rep = 0; rep < reps; ++rep) {
    wait_until_idle(opt);
    const Outcome o = run_in_child(run_once, opt.timeout);
    r.others = std::max(r.others, o.others_busy);
    if (!o.ok) {
      r.failure = o.failure;
      r.ok = false;
      return r;
    }
    if (r.seconds.empty()) r.first = o.sample;
    r.seconds.push_back(o.sample.seconds);
    r.peak_kb = std::max(r.peak_kb, o.sample.peak_kb);
    r.ok = true;
  }
  return r;
}

}  // namespace

int run(int argc, char** argv) {
  Options opt;
  CLI::App app{"stlrefine_slice_bench: our slicer beside CGAL::Polygon_mesh_slicer"};
  app.add_option("mesh_dir", opt.mesh_dir, "Folder of the shared meshes");
  app.add_option("--inputs", opt.inputs, "FILE[:SCALE[:BUTTERFLY_LEVELS]] relative to mesh_dir");
  app.add_option("--heights", opt.heights, "Layer heights in mm");
  app.add_option("--threads", opt.threads, "Thread counts for our slicer");
  app.add_option("--reps", opt.reps, "Processes per case (median reported)");
  app.add_option("--timeout", opt.timeout, "Seconds before a case is killed");
  app.add_option("--idle", opt.idle,
                 "Wait for this idle CPU fraction before each process (0: never)");
  app.add_option("--idle-wait", opt.idle_wait, "Seconds to wait for idle at most");
  app.add_flag("--no-cgal", opt.no_cgal, "Leave CGAL out");
  app.add_flag("--no-whole", opt.no_whole, "Leave out the whole-process cases");
  app.add_option("--tmp-dir", opt.tmp_dir, "Prepared meshes and output files");
  app.add_option("--slic3r", opt.slic3r,
                 "slic3r executable (path or name on PATH) run beside us; \"none\": leave out");
  app.add_option("--slic3r-reps", opt.slic3r_reps, "slic3r processes per case (it is slow)");
  app.add_option("--slic3r-threads", opt.slic3r_threads,
                 "slic3r --threads (0: the largest of --threads)");
  app.add_option("--stlrefine", opt.stlrefine,
                 "stlrefine executable for the process rows (default: next to this program)");
  app.add_flag("--no-process", opt.no_process, "Leave out the `stlrefine slice` process rows");
  CLI11_PARSE(app, argc, argv);
  if (opt.slic3r_threads <= 0)
    opt.slic3r_threads = *std::max_element(opt.threads.begin(), opt.threads.end());
  const fs::path slic3r = find_executable(opt.slic3r);
  const std::string slic3r_ver = slic3r.empty() ? "" : slic3r_version(slic3r);
  const int tmax = *std::max_element(opt.threads.begin(), opt.threads.end());
  fs::path stlrefine;
  if (!opt.no_process) {
    stlrefine = opt.stlrefine.empty()
                    ? fs::read_symlink("/proc/self/exe").parent_path() / "stlrefine"
                    : find_executable(opt.stlrefine);
    if (::access(stlrefine.c_str(), X_OK) != 0) stlrefine.clear();
  }

  fs::create_directories(opt.tmp_dir);
  const fs::path warm_stl = write_warmup_mesh(opt.tmp_dir);
  std::cout << "# Slicer benchmark\n\n## Machine\n\n" << machine_markdown() << '\n';
  std::cout << "Ours: `slicer::slice` (planes, one pass, loops, nesting) with layers handed to a "
               "callback; CGAL: `Polygon_mesh_slicer<Surface_mesh, Epick>` built once (its AABB "
               "tree), called once per plane, polylines collected per plane and discarded. Same "
               "ingested mesh, same planes. Points: ours count each loop point once, CGAL repeats "
               "the first point of a closed polyline. Times are wall seconds of the first run in "
               "a fresh process, median of "
            << opt.reps << "; peak RSS is the process's (input included).\n\n";
  if (!slic3r.empty()) {
    std::cout << "slic3r: `" << slic3r.string() << "` (version " << slic3r_ver
              << "), a separate process per run: `slic3r --no-gui --export-svg --layer-height H "
                 "--first-layer-height H --threads "
              << opt.slic3r_threads
              << " --output OUT.svg IN.stl` on the same prepared STL, timed from fork to exit "
                 "(read, slice, write the SVG), peak RSS and CPU time from wait4; median of "
              << opt.slic3r_reps << ". Its points are those of its SVG polygons.\n\n";
  } else if (opt.slic3r != "none") {
    std::cout << "**slic3r: `" << opt.slic3r
              << "` not found, its rows are left out** (Debian: `apt-get install slic3r`).\n\n";
  }
  if (!stlrefine.empty()) {
    std::cout << "Ours as a process: `" << stlrefine.string()
              << " slice IN.stl --layer-height H --format svg|cli-binary --threads " << tmax
              << " -o OUT`, timed like slic3r (fork to exit, wait4), median of " << opt.reps
              << ".\n\n";
  } else if (!opt.no_process) {
    std::cout << "**stlrefine not found next to this program: the process rows are left out** "
                 "(build the `stlrefine` target, or give --stlrefine).\n\n";
  }

  const std::vector<Case> cases = make_cases(opt);
  const auto print_row = [](const std::string& label, int threads, const Result& r,
                            std::size_t layers, double h) {
    std::cout << "| " << h << " | " << group(layers) << " | " << label << " | " << threads << " | ";
    if (!r.ok) {
      std::cout << "failed | | | | | | | " << r.failure << " |\n";
      return;
    }
    const double s = median(r.seconds);
    const auto [lo, hi] = std::minmax_element(r.seconds.begin(), r.seconds.end());
    std::cout << fixed(s, 3) << " | " << fixed(*lo, 3) << "–" << fixed(*hi, 3) << " | "
              << sig3(double(r.first.out_vertices) / s / 1e6) << " | " << sig3(double(layers) / s)
              << " | " << (r.first.out_vertices > 0 ? group(r.first.out_vertices) : "—") << " | "
              << mib(r.peak_kb) << " (" << (r.base_kb > 0 ? mib(r.base_kb) : "—") << ") | "
              << (r.others < 0 ? "—" : std::to_string(int(std::lround(r.others * 100))) + "%")
              << " | " << r.first.note << " |\n";
  };
  for (const std::string& spec : opt.inputs) {
    Input in = parse_input(opt, spec);
    std::cerr << "== " << in.name << '\n';
    prepare(opt, in);
    std::cout << "## " << in.name << "\n\n";
    if (!in.ok) {
      std::cout << "Skipped: " << in.why << "\n\n";
      continue;
    }
    std::cout << group(in.file_triangles) << " triangles in `" << in.prepared.filename().string()
              << "` (" << fixed(double(fs::file_size(in.prepared)) / 1e6, 1) << " MB), "
              << group(in.faces) << " faces after ingest, " << in.mesh_note << "; z from "
              << fixed(in.z_min, 3) << " to " << fixed(in.z_max, 3) << " mm.\n\n";
    std::cout << "| h mm | layers | case | thr | wall s | min–max s | M points/s | layers/s | "
                 "points | peak RSS MiB (base) | others' CPU | note |\n";
    std::cout << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const double h : opt.heights) {
      const std::vector<double> heights = plan_heights(in.z_min, in.z_max, h);
      std::map<std::string, double> best;  // kind+side -> median seconds
      for (const Case& c : cases) {
        std::cerr << "  h " << h << ": " << c.label << " thr " << c.threads << '\n';
        const std::vector<double> warm_heights = {0.0};
        const Result r =
            measure(opt, c.make(in.prepared, heights, h), c.make(warm_stl, warm_heights, 0.5));
        print_row(c.label, c.threads, r, heights.size(), h);
        if (!r.ok) continue;
        const double s = median(r.seconds);
        const std::string key = c.kind + (c.ours ? "/ours" : "/cgal");
        best[key] = std::min(best.count(key) ? best[key] : 1e300, s);
      }
      if (!stlrefine.empty()) {
        for (const std::string format : {"svg", "cli-binary"}) {
          std::cerr << "  h " << h << ": stlrefine slice --format " << format << " thr " << tmax
                    << '\n';
          const fs::path out = opt.tmp_dir / ("out_process." + format);
          const fs::path log = opt.tmp_dir / "stlrefine.log";
          const Result r = measure_process(opt, opt.reps, [&] {
            return run_ours_process(stlrefine, in.prepared, h, tmax, format, heights, out, log);
          });
          print_row("**ours** `stlrefine slice --format " + format + "` (own process)", tmax, r,
                    heights.size(), h);
          if (r.ok) best["process/ours/" + format] = median(r.seconds);
        }
      }
      if (!slic3r.empty()) {
        std::cerr << "  h " << h << ": slic3r --export-svg thr " << opt.slic3r_threads << '\n';
        const fs::path svg = opt.tmp_dir / "out_slic3r.svg", log = opt.tmp_dir / "slic3r.log";
        const Result r = measure_process(opt, opt.slic3r_reps, [&] {
          return run_slic3r(slic3r, in.prepared, h, opt.slic3r_threads, heights, in.z_min, svg,
                            log);
        });
        print_row("slic3r " + slic3r_ver + " `--export-svg` (own process)", opt.slic3r_threads, r,
                  heights.size(), h);
        if (r.ok) best["process/slic3r"] = median(r.seconds);
      }
      if (best.count("slice/ours") && best.count("slice/cgal"))
        std::cerr << "  slice speed-up " << best["slice/cgal"] / best["slice/ours"] << '\n';
      if (best.count("slice/ours") && best.count("slice/cgal") && best.count("whole/ours") &&
          best.count("whole/cgal")) {
        std::cout << "| " << h << " | | *ours vs CGAL* | | | | | | | | | slicing "
                  << fixed(best["slice/cgal"] / best["slice/ours"], 1) << "× faster, whole process "
                  << fixed(best["whole/cgal"] / best["whole/ours"], 1) << "× faster |\n";
      }
      if (best.count("process/ours/svg") && best.count("process/slic3r")) {
        std::cout << "| " << h << " | | *ours vs slic3r* | | | | | | | | | process to SVG "
                  << fixed(best["process/slic3r"] / best["process/ours/svg"], 0) << "× faster";
        if (best.count("whole/cgal"))
          std::cout << " (CGAL whole, in-process: "
                    << fixed(best["process/slic3r"] / best["whole/cgal"], 1)
                    << "× faster than slic3r)";
        std::cout << " |\n";
      }
    }
    std::cout << '\n';
    std::cout.flush();
  }
  std::cout << "Load average at the end: " << load_averages() << "\n";
  return 0;
}

}  // namespace stlrefine::bench

int main(int argc, char** argv) {
  try {
    return stlrefine::bench::run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "stlrefine_slice_bench: " << e.what() << '\n';
    return 1;
  }
}
