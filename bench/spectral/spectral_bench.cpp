// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_spectral_bench: Prautzsch and Umlauf's visible claims (CGI 1998, Figs. 6-9 and
// 12-13; issue 5 item 6), measured on our schemes.
//
//  1. Curvature. Control nets around one extraordinary vertex of valence 3 or 9, sampled
//     from a parabolic cylinder and from a hyperbolic paraboloid (as the paper's Figs. 7
//     and 9), refined by loop and loop-g2 (also with Remark 5.3's ramp). At every level the
//     discrete Gaussian curvature at the extraordinary vertex: the angle deficit over a
//     third of its fan's area, and a quadratic height fit over its two rings. Loop's
//     curvature there should degenerate (grow without bound or go to 0), loop-g2's stay
//     bounded.
//  2. Self-intersection. Nets with an extraordinary vertex of valence 3, 9, 10, 12, 16
//     distorted in the plane (a generic net, as the paper's Fig. 13), flat or
//     sampled from the same surfaces, refined by the original butterfly (8-point rule
//     everywhere, the scheme PU modify), butterfly-g1, and our default butterfly (Zorin's
//     modified one). Near the extraordinary vertex: faces turned over (normal against the
//     surface's), pairs of faces that intersect (CGAL's exact predicates), and the spread
//     of the vertex's face normals (a tangent plane exists only if that goes to 0).
//
// Markdown on stdout; --svg writes the plot. Hand-run, never a test (bench/RESULTS.md,
// section "Spectral (Prautzsch-Umlauf)").

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>

#include <CLI/CLI.hpp>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "bench/spectral/svg.h"
#include "core/analysis/local_matrix.h"
#include "core/analysis/polar_net.h"
#include "core/analysis/spectrum.h"
#include "core/features/features.h"
#include "core/schemes/butterfly.h"
#include "core/schemes/registry.h"
#include "core/schemes/split4_host.h"

using namespace stlrefine;
namespace sb = stlrefine::spectral_bench;

namespace {

constexpr double kPi = std::numbers::pi;

// ---------------------------------------------------------------------------------------
// Nets

struct Surface {
  std::string name;
  std::function<double(double, double)> z;
  double true_k;  // Gaussian curvature at the origin
};

// Curvature 1/4 across the cylinder; K = -4 a^2 = -1/16 for the paraboloid.
std::vector<Surface> surfaces() {
  return {{"parabolic cylinder z = x^2/8", [](double x, double) { return x * x / 8; }, 0.0},
          {"hyperbolic paraboloid z = (x^2 - y^2)/8",
           [](double x, double y) { return (x * x - y * y) / 8; }, -1.0 / 16}};
}

// A deterministic value in [-1, 1] per (vertex, coordinate).
double jitter_value(std::uint32_t v, int c) {
  std::uint64_t h =
      (std::uint64_t(v) + 1) * 0x9E3779B97F4A7C15ull + std::uint64_t(c) * 0xBF58476D1CE4E5B9ull;
  h ^= h >> 31, h *= 0x94D049BB133111EBull, h ^= h >> 29;
  return double(h >> 11) / double(1ull << 53) * 2 - 1;
}

// A polar net of `rings` rings (unit lattice, the extraordinary vertex 0 at the origin).
// In the plane every vertex but the centre moves by `twist` r (cos 2t, sin 2t) (polar
// coordinates r, t: a frequency-2 distortion, z -> z + twist z^2/|z|) and then by up to
// `jitter` times the lattice's shortest edge (2 sin(pi/n), at most 1: the edge between two
// spokes' first points) in each coordinate, so the net stays a valid net at every valence. Then it
// is lifted onto the surface. The outer ring is the boundary; nothing else is sharp.
Level make_net(int valence, int rings, const std::function<double(double, double)>& z,
               double jitter, double twist) {
  analysis::PolarNet net = analysis::make_polar_net(valence, rings);
  std::span<Vec3> p = net.mesh.mutable_positions();
  for (std::uint32_t v = 1; v < p.size(); ++v) {
    const double r = std::hypot(p[v].x, p[v].y), t = std::atan2(p[v].y, p[v].x);
    p[v].x += twist * r * std::cos(2 * t);
    p[v].y += twist * r * std::sin(2 * t);
    const double spacing = std::min(1.0, 2 * std::sin(kPi / valence));
    p[v].x += jitter * spacing * jitter_value(v, 0);
    p[v].y += jitter * spacing * jitter_value(v, 1);
  }
  for (Vec3& q : p) q.z = z ? z(q.x, q.y) : 0;
  Level level;
  BigVector<std::uint8_t> smooth(net.mesh.num_edges(), 0);
  level.features = Features(net.mesh, std::move(smooth));
  level.mesh = std::move(net.mesh);
  return level;
}

// ---------------------------------------------------------------------------------------
// Measures around vertex 0 (old vertices keep their ids: it is the extraordinary vertex at
// every level)

const VertexId kCentre(0);

// Vertices within `rings` edges of the centre, by ring.
std::vector<int> ring_distance(const Mesh& m, int rings) {
  std::vector<int> d(m.num_vertices(), -1);
  std::vector<VertexId> front{kCentre};
  d[0] = 0;
  for (int r = 1; r <= rings; ++r) {
    std::vector<VertexId> next;
    for (VertexId v : front)
      for_each_outgoing(m, v, [&](HalfedgeId h) {
        for (VertexId w : {m.to(h), m.from(Mesh::prev(h))})
          if (d[w.idx] < 0) d[w.idx] = r, next.push_back(w);
      });
    front = std::move(next);
  }
  return d;
}

struct Curvature {
  double deficit = 0;  // angle deficit / (fan area / 3)
  double fit = 0;      // quadratic fit over the two rings
};

Curvature centre_curvature(const Mesh& m) {
  Curvature out;
  const Vec3 c = m.position(kCentre);
  double angle = 0, area = 0;
  Vec3 normal;
  for_each_outgoing(m, kCentre, [&](HalfedgeId h) {
    const Vec3 a = m.position(m.to(h)) - c, b = m.position(m.from(Mesh::prev(h))) - c;
    angle += std::atan2(norm(cross(a, b)), dot(a, b));
    area += norm(cross(a, b)) / 2;
    normal += cross(a, b);
  });
  out.deficit = (2 * kPi - angle) / (area / 3);

  // z = c0 + c1 u + c2 v + c3 u^2 + c4 uv + c5 v^2 in the frame of the fan's normal.
  const Vec3 n = normalized(normal);
  const Vec3 t1 =
      normalized(std::abs(n.x) < 0.9 ? cross(n, Vec3(1, 0, 0)) : cross(n, Vec3(0, 1, 0)));
  const Vec3 t2 = cross(n, t1);
  const std::vector<int> d = ring_distance(m, 2);
  std::vector<Vec3> local;
  for (std::uint32_t v = 0; v < d.size(); ++v)
    if (d[v] >= 0) {
      const Vec3 q = m.position(VertexId(v)) - c;
      local.push_back({dot(q, t1), dot(q, t2), dot(q, n)});
    }
  Eigen::MatrixXd a(local.size(), 6);
  Eigen::VectorXd w(local.size());
  for (std::size_t i = 0; i < local.size(); ++i) {
    const double u = local[i].x, v = local[i].y;
    a.row(i) << 1, u, v, u * u, u * v, v * v;
    w[i] = local[i].z;
  }
  const Eigen::VectorXd k = a.colPivHouseholderQr().solve(w);
  const double g = 1 + k[1] * k[1] + k[2] * k[2];
  out.fit = (4 * k[3] * k[5] - k[4] * k[4]) / (g * g);
  return out;
}

struct Folding {
  int faces = 0;         // faces within the patch
  int flipped = 0;       // normal . surface normal <= 0 (all our surfaces face +z)
  int intersecting = 0;  // faces in at least one intersecting pair
  long pairs = 0;        // intersecting pairs (no shared vertex)
  double spread = 0;     // largest angle between a fan face normal and the fan's normal, deg
};

Folding folding(const Mesh& m, int patch_rings) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  Folding out;
  const std::vector<int> d = ring_distance(m, patch_rings);
  std::vector<std::array<VertexId, 3>> faces;
  std::vector<K::Triangle_3> tris;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto vs = m.face_vertices(FaceId(f));
    if (d[vs[0].idx] < 0 || d[vs[1].idx] < 0 || d[vs[2].idx] < 0) continue;
    faces.push_back(vs);
    auto pt = [&](VertexId v) {
      const Vec3& p = m.position(v);
      return K::Point_3(p.x, p.y, p.z);
    };
    tris.emplace_back(pt(vs[0]), pt(vs[1]), pt(vs[2]));
    const Vec3 n = triangle_normal(m.position(vs[0]), m.position(vs[1]), m.position(vs[2]));
    if (n.z <= 0) ++out.flipped;
  }
  out.faces = static_cast<int>(faces.size());
  std::vector<std::uint8_t> hit(faces.size(), 0);
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (std::size_t j = i + 1; j < faces.size(); ++j) {
      bool shared = false;
      for (VertexId a : faces[i])
        for (VertexId b : faces[j]) shared |= a == b;
      if (shared || !CGAL::do_intersect(tris[i], tris[j])) continue;
      ++out.pairs;
      hit[i] = hit[j] = 1;
    }
  out.intersecting = static_cast<int>(std::count(hit.begin(), hit.end(), 1));

  const Vec3 c = m.position(kCentre);
  Vec3 normal;
  std::vector<Vec3> normals;
  for_each_outgoing(m, kCentre, [&](HalfedgeId h) {
    const Vec3 a = m.position(m.to(h)) - c, b = m.position(m.from(Mesh::prev(h))) - c;
    normals.push_back(normalized(cross(a, b)));
    normal += normals.back();
  });
  for (const Vec3& n : normals)
    out.spread = std::max(out.spread,
                          std::acos(std::clamp(dot(n, normalized(normal)), -1.0, 1.0)) * 180 / kPi);
  return out;
}

// ---------------------------------------------------------------------------------------
// Schemes

struct Algorithm {
  std::string label;
  std::unique_ptr<Scheme> scheme;
};

std::unique_ptr<Scheme> by_name(const std::string& name, const SchemeOptions& options = {}) {
  if (name == "butterfly-8pt")
    return std::make_unique<HostScheme<Split4Stencil>>(
        "butterfly-8pt",
        std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint));
  return make_scheme(name, options);
}

// One step, with or without the host's fold guard.
Level step(const Scheme& scheme, const Level& coarse, bool guard, std::size_t& fold_fallbacks) {
  StepStats stats;
  Level fine = guard
                   ? scheme.refine_once(coarse, stats)
                   : split4(coarse, static_cast<const HostScheme<Split4Stencil>&>(scheme).stencil(),
                            stats, FoldGuard::Off);
  fold_fallbacks += stats.fold_fallbacks;
  return fine;
}

// Per level, the growth factor of the curvature at the vertex that the spectrum predicts:
// (mu / lambda^2)^2 for the largest mu below lambda (the second derivatives there grow
// like (mu / lambda^2)^level).
double predicted_growth(const Scheme& scheme, int valence) {
  const analysis::Refiner refiner = analysis::Refiner::of(scheme);
  const analysis::LocalMatrix a = analysis::local_subdivision_matrix(refiner, valence);
  const analysis::SpectralSummary s = analysis::summarize(refiner, a, 0);
  const double r = s.next / (s.lambda * s.lambda);
  return r * r;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

struct Options {
  int levels = 6;
  int rings = 6;
  int patch_rings = 6;
  double jitter = 0.2;
  double twist = 0.15;
  std::vector<int> curvature_valences{3, 9};
  std::vector<int> butterfly_valences{3, 9, 10, 12, 16};
  std::string svg;
  bool no_curvature = false, no_butterfly = false;
};

const char* kColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "stlrefine_spectral_bench: curvature near extraordinary vertices under loop vs loop-g2, "
      "and self-intersections under the butterfly vs butterfly-g1 (Prautzsch-Umlauf). "
      "Markdown on stdout."};
  app.add_option("--levels", opt.levels, "Subdivision steps")->check(CLI::Range(1, 8));
  app.add_option("--rings", opt.rings, "Rings of the control nets")->check(CLI::Range(4, 12));
  app.add_option("--patch-rings", opt.patch_rings,
                 "Rings around the vertex searched for folds and intersections, every level")
      ->check(CLI::Range(1, 16));
  app.add_option("--jitter", opt.jitter, "In-plane jitter of the butterfly nets (lattice units)")
      ->check(CLI::Range(0.0, 0.3));
  app.add_option("--twist", opt.twist,
                 "Frequency-2 distortion of the butterfly nets (z -> z + twist z^2/|z|)")
      ->check(CLI::Range(0.0, 0.45));
  app.add_option("--curvature-valences", opt.curvature_valences)->check(CLI::Range(3, 48));
  app.add_option("--butterfly-valences", opt.butterfly_valences)->check(CLI::Range(3, 48));
  app.add_option("--svg", opt.svg, "Write the plot here");
  app.add_flag("--no-curvature", opt.no_curvature);
  app.add_flag("--no-butterfly", opt.no_butterfly);
  CLI11_PARSE(app, argc, argv);

  std::vector<sb::Chart> charts;

  if (!opt.no_curvature) {
    std::cout << "### Gaussian curvature at the extraordinary vertex (loop vs loop-g2)\n\n"
              << "Nets of " << opt.rings
              << " rings on the unit lattice, sampled from the surface; K at the vertex after "
                 "each step: `def` = angle deficit / (fan area / 3), `fit` = quadratic height "
                 "fit over its two rings. Predicted growth = (mu / lambda^2)^2 per level from "
                 "the scheme's spectrum (> 1: K blows up).\n\n";
    const SchemeOptions ramp{{"ramp_steps", 6}};
    std::vector<std::pair<std::string, SchemeOptions>> algos{
        {"loop", {}}, {"loop-g2", {}}, {"loop-g2 ramp 6", ramp}};
    for (const Surface& s : surfaces())
      for (int n : opt.curvature_valences) {
        sb::Chart chart;
        chart.title =
            std::string("curvature: ") +
            (s.name.rfind("parabolic", 0) == 0 ? "parabolic cylinder" : "hyperbolic paraboloid") +
            ", n = " + std::to_string(n);
        chart.y_label = "|K| at the vertex (quadratic fit)";
        chart.log_y = true;
        std::vector<std::vector<Curvature>> rows(algos.size());
        std::cout << "**" << s.name << ", valence " << n << "** (true K at the vertex "
                  << fmt("%g", s.true_k) << ")\n\n| level |";
        for (const auto& [label, o] : algos)
          std::cout << " " << label << " def | " << label << " fit |";
        std::cout << "\n|---|";
        for (std::size_t i = 0; i < algos.size(); ++i) std::cout << "---|---|";
        std::cout << "\n";
        std::vector<double> growth;
        for (std::size_t a = 0; a < algos.size(); ++a) {
          const std::string name = algos[a].first.substr(0, algos[a].first.find(' '));
          const auto scheme = by_name(name, algos[a].second);
          growth.push_back(predicted_growth(*scheme, n));
          Level level = make_net(n, opt.rings, s.z, 0, 0);
          std::size_t folds = 0;
          rows[a].push_back(centre_curvature(level.mesh));
          for (int l = 1; l <= opt.levels; ++l) {
            level = step(*scheme, level, true, folds);
            rows[a].push_back(centre_curvature(level.mesh));
          }
          sb::Line line{algos[a].first, kColours[a], a > 0, {}};
          for (int l = 1; l <= opt.levels; ++l)
            line.points.push_back({double(l), std::abs(rows[a][l].fit)});
          chart.lines.push_back(std::move(line));
        }
        for (int l = 0; l <= opt.levels; ++l) {
          std::cout << "| " << l << " |";
          for (std::size_t a = 0; a < algos.size(); ++a)
            std::cout << " " << fmt("%.4g", rows[a][l].deficit) << " | "
                      << fmt("%.4g", rows[a][l].fit) << " |";
          std::cout << "\n";
        }
        std::cout << "| growth/level, last step |";
        for (std::size_t a = 0; a < algos.size(); ++a) {
          const int l = opt.levels;
          std::cout << " " << fmt("%.3g", rows[a][l].deficit / rows[a][l - 1].deficit) << " | "
                    << fmt("%.3g", rows[a][l].fit / rows[a][l - 1].fit) << " |";
        }
        std::cout << "\n| predicted (spectrum) |";
        for (double g : growth) std::cout << " " << fmt("%.3g", g) << " | |";
        std::cout << "\n\n";
        charts.push_back(std::move(chart));
      }
  }

  if (!opt.no_butterfly) {
    std::cout
        << "### Self-intersection near the extraordinary vertex (butterfly vs butterfly-g1)\n\n"
        << "Nets of " << opt.rings << " rings, distorted in the plane (z -> z + " << opt.twist
        << " z^2/|z|, then a fixed jitter of up to " << opt.jitter
        << " times the local spacing: generic nets without symmetry, the same for every "
           "scheme), flat or sampled from the surface. Searched: the faces within "
        << opt.patch_rings
        << " rings of the vertex at each level. `flip` = faces whose normal points "
           "down (every surface here faces +z), `x` = faces in an intersecting pair "
           "(no shared vertex; CGAL exact predicates), `spread` = largest angle between a fan face "
           "and "
           "the fan's mean normal (degrees; a tangent plane needs it to go to 0). The "
           "host's fold guard is off (the schemes as published); the guard column is "
           "what `stlrefine refine` does at the last level (with the number of edge points the "
           "guard "
           "moved anywhere in the net).\n\n";
    struct Net {
      std::string name;
      std::function<double(double, double)> z;
    };
    std::vector<Net> nets{{"flat", nullptr}};
    for (const Surface& s : surfaces()) nets.push_back({s.name, s.z});
    const std::vector<std::string> algos{"butterfly-8pt", "butterfly-g1", "butterfly"};
    for (const Net& net : nets) {
      std::cout << "**" << net.name << "**\n\n| n | scheme | level 0 flip/x | ";
      for (int l = 1; l <= opt.levels; ++l) std::cout << "L" << l << " flip/x | ";
      std::cout << "spread L1..L" << opt.levels
                << " (deg) | guard: flip/x, edges moved (whole net) |\n|---|---|---|";
      for (int l = 1; l <= opt.levels; ++l) std::cout << "---|";
      std::cout << "---|---|\n";
      for (int n : opt.butterfly_valences) {
        sb::Chart chart;
        chart.title = "folding: " + net.name.substr(0, net.name.find(' ')) +
                      " paraboloid, n = " + std::to_string(n);
        chart.y_label = "fan normal spread at the vertex (deg)";
        for (std::size_t a = 0; a < algos.size(); ++a) {
          const auto scheme = by_name(algos[a]);
          const Level coarse = make_net(n, opt.rings, net.z, opt.jitter, opt.twist);
          Level level = coarse;
          std::size_t folds = 0;
          std::vector<Folding> rows{folding(level.mesh, opt.patch_rings)};
          for (int l = 1; l <= opt.levels; ++l) {
            level = step(*scheme, level, false, folds);
            rows.push_back(folding(level.mesh, opt.patch_rings));
          }
          Level guarded = coarse;
          std::size_t moved = 0;
          for (int l = 1; l <= opt.levels; ++l) guarded = step(*scheme, guarded, true, moved);
          const Folding g = folding(guarded.mesh, opt.patch_rings);
          std::cout << "| " << n << " | " << algos[a] << " |";
          for (const Folding& f : rows)
            std::cout << " " << f.flipped << "/" << f.intersecting << " |";
          std::string spread;
          for (int l = 1; l <= opt.levels; ++l)
            spread += (l > 1 ? " " : "") + fmt("%.1f", rows[l].spread);
          std::cout << " " << spread << " | " << g.flipped << "/" << g.intersecting << ", " << moved
                    << " |\n";
          sb::Line line{algos[a], kColours[a], a == 1, {}};
          for (int l = 1; l <= opt.levels; ++l) line.points.push_back({double(l), rows[l].spread});
          chart.lines.push_back(std::move(line));
        }
        if (net.name.rfind("hyperbolic", 0) == 0) charts.push_back(std::move(chart));
      }
      std::cout << "\n";
    }
  }

  if (!opt.svg.empty() && !sb::write_svg(opt.svg,
                                         "Prautzsch-Umlauf: curvature (loop vs loop-g2) and "
                                         "self-intersection (butterfly vs butterfly-g1)",
                                         charts, 3)) {
    std::cerr << "cannot write " << opt.svg << "\n";
    return 1;
  }
  return 0;
}
