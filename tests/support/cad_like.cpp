// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/cad_like.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "core/mesh/build_mesh.h"
#include "tests/support/convex_hull.h"
#include "tests/support/random.h"

namespace stlrefine::test {
namespace {

using Tri = std::array<std::uint32_t, 3>;
constexpr double kPi = std::numbers::pi;

constexpr std::array<CadFamily, 9> kFamilies{
    CadFamily::CappedCylinder, CadFamily::Cone,       CadFamily::Torus,
    CadFamily::Tube,           CadFamily::Sphere,     CadFamily::Ellipsoid,
    CadFamily::Blob,           CadFamily::RoundedBox, CadFamily::Plate};
constexpr std::array<std::string_view, 9> kNames{
    "cylinder", "cone", "torus", "tube", "sphere", "ellipsoid", "blob", "rounded-box", "plate"};

//! A family's own stream: seeds that differ in one bit give unrelated meshes (splitmix64).
std::uint64_t mix(std::uint64_t seed, CadFamily family) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (static_cast<std::uint64_t>(family) + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

std::string fmt(const char* format, double a, double b = 0, double c = 0, double d = 0) {
  char buf[160];
  std::snprintf(buf, sizeof buf, format, a, b, c, d);
  return buf;
}

//! A chain of vertices along a curve with increasing parameters (angles).
struct Chain {
  std::vector<std::uint32_t> ids;
  std::vector<double> t;
  std::size_t size() const { return ids.size(); }
};

class Builder {
 public:
  Builder(CadFamily family, const CadParams& params) : rng(mix(params.seed, family)) {
    if (!(params.coarseness >= 0.25 && params.coarseness <= 4))
      throw std::invalid_argument("make_cad_shape: coarseness must be in [0.25, 4]");
    coarse = params.coarseness;
    shape.family = family;
    shape.name = cad_family_name(family);
  }

  Rng rng;
  double coarse = 1;
  CadShape shape;

  std::uint32_t vertex(const Vec3& p, bool crease) {
    shape.soup.positions.push_back(p);
    shape.on_crease.push_back(crease ? 1 : 0);
    return static_cast<std::uint32_t>(shape.soup.positions.size() - 1);
  }

  //! A dimension: `nominal` times a factor in [0.85, 1.15).
  double jittered(double nominal) { return nominal * rng.uniform(0.85, 1.15); }

  //! A vertex count for a curve `base` vertices long at coarseness 1, +-2, at least `min`.
  int count(double base, int min) {
    return std::max(min, static_cast<int>(std::lround(base / coarse)) + rng.integer(-2, 2));
  }
  //! ... different from every count in `others` (the next free one up).
  int count_unlike(double base, int min, std::initializer_list<int> others) {
    int n = count(base, min);
    while (std::find(others.begin(), others.end(), n) != others.end()) ++n;
    return n;
  }

  //! n angles around the circle: a random phase, each jittered by up to 35% of the mean
  //! spacing, then warped by w sin(t + phi) (denser on one side), strictly increasing in
  //! [t0, t0 + 2 pi) with t0 the first.
  std::vector<double> ring_angles(int n) {
    const double phase = rng.uniform(0, 2 * kPi / n);
    const double w = rng.uniform(0.05, 0.25), phi = rng.uniform(0, 2 * kPi);
    std::vector<double> t(n);
    for (int i = 0; i < n; ++i) {
      const double s = phase + 2 * kPi * (i + rng.uniform(-0.35, 0.35)) / n;
      t[i] = s + w * std::sin(s + phi) - w * std::sin(phi);  // monotone: 1 + w cos > 0
    }
    return t;
  }

  //! Parameters of an open curve on [0, len]: both ends and the n - 1 points between,
  //! jittered by up to 35% of the mean spacing.
  std::vector<double> open_params(int segments, double len) {
    std::vector<double> t{0};
    for (int i = 1; i < segments; ++i) t.push_back(len * (i + rng.uniform(-0.35, 0.35)) / segments);
    t.push_back(len);
    return t;
  }

  //! Consecutive vertices of a crease curve (closed: the last joins the first).
  void crease_chain(const std::vector<std::uint32_t>& ids, bool closed) {
    for (std::size_t k = 0; k + (closed ? 0 : 1) < ids.size(); ++k) {
      const std::uint32_t a = ids[k], b = ids[(k + 1) % ids.size()];
      shape.crease_edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }

  void tri(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    shape.soup.triangles.push_back({a, b, c});
  }

  //! Zips two open chains over the same parameter interval, A's and B's ends joined by the
  //! strip's side edges (A0, B0) and (A_last, B_last): at each step the chain whose next
  //! vertex comes first advances. Triangles (A_i, A_i+1, B_j) and (A_i, B_j+1, B_j).
  void zip_open(const Chain& a, const Chain& b) {
    const std::size_t first = shape.soup.triangles.size();
    std::size_t i = 0, j = 0;
    while (i + 1 < a.size() || j + 1 < b.size()) {
      if (j + 1 == b.size() || (i + 1 < a.size() && a.t[i + 1] <= b.t[j + 1])) {
        tri(a.ids[i], a.ids[i + 1], b.ids[j]);
        ++i;
      } else {
        tri(a.ids[i], b.ids[j + 1], b.ids[j]);
        ++j;
      }
    }
    shape.zipped_rims.push_back({a.size(), b.size()});
    orient_patch(first);
  }

  //! Zips two closed loops of angles (period 2 pi): B is rotated to start at its vertex
  //! nearest A's first, both are closed by repeating their first vertex one turn later.
  void zip_closed(const Chain& a, const Chain& b) {
    std::size_t j0 = 0;
    auto gap = [&](std::size_t j) { return std::abs(std::remainder(b.t[j] - a.t[0], 2 * kPi)); };
    for (std::size_t j = 1; j < b.size(); ++j)
      if (gap(j) < gap(j0)) j0 = j;
    Chain ac = a, bc;
    ac.ids.push_back(a.ids[0]);
    ac.t.push_back(a.t[0] + 2 * kPi);
    // Unwrap B from a start within half a turn of A's first angle.
    // (Each loop spans less than a turn: angles relative to j0 are in [0, 2 pi).)
    const double start = a.t[0] + std::remainder(b.t[j0] - a.t[0], 2 * kPi);
    for (std::size_t k = 0; k <= b.size(); ++k) {
      const std::size_t j = (j0 + k) % b.size();
      double rel = b.t[j] - b.t[j0];
      if (rel < 0) rel += 2 * kPi;
      bc.ids.push_back(b.ids[j]);
      bc.t.push_back(k == b.size() ? start + 2 * kPi : start + rel);
    }
    zip_open(ac, bc);
    shape.zipped_rims.back() = {a.size(), b.size()};
  }

  //! A fan from the `apex`-th vertex of a closed convex polygon to all its other edges.
  void fan_from(const std::vector<std::uint32_t>& polygon, std::size_t apex) {
    const std::size_t first = shape.soup.triangles.size(), n = polygon.size();
    for (std::size_t k = 1; k + 1 < n; ++k)
      tri(polygon[apex], polygon[(apex + k) % n], polygon[(apex + k + 1) % n]);
    orient_patch(first);
  }
  //! A fan from an extra vertex to every edge of the closed polygon.
  void fan_around(std::uint32_t centre, const std::vector<std::uint32_t>& polygon) {
    const std::size_t first = shape.soup.triangles.size(), n = polygon.size();
    for (std::size_t k = 0; k < n; ++k) tri(centre, polygon[k], polygon[(k + 1) % n]);
    orient_patch(first);
  }

  //! Each patch (a strip, a fan) is made with one winding; it is reversed as a whole when
  //! its triangles face into the solid on (area-weighted) average.
  void orient_patch(std::size_t first) {
    auto& tris = shape.soup.triangles;
    const auto& pos = shape.soup.positions;
    double vote = 0;
    for (std::size_t f = first; f < tris.size(); ++f) {
      const Vec3 &a = pos[tris[f][0]], &b = pos[tris[f][1]], &c = pos[tris[f][2]];
      const SurfacePoint s = shape.surface->closest_point((a + b + c) * (1.0 / 3));
      vote += dot(triangle_normal(a, b, c), s.normal + s.other_normal);
    }
    if (vote < 0)
      for (std::size_t f = first; f < tris.size(); ++f) std::swap(tris[f][1], tris[f][2]);
  }

  //! `n` random unit vectors no two closer than `min_angle` (radians), mapped by `map`;
  //! the hull of the mapped points (or of the directions themselves when `hull_of_dirs`)
  //! becomes the mesh. A degenerate draw is redrawn.
  template <class Map>
  void random_hull(int n, double min_angle, bool hull_of_dirs, Map map) {
    for (int attempt = 0;; ++attempt) {
      std::vector<Vec3> dirs;
      const double min_dot = std::cos(min_angle);
      while (static_cast<int>(dirs.size()) < n) {
        const Vec3 d = rng.unit_vector();
        bool ok = true;
        for (const Vec3& e : dirs) ok = ok && dot(d, e) < min_dot;
        if (ok) dirs.push_back(d);
      }
      std::vector<Vec3> points;
      for (const Vec3& d : dirs) points.push_back(map(d));
      try {
        auto tris = convex_hull(hull_of_dirs ? dirs : points);
        for (const Vec3& p : points) vertex(p, false);
        shape.soup.triangles = std::move(tris);
        return;
      } catch (const std::runtime_error&) {
        if (attempt == 20) throw;
      }
    }
  }

  //! Mean angular spacing of n points on the sphere, times a fraction: the minimum spacing.
  static double min_spacing(int n) { return 0.4 * std::sqrt(4 * kPi / n); }

  //! A rim: n vertices at ring_angles on the circle of radius r at height z (crease).
  Chain rim(int n, double r, double z, bool crease) {
    Chain c;
    c.t = ring_angles(n);
    for (const double t : c.t)
      c.ids.push_back(vertex({r * std::cos(t), r * std::sin(t), z}, crease));
    return c;
  }
};

// --- families --------------------------------------------------------------------------------

//! Side zipped between two rims, both caps fanned from one rim vertex each.
CadShape zipped_solid(Builder& b, double r0, double r1, double h, double base0, double base1) {
  b.shape.surface = revolution_surface({ProfilePiece::segment({0, 0}, {r0, 0}),
                                        ProfilePiece::segment({r0, 0}, {r1, h}),
                                        ProfilePiece::segment({r1, h}, {0, h})});
  const int n0 = b.count(base0, 6);
  const int n1 = b.count_unlike(base1, 6, {n0});
  const Chain bottom = b.rim(n0, r0, 0, true), top = b.rim(n1, r1, h, true);
  b.crease_chain(bottom.ids, true);
  b.crease_chain(top.ids, true);
  b.zip_closed(bottom, top);
  b.fan_from(bottom.ids, static_cast<std::size_t>(b.rng.integer(0, n0 - 1)));
  b.fan_from(top.ids, static_cast<std::size_t>(b.rng.integer(0, n1 - 1)));
  b.shape.description =
      (r0 == r1 ? fmt("r %.2f", r0) : fmt("r %.2f -> %.2f", r0, r1)) +
      fmt(", h %.2f mm; rims of %.0f / %.0f jittered vertices, side zipped, caps fanned from one "
          "rim vertex",
          h, n0, n1);
  return std::move(b.shape);
}

CadShape cylinder(Builder& b) {
  const double r = b.jittered(10), h = b.jittered(20);
  CadShape s = zipped_solid(b, r, r, h, 23, 37);
  s.description = "capped cylinder " + s.description;
  return s;
}

CadShape cone(Builder& b) {
  const double r0 = b.jittered(10), r1 = b.jittered(5), h = b.jittered(15);
  CadShape s = zipped_solid(b, r0, r1, h, 33, 19);
  s.description = "frustum " + s.description;
  return s;
}

CadShape torus(Builder& b) {
  const double big = b.jittered(10), small = b.jittered(3.5);
  b.shape.surface = revolution_surface({ProfilePiece::arc({big, 0}, small, -kPi, kPi)});
  const int rings = b.count(24, 6);
  const std::vector<double> u = b.ring_angles(rings);
  std::vector<int> counts(rings);
  for (int i = 0; i < rings; ++i)  // the last ring differs from the first too
    counts[i] =
        b.count_unlike(12, 5, {i > 0 ? counts[i - 1] : -1, i + 1 == rings ? counts[0] : -1});
  std::vector<Chain> ring(rings);
  for (int i = 0; i < rings; ++i) {
    ring[i].t = b.ring_angles(counts[i]);
    for (const double v : ring[i].t) {
      const double rho = big + small * std::cos(v);
      ring[i].ids.push_back(
          b.vertex({rho * std::cos(u[i]), rho * std::sin(u[i]), small * std::sin(v)}, false));
    }
  }
  for (int i = 0; i < rings; ++i) b.zip_closed(ring[i], ring[(i + 1) % rings]);
  int lo = counts[0], hi = counts[0];
  for (const int c : counts) lo = std::min(lo, c), hi = std::max(hi, c);
  b.shape.description =
      fmt("torus R %.2f r %.2f mm; %.0f rings of %.0f", big, small, rings, lo) +
      fmt("-%.0f vertices at warped jittered angles, each its own phase, zipped ring to ring", hi);
  return std::move(b.shape);
}

CadShape tube(Builder& b) {
  const double ro = b.jittered(10), ri = b.jittered(6), h = b.jittered(15);
  b.shape.surface = revolution_surface(
      {ProfilePiece::segment({ri, 0}, {ro, 0}), ProfilePiece::segment({ro, 0}, {ro, h}),
       ProfilePiece::segment({ro, h}, {ri, h}), ProfilePiece::segment({ri, h}, {ri, 0})});
  std::array<int, 4> n{};
  const std::array<double, 4> base{37, 29, 23, 17};
  for (std::size_t k = 0; k < 4; ++k) n[k] = b.count_unlike(base[k], 6, {n[0], n[1], n[2]});
  const Chain outer_bottom = b.rim(n[0], ro, 0, true), outer_top = b.rim(n[1], ro, h, true);
  const Chain inner_bottom = b.rim(n[2], ri, 0, true), inner_top = b.rim(n[3], ri, h, true);
  for (const Chain* rim : {&outer_bottom, &outer_top, &inner_bottom, &inner_top})
    b.crease_chain(rim->ids, true);
  b.zip_closed(outer_bottom, outer_top);
  b.zip_closed(inner_bottom, inner_top);
  b.zip_closed(outer_bottom, inner_bottom);
  b.zip_closed(outer_top, inner_top);
  b.shape.description =
      fmt("tube r %.2f .. %.2f, h %.2f mm; ", ri, ro, h) +
      fmt("rims of %.0f / %.0f (outer) and %.0f / %.0f (inner) vertices, walls and annulus caps "
          "zipped",
          n[0], n[1], n[2], n[3]);
  return std::move(b.shape);
}

CadShape sphere(Builder& b) {
  const double r = b.jittered(10);
  b.shape.surface = sphere_surface({0, 0, 0}, r);
  const int n = b.count(300 / b.coarse, 12);
  b.random_hull(n, Builder::min_spacing(n), false, [&](const Vec3& d) { return d * r; });
  b.shape.description = fmt("sphere r %.2f mm; convex hull of %.0f random points", r, n);
  return std::move(b.shape);
}

CadShape ellipsoid(Builder& b) {
  const double ax = b.jittered(12), ay = b.jittered(9), az = b.jittered(6.5);
  b.shape.surface = ellipsoid_surface(ax, ay, az);
  const int n = b.count(300 / b.coarse, 12);
  b.random_hull(n, Builder::min_spacing(n), false, [&](const Vec3& d) {
    return Vec3{ax * d.x, ay * d.y, az * d.z};
  });
  b.shape.description = fmt("ellipsoid %.2f x %.2f x %.2f mm (semi-axes); ", ax, ay, az) +
                        fmt("convex hull of %.0f random points", n);
  return std::move(b.shape);
}

CadShape blob(Builder& b) {
  const double r = b.jittered(10);
  std::array<double, kBlobHarmonics> c{};
  double amplitude = 0;
  for (double& ck : c) {
    ck = (b.rng.uniform() < 0.5 ? -1 : 1) * b.rng.uniform(0.03, 0.07);
    amplitude += std::abs(ck);
  }
  b.shape.surface = blob_surface(r, c);
  const int n = b.count(300 / b.coarse, 12);
  // The hull of the directions, mapped out: a valid triangulation of any star shape.
  b.random_hull(n, Builder::min_spacing(n), true,
                [&](const Vec3& d) { return blob_point(r, c, d); });
  b.shape.description =
      fmt("blob r %.2f mm, 7 harmonics up to degree 3 with coefficients summing to %.2f in "
          "magnitude; hull of %.0f random directions mapped out",
          r, amplitude, n);
  return std::move(b.shape);
}

CadShape rounded_box(Builder& b) {
  const Vec3 half{b.jittered(20), b.jittered(15), b.jittered(10)};
  const double r = b.jittered(4);
  b.shape.surface = rounded_box_surface(half, r);
  const std::array<double, 3> inner{half.x - r, half.y - r, half.z - r};
  auto unit = [](int axis) {
    std::array<double, 3> e{0, 0, 0};
    e[axis] = 1;
    return e;
  };
  auto corner_centre = [&](int corner) {
    std::array<double, 3> c{};
    for (int k = 0; k < 3; ++k) c[k] = (corner >> k & 1 ? 1 : -1) * inner[k];
    return c;
  };
  auto sign = [](int corner, int axis) { return corner >> axis & 1 ? 1.0 : -1.0; };
  auto at = [&](int corner, const std::array<double, 3>& n) {
    const auto c = corner_centre(corner);
    return Vec3{c[0] + r * n[0], c[1] + r * n[1], c[2] + r * n[2]};
  };

  // The face points: corner c pushed out along its axis k (the flat faces' corners).
  std::array<std::array<std::uint32_t, 3>, 8> face_point{};
  for (int corner = 0; corner < 8; ++corner)
    for (int k = 0; k < 3; ++k) {
      auto e = unit(k);
      e[k] *= sign(corner, k);
      face_point[corner][k] = b.vertex(at(corner, e), false);
    }
  // The arcs: at corner c, the quarter circle with n_k = 0 from face point i = k+1 (psi = 0)
  // to j = k+2 (psi = pi/2). The two ends of each fillet are sampled differently.
  std::array<std::array<Chain, 3>, 8> arc;
  std::array<std::array<int, 3>, 8> segments{};
  for (int k = 0; k < 3; ++k)
    for (int corner = 0; corner < 8; ++corner) {
      if (corner >> k & 1) continue;  // the fillet along k from this corner to its mirror
      const int mirror = corner | (1 << k);
      segments[corner][k] = b.count(4, 1);
      segments[mirror][k] = b.count_unlike(4, 1, {segments[corner][k]});
    }
  for (int corner = 0; corner < 8; ++corner)
    for (int k = 0; k < 3; ++k) {
      const int i = (k + 1) % 3, j = (k + 2) % 3;
      Chain& c = arc[corner][k];
      c.t = b.open_params(segments[corner][k], kPi / 2);
      for (std::size_t l = 0; l < c.t.size(); ++l) {
        if (l == 0) {
          c.ids.push_back(face_point[corner][i]);
        } else if (l + 1 == c.t.size()) {
          c.ids.push_back(face_point[corner][j]);
        } else {
          std::array<double, 3> n{0, 0, 0};
          n[i] = sign(corner, i) * std::cos(c.t[l]);
          n[j] = sign(corner, j) * std::sin(c.t[l]);
          c.ids.push_back(b.vertex(at(corner, n), false));
        }
      }
    }
  // Fillets: strips zipped between their end arcs.
  for (int k = 0; k < 3; ++k)
    for (int corner = 0; corner < 8; ++corner)
      if (!(corner >> k & 1)) b.zip_open(arc[corner][k], arc[corner | (1 << k)][k]);
  // Flat faces: two big triangles (a random diagonal) or a fan from an inner point.
  int fans = 0;
  for (int k = 0; k < 3; ++k)
    for (const int s : {0, 1}) {
      const int i = (k + 1) % 3, j = (k + 2) % 3;
      // Corners of face (k, s) in cyclic order: (i, j) signs (-,-), (+,-), (+,+), (-,+).
      std::vector<std::uint32_t> quad;
      constexpr std::array<std::pair<int, int>, 4> kCycle{{{0, 0}, {1, 0}, {1, 1}, {0, 1}}};
      for (const auto& [si, sj] : kCycle)
        quad.push_back(face_point[(s << k) | (si << i) | (sj << j)][k]);
      if (b.rng.uniform() < 0.5) {
        b.fan_from(quad, static_cast<std::size_t>(b.rng.integer(0, 3)));
      } else {
        std::array<double, 3> p{};
        p[k] = (s ? 1 : -1) * std::array<double, 3>{half.x, half.y, half.z}[k];
        p[i] = b.rng.uniform(-0.7, 0.7) * inner[i];
        p[j] = b.rng.uniform(-0.7, 0.7) * inner[j];
        b.fan_around(b.vertex({p[0], p[1], p[2]}, false), quad);
        ++fans;
      }
    }
  // Corners: a fan from an inner point of the octant to its three arcs.
  for (int corner = 0; corner < 8; ++corner) {
    std::array<double, 3> n{};
    for (int k = 0; k < 3; ++k) n[k] = sign(corner, k) * b.rng.uniform(0.7, 1.3);
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& x : n) x /= len;
    std::vector<std::uint32_t> loop;
    for (const int k : {2, 0, 1})  // x -> y, y -> z, z -> x
      for (std::size_t l = 0; l + 1 < arc[corner][k].size(); ++l)
        loop.push_back(arc[corner][k].ids[l]);
    b.fan_around(b.vertex(at(corner, n), false), loop);
  }
  int lo = 99, hi = 0;
  for (const auto& s : segments)
    for (const int m : s) lo = std::min(lo, m), hi = std::max(hi, m);
  b.shape.description =
      fmt("rounded box %.1f x %.1f x %.1f mm, ", 2 * half.x, 2 * half.y, 2 * half.z) +
      fmt("fillet radius %.2f mm; arcs of %.0f-%.0f segments (each fillet's two ends differ), "
          "fillets zipped, %.0f of 6 faces fanned, corners fanned",
          r, lo, hi, fans);
  return std::move(b.shape);
}

CadShape plate(Builder& b) {
  constexpr double kWidth = 203, kLength = 305, kThickness = 12.7;
  const double crease = b.rng.uniform(6, 12) * kPi / 180;
  // The side arc meets the bottom at (x_e, 0) and the top at (x_e, T), its normal there
  // `crease` off the flat face's, and reaches x = W / 2.
  const double rho = 0.5 * kThickness / std::cos(crease);
  const double xc = 0.5 * kWidth - rho, xe = xc + rho * std::sin(crease);
  const double a_end = kPi / 2 - crease;
  const double y0 = -0.5 * kLength, y1 = 0.5 * kLength;
  b.shape.surface =
      extrusion_surface({ProfilePiece::segment({-xe, 0}, {xe, 0}),
                         ProfilePiece::arc({xc, 0.5 * kThickness}, rho, -a_end, a_end),
                         ProfilePiece::segment({xe, kThickness}, {-xe, kThickness}),
                         ProfilePiece::arc({-xc, 0.5 * kThickness}, rho, kPi - a_end, kPi + a_end)},
                        y0, y1);

  // Each side arc at each end, sampled on its own: (bottom corner .. top corner) on the
  // right, (top .. bottom) on the left, all crease vertices.
  std::array<int, 4> segments{};
  segments[0] = b.count(8, 2);
  segments[1] = b.count_unlike(8, 2, {segments[0]});
  segments[2] = b.count(8, 2);
  segments[3] = b.count_unlike(8, 2, {segments[2]});
  std::array<Chain, 4> side;                              // right y0, right y1, left y0, left y1
  std::array<std::array<std::uint32_t, 4>, 2> corners{};  // per end: (-xe,0) (xe,0) (xe,T) (-xe,T)
  for (int end = 0; end < 2; ++end) {
    const double y = end ? y1 : y0;
    corners[end] = {b.vertex({-xe, y, 0}, true), b.vertex({xe, y, 0}, true),
                    b.vertex({xe, y, kThickness}, true), b.vertex({-xe, y, kThickness}, true)};
  }
  for (int k = 0; k < 4; ++k) {
    const int end = k % 2;
    const bool right = k < 2;
    Chain& c = side[k];
    c.t = b.open_params(segments[k], 2 * a_end);
    for (std::size_t l = 0; l < c.t.size(); ++l) {
      if (l == 0 || l + 1 == c.t.size()) {
        const bool first = l == 0;
        c.ids.push_back(corners[end][right ? (first ? 1 : 2) : (first ? 3 : 0)]);
        continue;
      }
      const double ang = (right ? -a_end : kPi - a_end) + c.t[l];
      c.ids.push_back(b.vertex({(right ? xc : -xc) + rho * std::cos(ang), end ? y1 : y0,
                                0.5 * kThickness + rho * std::sin(ang)},
                               true));
    }
  }
  for (int k = 0; k < 4; ++k) b.crease_chain({corners[0][k], corners[1][k]}, false);  // lines
  b.zip_open(side[0], side[1]);
  b.zip_open(side[2], side[3]);
  // Top and bottom: two triangles each, a random diagonal.
  constexpr std::array<std::pair<int, int>, 2> kFlat{{{0, 1}, {3, 2}}};  // bottom, top
  for (const auto& [p, q] : kFlat) {
    const std::vector<std::uint32_t> quad{corners[0][p], corners[0][q], corners[1][q],
                                          corners[1][p]};
    b.fan_from(quad, static_cast<std::size_t>(b.rng.integer(0, 3)));
  }
  // End sections: the convex profile polygon, fanned from one of its vertices.
  for (int end = 0; end < 2; ++end) {
    std::vector<std::uint32_t> polygon{corners[end][0]};
    for (const std::uint32_t v : side[end].ids) polygon.push_back(v);      // right, up
    for (const std::uint32_t v : side[2 + end].ids) polygon.push_back(v);  // left, down
    polygon.pop_back();                                                    // corners[end][0] again
    b.crease_chain(polygon, true);  // the end section's outline
    b.fan_from(polygon, static_cast<std::size_t>(b.rng.integer(0, int(polygon.size()) - 1)));
  }
  b.shape.description =
      fmt("plate %.0f x %.0f x %.1f mm, ", kWidth, kLength, kThickness) +
      fmt("long sides rounded (radius %.2f mm, %.1f deg crease to the flat faces); ", rho,
          crease * 180 / kPi) +
      fmt("side arcs of %.0f / %.0f (right) and %.0f / %.0f (left) segments at the two ends, "
          "zipped into 305 mm slivers; end sections fanned",
          segments[0], segments[1], segments[2], segments[3]);
  return std::move(b.shape);
}

}  // namespace

std::span<const CadFamily> cad_families() {
  return kFamilies;
}

std::string_view cad_family_name(CadFamily family) {
  return kNames[static_cast<std::size_t>(family)];
}

std::optional<CadFamily> cad_family_from_name(std::string_view name) {
  for (std::size_t i = 0; i < kNames.size(); ++i)
    if (kNames[i] == name) return kFamilies[i];
  return std::nullopt;
}

CadShape make_cad_shape(CadFamily family, const CadParams& params) {
  Builder b(family, params);
  switch (family) {
    case CadFamily::CappedCylinder:
      return cylinder(b);
    case CadFamily::Cone:
      return cone(b);
    case CadFamily::Torus:
      return torus(b);
    case CadFamily::Tube:
      return tube(b);
    case CadFamily::Sphere:
      return sphere(b);
    case CadFamily::Ellipsoid:
      return ellipsoid(b);
    case CadFamily::Blob:
      return blob(b);
    case CadFamily::RoundedBox:
      return rounded_box(b);
    case CadFamily::Plate:
      return plate(b);
  }
  throw std::invalid_argument("make_cad_shape: unknown family");
}

Mesh float_rounded(Mesh mesh) {
  for (Vec3& p : mesh.mutable_positions())
    p = {double(float(p.x)), double(float(p.y)), double(float(p.z))};
  return mesh;
}

FloatRounding float_rounding(const Mesh& mesh) {
  const double eps = std::numeric_limits<float>::epsilon();
  const Mesh stl = float_rounded(mesh);
  FloatRounding r;
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    const std::array<Vec3, 3> p = {mesh.position(a), mesh.position(b), mesh.position(c)};
    r.reversed += dot(mesh.face_normal(FaceId(f)), stl.face_normal(FaceId(f))) <= 0;
    double longest = 0, largest = 0;
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, distance(p[k], p[(k + 1) % 3]));
      largest = std::max({largest, std::abs(p[k].x), std::abs(p[k].y), std::abs(p[k].z)});
    }
    r.below_grid += norm(mesh.face_normal(FaceId(f))) / longest < 2 * eps * largest;
  }
  return r;
}

Mesh float_mesh(const CadShape& shape) {
  IndexedSoup soup = shape.soup;
  for (Vec3& p : soup.positions)
    p = Vec3{static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
  return build_mesh(soup).mesh;
}

}  // namespace stlrefine::test
