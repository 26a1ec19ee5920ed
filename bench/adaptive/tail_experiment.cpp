// Experiment: how the uniform sqrt3-interp surfaces S_k approach the cap surface over a
// coarse triangle T (in T's prism), to design a tolerance criterion.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/features/features.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/mesh/indexed_soup.h"
#include "core/refine.h"
#include "core/schemes/scheme.h"

using namespace stlrefine;

namespace {
double kMargin = 1.0;

struct Grid {
  const Mesh* m = nullptr;
  double cell = 1;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> cells;
  static std::int64_t key(std::int64_t i, std::int64_t j, std::int64_t k) {
    return (i & 0x1fffff) | ((j & 0x1fffff) << 21) | ((k & 0x1fffff) << 42);
  }
  std::int64_t idx(double x) const { return static_cast<std::int64_t>(std::floor(x / cell)); }
  Grid(const Mesh& mesh, double c) : m(&mesh), cell(c) {
    for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
      Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
      for (VertexId v : mesh.face_vertices(FaceId(f))) {
        const Vec3& p = mesh.position(v);
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      }
      for (auto i = idx(lo.x); i <= idx(hi.x); ++i)
        for (auto j = idx(lo.y); j <= idx(hi.y); ++j)
          for (auto k = idx(lo.z); k <= idx(hi.z); ++k) cells[key(i, j, k)].push_back(f);
    }
  }
  std::vector<std::uint32_t> near(const Vec3& lo, const Vec3& hi) const {
    std::vector<std::uint32_t> out;
    for (auto i = idx(lo.x); i <= idx(hi.x); ++i)
      for (auto j = idx(lo.y); j <= idx(hi.y); ++j)
        for (auto k = idx(lo.z); k <= idx(hi.z); ++k) {
          auto it = cells.find(key(i, j, k));
          if (it != cells.end()) out.insert(out.end(), it->second.begin(), it->second.end());
        }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }
};

struct Frame {
  Vec3 a, n;                       // origin, unit normal
  std::array<Vec3, 3> P;           // corners
  std::array<Vec3, 3> wall_n;      // inward normals of the prism walls
  double size = 0;
  double height(const Vec3& p) const { return dot(p - a, n); }
  bool inside(const Vec3& p, double eps = 0) const {
    for (int k = 0; k < 3; ++k)
      if (dot(p - P[k], wall_n[k]) < -eps * size) return false;
    return true;
  }
};

Frame frame_of(const Vec3& A, const Vec3& B, const Vec3& C) {
  Frame f;
  f.a = A;
  f.P = {A, B, C};
  f.n = normalized(cross(B - A, C - A));
  for (int k = 0; k < 3; ++k) {
    const Vec3 e = f.P[(k + 1) % 3] - f.P[k];
    f.wall_n[k] = normalized(cross(f.n, e));
    f.size = std::max(f.size, norm(e));
  }
  return f;
}

// Max |height| of triangle (x,y,z) clipped to T's prism; -1 if it misses it.
double clipped_max(const Frame& f, const Vec3& x, const Vec3& y, const Vec3& z) {
  std::vector<Vec3> poly{x, y, z}, next;
  for (int k = 0; k < 3; ++k) {
    next.clear();
    for (std::size_t i = 0; i < poly.size(); ++i) {
      const Vec3 p = poly[i], q = poly[(i + 1) % poly.size()];
      const double dp = dot(p - f.P[k], f.wall_n[k]), dq = dot(q - f.P[k], f.wall_n[k]);
      if (dp >= 0) next.push_back(p);
      if ((dp >= 0) != (dq >= 0)) next.push_back(p + (dp / (dp - dq)) * (q - p));
    }
    poly.swap(next);
    if (poly.empty()) return -1;
  }
  double h = 0;
  for (const Vec3& p : poly) h = std::max(h, std::abs(f.height(p)));
  return h;
}

// Max |height| of S (mesh m) over T's prism: the triangles reached from T's corners through
// triangles that overlap the prism (T's own sheet).
double surface_max(const Frame& f, const Mesh& m, const Grid& g) {
  const double margin = kMargin * f.size;
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& p : f.P) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  lo = lo - Vec3{margin, margin, margin};
  hi = hi + Vec3{margin, margin, margin};
  std::unordered_map<std::uint32_t, double> cand;
  std::vector<std::uint32_t> stack;
  for (std::uint32_t t : g.near(lo, hi)) {
    const auto [a, b, c] = m.face_vertices(FaceId(t));
    const Vec3 x = m.position(a), y = m.position(b), z = m.position(c);
    const double h = clipped_max(f, x, y, z);
    if (h < 0) continue;
    cand[t] = h;
    for (const Vec3& q : {x, y, z})
      for (const Vec3& corner : f.P)
        if (distance(q, corner) < 1e-12 * f.size) stack.push_back(t);
  }
  std::unordered_map<std::uint32_t, bool> seen;
  double best = 0;
  while (!stack.empty()) {
    const std::uint32_t t = stack.back();
    stack.pop_back();
    if (seen[t]) continue;
    seen[t] = true;
    best = std::max(best, cand[t]);
    for (std::uint32_t k = 0; k < 3; ++k) {
      const HalfedgeId tw = m.twin(HalfedgeId(3 * t + k));
      if (!tw.valid()) continue;
      const std::uint32_t u = tw.idx / 3;
      if (cand.count(u) && !seen[u]) stack.push_back(u);
    }
  }
  return best;
}

// Max |height| of S's vertices over T's prism.
double vertex_max(const Frame& f, const Mesh& m, const Grid& g) {
  const double margin = kMargin * f.size;
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& p : f.P) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  lo = lo - Vec3{margin, margin, margin};
  hi = hi + Vec3{margin, margin, margin};
  double best = 0;
  for (std::uint32_t t : g.near(lo, hi)) {
    for (VertexId v : m.face_vertices(FaceId(t))) {
      const Vec3 x = m.position(v);
      if (std::abs(f.height(x)) > margin || !f.inside(x)) continue;
      best = std::max(best, std::abs(f.height(x)));
    }
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argv[1];
  const int cap = std::atoi(argv[2]);
  const int src = std::atoi(argv[3]);  // level of the test triangles
  const std::size_t max_faces = argc > 4 ? std::atoi(argv[4]) : 3000;
  if (argc > 5) kMargin = std::atof(argv[5]);
  const Mesh mesh = build_mesh(weld(read_stl_file(path))).mesh;
  const Level input{mesh, detect_features(mesh, {35})};
  std::vector<Level> U;
  U.push_back(input);
  {
    const auto s = make_scheme("sqrt3-interp");
    StepStats stats;
    for (int k = 1; k <= cap; ++k) U.push_back(s->refine_once(U.back(), stats));
  }
  double edge = 0;
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    edge += distance(mesh.position(a), mesh.position(b));
  }
  edge /= mesh.num_faces();
  std::vector<Grid> grids;
  for (int k = 0; k <= cap; ++k) grids.emplace_back(U[k].mesh, edge);
  const Mesh& S = U[src].mesh;
  const std::size_t stride = std::max<std::size_t>(1, S.num_faces() / max_faces);
  std::printf("# face H_k (surface max over prism, k=src..cap) | V_k (vertex max)\n");
  for (std::uint32_t t = 0; t < S.num_faces(); t += stride) {
    const auto [a, b, c] = S.face_vertices(FaceId(t));
    const Frame f = frame_of(S.position(a), S.position(b), S.position(c));
    std::printf("%u %d %d %d |", t, S.valence(a), S.valence(b), S.valence(c));
    for (int k = src; k <= cap; ++k) std::printf(" %.6g", surface_max(f, U[k].mesh, grids[k]));
    std::printf(" |");
    for (int k = src; k <= cap; ++k) std::printf(" %.6g", vertex_max(f, U[k].mesh, grids[k]));
    std::printf("\n");
  }
  return 0;
}
