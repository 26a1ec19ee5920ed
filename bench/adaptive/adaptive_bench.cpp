// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_adaptive_bench: Labsik and Greiner's adaptive comparison (section 6: the cat,
// 728 triangles, refined adaptively at a dihedral criterion of 20 and 10 degrees to 9358 and
// 34228 triangles by interpolatory sqrt3 against 13364 and 49908 by the modified butterfly,
// "a reduction by about 30%") on our meshes: triangles made by adaptive sqrt3-interp and
// by adaptive butterfly (red-green 1-to-4) at the same dihedral criterion, next to the
// uniform counts at the levels they reached. Then the same at equal chordal tolerance
// (adaptive_tol, mm): faces of adaptive sqrt3-interp, adaptive butterfly and of the uniform
// level each scheme needs for the same deviation, with the largest deviation of each output
// from its scheme's uniform level at the cap (and, for the spheres, from the true sphere).
// Markdown on stdout. Hand-run, never a test.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "core/features/features.h"
#include "core/geometry/point_triangle.h"
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
  //! Chordal tolerances (mm) of the equal-tolerance table, and its level caps (the
  //! reference of each scheme is its uniform level at the cap: 3^4 = 81 and 4^3 = 64
  //! times the input's faces).
  std::vector<double> tols{0.05, 0.01};
  int tol_sqrt3_cap = 4;
  int tol_split4_cap = 3;
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
    r.over_at_cap = adaptive.remaining(stencil, 0, angle).count;
  return r;
}

// --- distance from points to a triangle mesh (a uniform grid of triangle bounding boxes)

class MeshDistance {
 public:
  explicit MeshDistance(const Mesh& m) : m_(m) {
    lo_ = hi_ = m.position(VertexId(0));
    for (const Vec3& p : m.positions()) {
      lo_ = {std::min(lo_.x, p.x), std::min(lo_.y, p.y), std::min(lo_.z, p.z)};
      hi_ = {std::max(hi_.x, p.x), std::max(hi_.y, p.y), std::max(hi_.z, p.z)};
    }
    // About two triangles per cell.
    const Vec3 size = hi_ - lo_;
    const double volume = std::max(size.x, 1e-9) * std::max(size.y, 1e-9) * std::max(size.z, 1e-9);
    cell_ = std::cbrt(volume / std::max<double>(1, m.num_faces() / 2.0));
    cell_ = std::max({cell_, size.x / 512, size.y / 512, size.z / 512, 1e-9});
    for (int k = 0; k < 3; ++k) n_[k] = std::max(1, int(std::ceil(coord(size, k) / cell_)) + 1);
    start_.assign(std::size_t(n_[0]) * n_[1] * n_[2] + 1, 0);
    std::vector<std::pair<std::size_t, std::uint32_t>> entries;
    for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
      const auto [a, b, c] = m.face_vertices(FaceId(f));
      std::array<int, 3> l{}, h{};
      for (int k = 0; k < 3; ++k) {
        const double lo =
            std::min({coord(m.position(a), k), coord(m.position(b), k), coord(m.position(c), k)});
        const double hi =
            std::max({coord(m.position(a), k), coord(m.position(b), k), coord(m.position(c), k)});
        l[k] = index(lo, k);
        h[k] = index(hi, k);
      }
      for (int x = l[0]; x <= h[0]; ++x)
        for (int y = l[1]; y <= h[1]; ++y)
          for (int z = l[2]; z <= h[2]; ++z) entries.emplace_back(cell(x, y, z), f);
    }
    std::sort(entries.begin(), entries.end());
    faces_.reserve(entries.size());
    for (const auto& [c, f] : entries) {
      ++start_[c + 1];
      faces_.push_back(f);
    }
    for (std::size_t i = 1; i < start_.size(); ++i) start_[i] += start_[i - 1];
  }

  //! Distance from p to the mesh: cells in growing shells around p's cell until the best
  //! distance found is below the shell's distance.
  double operator()(const Vec3& p) const { return nearest(p).first; }

  //! The distance from p to the mesh and the nearest face.
  std::pair<double, std::uint32_t> nearest(const Vec3& p) const {
    std::uint32_t face = 0;
    std::array<int, 3> c{};
    for (int k = 0; k < 3; ++k) c[k] = index(coord(p, k), k);
    double best = std::numeric_limits<double>::max();
    const int max_r = std::max({n_[0], n_[1], n_[2]});
    for (int r = 0; r <= max_r; ++r) {
      for (int x = c[0] - r; x <= c[0] + r; ++x)
        for (int y = c[1] - r; y <= c[1] + r; ++y)
          for (int z = c[2] - r; z <= c[2] + r; ++z) {
            if (std::max({std::abs(x - c[0]), std::abs(y - c[1]), std::abs(z - c[2])}) != r)
              continue;
            if (x < 0 || y < 0 || z < 0 || x >= n_[0] || y >= n_[1] || z >= n_[2]) continue;
            const std::size_t id = cell(x, y, z);
            for (std::size_t i = start_[id]; i < start_[id + 1]; ++i) {
              const auto [a, b, cc] = m_.face_vertices(FaceId(faces_[i]));
              const double d =
                  point_triangle_distance(p, m_.position(a), m_.position(b), m_.position(cc));
              if (d < best) best = d, face = faces_[i];
            }
          }
      if (best <= r * cell_) break;  // every unvisited cell is at least r cells away
    }
    return {best, face};
  }

 private:
  static double coord(const Vec3& p, int k) { return k == 0 ? p.x : k == 1 ? p.y : p.z; }
  int index(double v, int k) const {
    return std::clamp(int((v - coord(lo_, k)) / cell_), 0, n_[k] - 1);
  }
  std::size_t cell(int x, int y, int z) const { return (std::size_t(z) * n_[1] + y) * n_[0] + x; }
  const Mesh& m_;
  Vec3 lo_, hi_;
  double cell_ = 1;
  std::array<int, 3> n_{};
  std::vector<std::size_t> start_;
  std::vector<std::uint32_t> faces_;
};

//! Points on every face of m (its centroid, the midpoints of its edges and the points
//! (2/3, 1/6, 1/6)), passed to fn: an interpolating output's vertices are the reference's
//! own, so its deviation is inside the faces.
template <class Fn>
void for_each_sample(const Mesh& m, Fn&& fn) {
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [ia, ib, ic] = m.face_vertices(FaceId(f));
    const Vec3 a = m.position(ia), b = m.position(ib), c = m.position(ic);
    fn((a + b + c) * (1.0 / 3.0));
    fn(0.5 * (a + b));
    fn(0.5 * (b + c));
    fn(0.5 * (c + a));
    fn((4.0 * a + b + c) * (1.0 / 6.0));
    fn((a + 4.0 * b + c) * (1.0 / 6.0));
    fn((a + b + 4.0 * c) * (1.0 / 6.0));
  }
}

double max_deviation(const Mesh& m, const MeshDistance& reference) {
  double worst = 0;
  for_each_sample(m, [&](const Vec3& p) { worst = std::max(worst, reference(p)); });
  return worst;
}

//! For the sphere inputs (radius 10 about the origin): the largest | |p| - 10 | sampled.
double sphere_deviation(const Mesh& m) {
  double worst = 0;
  for_each_sample(m, [&](const Vec3& p) { worst = std::max(worst, std::abs(norm(p) - 10.0)); });
  return worst;
}

Level uniform(const Level& input, const char* scheme, int levels) {
  const auto s = make_scheme(scheme);
  Level level = input;
  StepStats stats;
  for (int i = 0; i < levels; ++i) level = s->refine_once(level, stats);
  return level;
}

struct TolRun {
  std::size_t faces = 0;
  int levels = 0;
  double dev = 0, true_dev = -1, seconds = 0;
};

TolRun tol_sqrt3(const Level& input, double tol, int cap, const MeshDistance& reference,
                 bool sphere) {
  const auto scheme = make_scheme("sqrt3-interp");
  const auto t0 = Clock::now();
  AdaptiveSqrt3 adaptive(input, *adaptive_sqrt3_scheme(*scheme), {0, tol, cap});
  adaptive.run(std::uint64_t{1} << 31);
  const Level out = adaptive.result();
  TolRun r;
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.faces = out.mesh.num_faces();
  r.levels = adaptive.stats().levels;
  r.dev = max_deviation(out.mesh, reference);
  if (sphere) r.true_dev = sphere_deviation(out.mesh);
  return r;
}

TolRun tol_butterfly(const Level& input, double tol, int cap, const MeshDistance& reference,
                     bool sphere) {
  const auto scheme = make_scheme("butterfly");
  const Split4Stencil& stencil = *adaptive_scheme(*scheme);
  const auto t0 = Clock::now();
  AdaptiveSplit4 adaptive(input);
  StepStats stats;
  TolRun r;
  for (int i = 1; i <= cap; ++i) {
    AdaptiveStepStats step;
    if (!adaptive.step(stencil, tol, std::uint64_t{1} << 31, stats, step)) break;
    r.levels = i;
  }
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.faces = adaptive.level().mesh.num_faces();
  r.dev = max_deviation(adaptive.level().mesh, reference);
  if (sphere) r.true_dev = sphere_deviation(adaptive.level().mesh);
  return r;
}

//! Which output faces of adaptive sqrt3-interp at tol are farther than tol from the uniform
//! level at the cap: every vertex of each uniform level k <= cap is given to its nearest
//! output face, whose e_k is the largest distance given to it (nondecreasing in k for an
//! interpolating scheme, whose levels keep their vertices; e_cap is what the unit test checks).
//! Lists the worst faces: level, valences, e_k / tol, and where the farthest point lies.
void diagnose(const Level& input, double tol, int cap, std::size_t list) {
  const auto scheme = make_scheme("sqrt3-interp");
  AdaptiveSqrt3 adaptive(input, *adaptive_sqrt3_scheme(*scheme), {0, tol, cap});
  adaptive.run(std::uint64_t{1} << 31);
  std::vector<std::uint8_t> face_level;
  const Level out = adaptive.result(&face_level);
  const Mesh& m = out.mesh;
  const MeshDistance dist(m);
  std::vector<std::vector<double>> e(cap + 1, std::vector<double>(m.num_faces(), 0.0));
  std::vector<Vec3> worst_point(m.num_faces());
  for (int k = 1; k <= cap; ++k) {
    const Level u = uniform(input, "sqrt3-interp", k);
    for (const Vec3& p : u.mesh.positions()) {
      const auto [d, f] = dist.nearest(p);
      if (d > e[k][f] && k == cap) worst_point[f] = p;
      e[k][f] = std::max(e[k][f], d);
    }
  }
  std::vector<std::size_t> faces_at(cap + 2, 0), over_at(cap + 2, 0);
  double worst = 0;
  std::vector<std::uint32_t> over;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const int l = face_level[f];
    ++faces_at[l];
    worst = std::max(worst, e[cap][f]);
    if (e[cap][f] <= tol) continue;
    ++over_at[l];
    over.push_back(f);
  }
  std::sort(over.begin(), over.end(),
            [&](std::uint32_t x, std::uint32_t y) { return e[cap][x] > e[cap][y]; });
  if (over.size() > list) over.resize(list);
  for (std::uint32_t f : over) {
    const int l = face_level[f];
    const auto [a, b, c] = m.face_vertices(FaceId(f));
    int sharp = 0;
    for (int k = 0; k < 3; ++k) sharp += out.features.is_sharp(m.edge(HalfedgeId(3 * f + k)));
    std::printf("face %u level %d valences %d %d %d (input: %d%d%d) sharp edges %d  e_k/tol:", f, l,
                m.valence(a), m.valence(b), m.valence(c), a.idx < input.mesh.num_vertices(),
                b.idx < input.mesh.num_vertices(), c.idx < input.mesh.num_vertices(), sharp);
    for (int k = 1; k <= cap; ++k) std::printf(" %.2f", e[k][f] / tol);
    {  // where the farthest point is: barycentric over the face, and its height above it
      const Vec3 A = m.position(a), B = m.position(b), C = m.position(c), p = worst_point[f];
      const Vec3 n = cross(B - A, C - A);
      const double n2 = dot(n, n);
      const double u = dot(cross(C - B, p - B), n) / n2, v = dot(cross(A - C, p - C), n) / n2;
      std::printf("  at (%.2f %.2f %.2f) plane %.2f", u, v, 1 - u - v,
                  std::abs(dot(p - A, n)) / std::sqrt(n2) / tol);
    }
    std::printf("\n");
  }
  std::printf("tol %g cap %d: %zu faces, worst %.5f (%.2f tol); by level faces/over:", tol, cap,
              std::size_t(m.num_faces()), worst, worst / tol);
  for (int l = 0; l <= cap + 1; ++l) std::printf(" L%d %zu/%zu", l, faces_at[l], over_at[l]);
  std::printf("\n");
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
  app.add_option("--tols", o.tols, "Chordal tolerances (mm) of the equal-tolerance table")
      ->capture_default_str();
  app.add_option("--tol-sqrt3-cap", o.tol_sqrt3_cap, "max_level of sqrt3-interp there")
      ->capture_default_str();
  app.add_option("--tol-split4-cap", o.tol_split4_cap, "max_level of butterfly there")
      ->capture_default_str();
  std::vector<double> diagnose_tols;
  std::size_t diagnose_list = 40;
  app.add_option("--diagnose", diagnose_tols,
                 "Only list the faces of adaptive sqrt3-interp over these tolerances (cap "
                 "--tol-sqrt3-cap) and stop");
  app.add_option("--diagnose-list", diagnose_list, "Faces listed per run")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  auto load = [&](const std::string& name) {
    std::cerr << "reading " << name << '\n';
    return name == "icosphere" ? build_mesh(icosphere()).mesh
                               : build_mesh(weld(read_stl_file(fs::path(o.mesh_dir) / name))).mesh;
  };
  if (!diagnose_tols.empty()) {
    for (const std::string& name : o.inputs) {
      const Mesh mesh = load(name);
      const Level input{mesh, detect_features(mesh, {o.crease_angle})};
      for (double tol : diagnose_tols) {
        std::printf("## %s\n", name.c_str());
        diagnose(input, tol, o.tol_sqrt3_cap, diagnose_list);
      }
    }
    return 0;
  }

  std::cout << "sqrt3-interp max_level " << o.sqrt3_cap << ", butterfly max_level " << o.split4_cap
            << ", crease angle " << o.crease_angle
            << "°. Refined = triangles (sqrt3) or red triangles (butterfly) split because the "
               "criterion asked + to close the mesh; over at cap = faces (sqrt3) or edges "
               "(butterfly) still over the angle at the level cap.\n\n"
            << "Uniform = faces of uniform refinement to the level the adaptive run reached.\n\n"
            << "| input | faces | angle | sqrt3-interp | levels | uniform | over at cap | refined "
               "| s | edge closure | butterfly | levels | uniform | over at cap | refined | s | "
               "sqrt3 / butterfly | edge closure / butterfly |\n"
               "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  auto pow_faces = [](std::size_t faces, int base, int levels) {
    for (int i = 0; i < levels; ++i) faces *= std::size_t(base);
    return faces;
  };
  for (const std::string& name : o.inputs) {
    const Mesh mesh = load(name);
    const Level input{mesh, detect_features(mesh, {o.crease_angle})};
    for (double angle : o.angles) {
      std::cerr << "  " << name << " at " << angle << " degrees\n";
      const Run s = run_sqrt3(input, angle, o.sqrt3_cap, Sqrt3Closure::Stencil);
      const Run e = run_sqrt3(input, angle, o.sqrt3_cap, Sqrt3Closure::EdgeNeighbours);
      const Run b = run_butterfly(input, angle, o.split4_cap);
      char line[512];
      std::snprintf(
          line, sizeof line,
          "| %s | %s | %g° | %s | %d | %s | %zu | %zu + %zu | %.3f | %s | %s | %d | %s | %zu | "
          "%zu + %zu | %.3f | %.2f | %.2f |",
          name.c_str(), thousands(mesh.num_faces()).c_str(), angle, thousands(s.faces).c_str(),
          s.levels, thousands(pow_faces(mesh.num_faces(), 3, s.levels)).c_str(), s.over_at_cap,
          s.by_criterion, s.by_closure, s.seconds, thousands(e.faces).c_str(),
          thousands(b.faces).c_str(), b.levels,
          thousands(pow_faces(mesh.num_faces(), 4, b.levels)).c_str(), b.over_at_cap,
          b.by_criterion, b.by_closure, b.seconds, double(s.faces) / double(b.faces),
          double(e.faces) / double(b.faces));
      std::cout << line << std::endl;
    }
  }

  if (o.tols.empty()) return 0;
  std::cout << "\nEqual chordal tolerance (adaptive_tol): sqrt3-interp max_level "
            << o.tol_sqrt3_cap << ", butterfly max_level " << o.tol_split4_cap
            << ". Dev = the largest distance (mm) of points sampled on every face (centroid, "
               "edge midpoints, three inner points) from the same scheme's uniform level at "
               "its cap; true = from the sphere of radius 10 (sphere inputs only). Uniform = "
               "faces of the first uniform level of that scheme whose own dev is within the "
               "tolerance (its level in brackets; \"(cap)\": no level below the cap is).\n\n"
            << "| input | faces | tol mm | sqrt3-interp | levels | dev | true | uniform sqrt3 "
               "| s | butterfly | levels | dev | true | uniform butterfly | s | sqrt3 / "
               "butterfly |\n"
               "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  for (const std::string& name : o.inputs) {
    const Mesh mesh = load(name);
    const bool sphere = name.find("sphere") != std::string::npos;
    const Level input{mesh, detect_features(mesh, {o.crease_angle})};
    std::cerr << "  " << name << ": references\n";
    const Level ref_s = uniform(input, "sqrt3-interp", o.tol_sqrt3_cap);
    const Level ref_b = uniform(input, "butterfly", o.tol_split4_cap);
    const MeshDistance dist_s(ref_s.mesh), dist_b(ref_b.mesh);
    // Deviation of each uniform level below the cap from the cap.
    std::vector<double> dev_s, dev_b;
    for (int l = 0; l < o.tol_sqrt3_cap; ++l)
      dev_s.push_back(max_deviation(uniform(input, "sqrt3-interp", l).mesh, dist_s));
    for (int l = 0; l < o.tol_split4_cap; ++l)
      dev_b.push_back(max_deviation(uniform(input, "butterfly", l).mesh, dist_b));
    auto needed = [&](const std::vector<double>& dev, double tol, int base) {
      for (std::size_t l = 0; l < dev.size(); ++l)
        if (dev[l] <= tol)
          return thousands(pow_faces(mesh.num_faces(), base, int(l))) + " (" + std::to_string(l) +
                 ")";
      return "≥ " + thousands(pow_faces(mesh.num_faces(), base, int(dev.size()))) + " (cap)";
    };
    for (double tol : o.tols) {
      std::cerr << "  " << name << " at tol " << tol << '\n';
      const TolRun s = tol_sqrt3(input, tol, o.tol_sqrt3_cap, dist_s, sphere);
      const TolRun b = tol_butterfly(input, tol, o.tol_split4_cap, dist_b, sphere);
      auto true_text = [](double d) { return d < 0 ? std::string("–") : std::to_string(d); };
      char line[512];
      std::snprintf(line, sizeof line,
                    "| %s | %s | %g | %s | %d | %.4f | %s | %s | %.3f | %s | %d | %.4f | %s | %s "
                    "| %.3f | %.2f |",
                    name.c_str(), thousands(mesh.num_faces()).c_str(), tol,
                    thousands(s.faces).c_str(), s.levels, s.dev, true_text(s.true_dev).c_str(),
                    needed(dev_s, tol, 3).c_str(), s.seconds, thousands(b.faces).c_str(), b.levels,
                    b.dev, true_text(b.true_dev).c_str(), needed(dev_b, tol, 4).c_str(), b.seconds,
                    double(s.faces) / double(b.faces));
      std::cout << line << std::endl;
    }
  }
  return 0;
}
