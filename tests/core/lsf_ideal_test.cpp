// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// LSF against the ideal refinement on CAD-like tessellations (issue 17 item 3: within 2x of
// the ideal, at most 0.25x the input, 2 levels). The ideal is the same 1-to-4 topology with
// every new edge point the chord midpoint moved onto the true surface (onto the crease for a
// crease chord's halves), as bench/fidelity measures it. Default (auto) crease detection,
// as a request runs it.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/features/features.h"
#include "core/schemes/lsf.h"
#include "core/schemes/lsf_rules.h"
#include "tests/core/test_util.h"
#include "tests/support/cad_like.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

namespace stlrefine {
namespace {

using namespace test;

constexpr std::array<std::uint64_t, 3> kSeeds{1, 2, 3};

// `levels` 1-to-4 splits of the shape's soup whose edge points are the chord midpoints moved
// onto the truth (the crease's nearest point for halves of a crease chord).
IndexedSoup ideal_refinement(const CadShape& shape, int levels) {
  IndexedSoup soup = shape.soup;
  using Edge = std::pair<std::uint32_t, std::uint32_t>;
  std::set<Edge> crease;
  for (const auto& [a, b] : shape.crease_edges) crease.insert({a, b});
  for (int level = 0; level < levels; ++level) {
    std::map<Edge, std::uint32_t> edge_point;
    std::set<Edge> next_crease;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const Edge key = std::minmax(a, b);
      if (const auto it = edge_point.find(key); it != edge_point.end()) return it->second;
      const Vec3 m = (soup.positions[a] + soup.positions[b]) * 0.5;
      const bool on_crease = crease.count(key) > 0;
      soup.positions.push_back(on_crease ? shape.surface->closest_crease_point(m)->point
                                         : shape.surface->closest_point(m).point);
      const auto id = static_cast<std::uint32_t>(soup.positions.size() - 1);
      edge_point.emplace(key, id);
      if (on_crease) next_crease.insert(std::minmax(a, id)), next_crease.insert(std::minmax(id, b));
      return id;
    };
    std::vector<std::array<std::uint32_t, 3>> next;
    for (const auto& t : soup.triangles) {
      const std::uint32_t ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({ab, t[1], bc});
      next.push_back({ca, bc, t[2]});
      next.push_back({ab, bc, ca});
    }
    soup.triangles = std::move(next);
    crease = std::move(next_crease);
  }
  return soup;
}

struct Ratios {
  double to_ideal = 0, to_input = 0;  // means over kSeeds, 2 levels
};

Ratios two_level_ratios(CadFamily family) {
  Ratios r;
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(family, {seed, 1.0});
    const Mesh input = to_mesh(shape.soup);
    Level level{Mesh(input), detect_features(input, FeatureParams{})};
    level = refine_levels("lsf", std::move(level), 2);
    const double rms = sampled_rms_distance(level.mesh, *shape.surface, 2);
    const double ideal =
        sampled_rms_distance(to_mesh(ideal_refinement(shape, 2)), *shape.surface, 2);
    const double in = sampled_rms_distance(input, *shape.surface, 8);
    r.to_ideal += rms / ideal / kSeeds.size();
    r.to_input += rms / in / kSeeds.size();
  }
  return r;
}

// The families issue 17's target is met on: the zipped walls (crease sector normals held
// across the rim, Hermite midpoints at crease ends, rims continued through false corners),
// the hulls (relaxed guard normals) and the rounded box (guard normals relaxed to convergence
// over its fillets and corners, circle-exact Hermite midpoints between them: 6.18x the ideal
// and 0.42x the input before, 1.57x and 0.11x here). Before round 5 the cylinder was 2.9-3.8x
// the ideal, the cone 3.6-4.0x, the tube 2.7-4.5x; after it 1.71, 1.69, 1.63 (hulls 1.25-1.40).
TEST(LsfIdeal, ZippedWallsHullsAndRoundedBoxWithinTwiceTheIdealAndAQuarterOfTheInput) {
  for (const CadFamily family :
       {CadFamily::CappedCylinder, CadFamily::Cone, CadFamily::Tube, CadFamily::Sphere,
        CadFamily::Ellipsoid, CadFamily::Blob, CadFamily::RoundedBox}) {
    const Ratios r = two_level_ratios(family);
    EXPECT_LE(r.to_ideal, 2.0) << cad_family_name(family);
    EXPECT_LE(r.to_input, 0.25) << cad_family_name(family);
  }
}

// Where the target is still missed, today's figures on these seeds are the bound, so that
// they cannot get worse unnoticed (the target stays open): plate 3.14x the ideal, 0.20x the
// input (3.01x, 0.19x before the relaxed normals of bench/results-issue17-s7-lsf.md; 3.56x,
// 0.23x before round 6's sliver normals and corner tangents); torus 1.78x, 0.12x (2.02x,
// 0.14x before; within 2x on these seeds, not on every bench seed).
TEST(LsfIdeal, PlateAndTorusNoWorseThanToday) {
  const std::array<std::pair<CadFamily, double>, 2> bounds = {
      {{CadFamily::Plate, 3.2}, {CadFamily::Torus, 1.95}}};
  for (const auto& [family, bound] : bounds) {
    const Ratios r = two_level_ratios(family);
    EXPECT_LE(r.to_ideal, bound) << cad_family_name(family);
    EXPECT_LE(r.to_input, 0.5) << cad_family_name(family);
  }
}

// The torus (issue 17): a warped, jittered (u, v) grid, its rings zipped. Its guard normals
// were relaxed to the chord symmetry n_v . u + n_w . u = 0, which its normal curvature, changing
// from ring to ring, breaks by ~0.01: ~2 degrees off, and the Hermite midpoints between them
// (most of its edges: both ends relaxed) bent by the normals' differences. Now the relaxation
// adds the third-order curvature terms and a relaxed vertex whose ring is not a fan or zipper
// takes its fit's normal (fit_guard_normals). L2 RMS / ideal, mean over seeds 1-3: 1.78 before
// (0.12x the input), 1.52 here (0.10x).
TEST(LsfIdeal, TorusWithinOnePointSixTimesTheIdeal) {
  const Ratios r = two_level_ratios(CadFamily::Torus);
  EXPECT_LE(r.to_ideal, 1.6);  // 1.52 here
  EXPECT_LE(r.to_input, 0.25);
}

// One lsf level on a CAD-like shape: the RMS distance (mm) from the truth of the points of
// the smooth input edges `measured` picks (edge e's point is vertex V + e of the level).
struct EdgePointError {
  double rms = 0;
  int count = 0;
};
EdgePointError one_level_edge_point_error(
    CadFamily family, std::uint64_t seed,
    const std::function<bool(const Mesh&, EdgeId)>& measured) {
  const CadShape shape = make_cad_shape(family, {seed, 1.0});
  const Mesh input = to_mesh(shape.soup);
  const Level coarse{Mesh(input), detect_features(input, FeatureParams{})};
  const Level fine = refine_level("lsf", coarse);
  double sum = 0;
  EdgePointError out;
  for (std::uint32_t e = 0; e < input.num_edges(); ++e) {
    if (coarse.features.is_sharp(EdgeId(e)) || !measured(input, EdgeId(e))) continue;
    const Vec3 p = fine.mesh.position(VertexId(input.num_vertices() + e));
    const double d = distance(p, shape.surface->closest_point(p).point);
    sum += d * d;
    ++out.count;
  }
  out.rms = out.count > 0 ? std::sqrt(sum / out.count) : 0;
  return out;
}

// The plate's 305 mm slivers: one level's points on its long smooth edges, against the truth.
// Their Hermite midpoints read the end sections' sector normals, whose face sums tilt along
// the strips by ~1e-4 rad (the sagitta of the arc between a strip's two ends over 305 mm); the
// chord symmetry along each zipped run of strips (relax_sliver_normals) removes most of that,
// and the corners' outline tangents of circles (curve_tangent_towards) the rest of what is
// measured here. RMS point error, mean over the seeds: 10.3 um before (9.6, 12.4, 8.9), 6.4 um
// with the first, 5.9 um (6.2, 8.3, 3.2) with both.
TEST(LsfIdeal, PlateSliverPointsCloseToTheArc) {
  double mean = 0;
  for (const std::uint64_t seed : kSeeds) {
    const auto long_edge = [](const Mesh& m, EdgeId e) {
      const HalfedgeId h = m.halfedge(e);
      return distance(m.position(m.from(h)), m.position(m.to(h))) >= 100.0;
    };
    const EdgePointError err = one_level_edge_point_error(CadFamily::Plate, seed, long_edge);
    ASSERT_GT(err.count, 30) << "seed " << seed;
    mean += err.rms / kSeeds.size();
  }
  EXPECT_LE(mean, 7e-3);  // mm
}

// The rounded box (issue 17): planes, quarter-cylinder fillets zipped between differently
// sampled end arcs, sphere-octant corners fanned from an inner point; every vertex smooth.
// The guard normals, relaxed to the chord symmetry n_v . c + n_w . c = 0 along every edge
// (relax_guard_normals, as the stencil runs it), against the true normals at the input
// vertices: the face sums of the fillets' 30 mm strips and the corners' fans were 5.6 and 4.2
// deg RMS off, and 10 rounds of the even-to-uneven rings only left the fans and zippers
// there (RMS over seeds 1-3: 5.0 deg before, 0.016 deg here).
TEST(LsfIdeal, RoundedBoxGuardNormalsRelaxedToTheTruth) {
  double sum = 0;
  int count = 0;
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(CadFamily::RoundedBox, {seed, 1.0});
    const Mesh m = to_mesh(shape.soup);
    const Features f = detect_features(m, FeatureParams{});
    std::vector<lsf::GuardVertex> guard(m.num_vertices());
    for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
      if (f.kind(VertexId(v)) > VertexKind::Dart) continue;
      guard[v].one_sector = 1;
      guard[v].normal = lsf::sector_normal(m, f, m.halfedge(VertexId(v)));
      guard[v].spokes = lsf::ring_spoke_flags(m, VertexId(v));
    }
    lsf::SectorNormals sectors;
    lsf::relax_guard_normals(m, f, guard, sectors, /*lsf_terms=*/true);
    for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
      if (!guard[v].one_sector) continue;
      const double deg =
          normal_angle_deg(shape.surface->closest_point(m.position(VertexId(v))), guard[v].normal);
      sum += deg * deg;
      ++count;
    }
  }
  EXPECT_LE(std::sqrt(sum / count), 0.1);
}

// One level's points on the rounded box against the truth (RMS over every smooth edge's point,
// mean over the seeds). With the relaxed normals the Hermite midpoint, exact on circular arcs
// (the sphere corners' and the fillets' sections), is taken between relaxed ends, and the
// edge-local fold pull no longer puts the corners' points towards their chords: 59.9 um
// before (43.4, 58.8, 77.6), here 5.8 um (6.5, 4.8, 6.2).
TEST(LsfIdeal, RoundedBoxOneLevelPointsOnTheTruth) {
  double mean = 0;
  for (const std::uint64_t seed : kSeeds) {
    const auto any_edge = [](const Mesh&, EdgeId) { return true; };
    mean += one_level_edge_point_error(CadFamily::RoundedBox, seed, any_edge).rms / kSeeds.size();
  }
  EXPECT_LE(mean, 10e-3);  // mm
}

// One level's points on the torus and the sphere (hull of random points), against the truth:
// the Hermite midpoints of the fits' normals (fit_guard_normals) and the curvature terms where
// the relaxed normals were degrees off. RMS over every smooth edge's point, mean over seeds 1-3:
// torus 13.7 um before, 10.2 here; sphere 3.0 um before, 1.9 here.
TEST(LsfIdeal, TorusAndSphereOneLevelPointsOnTheTruth) {
  for (const auto& [family, bound] :
       {std::pair{CadFamily::Torus, 11.5e-3}, std::pair{CadFamily::Sphere, 2.5e-3}}) {
    double mean = 0;
    for (const std::uint64_t seed : kSeeds) {
      const auto any_edge = [](const Mesh&, EdgeId) { return true; };
      mean += one_level_edge_point_error(family, seed, any_edge).rms / kSeeds.size();
    }
    EXPECT_LE(mean, bound) << cad_family_name(family);  // mm
  }
}

// The zipped walls (issue 17, round 8): every crease vertex's sector normal on the cylinder,
// cone and tube (walls and annuli zipped between two rims), against the truth's normal just
// inside the sector. The face sums, held across the rim, tilt across it by the chords'
// sagittas over the strip's width (a tilt of opposite signs at the two rims that the chord
// symmetry cannot see); the strip's ruled normal (across the crease tangent and the direction
// to the far rim's point straight across) is exact on walls of revolution. RMS over seeds
// 1-3: cylinder 0.11, cone 0.23, tube 0.12 deg before; here 0.004, 0.006, 0.005.
TEST(LsfIdeal, ZippedWallSectorNormalsRuledAcrossTheStrip) {
  for (const CadFamily family : {CadFamily::CappedCylinder, CadFamily::Cone, CadFamily::Tube}) {
    double sum = 0;
    int count = 0;
    for (const std::uint64_t seed : kSeeds) {
      const CadShape shape = make_cad_shape(family, {seed, 1.0});
      const Mesh m = to_mesh(shape.soup);
      const Features f = detect_features(m, FeatureParams{});
      for (std::uint32_t i = 0; i < m.num_vertices(); ++i) {
        const VertexId v(i);
        if (f.kind(v) != VertexKind::Crease) continue;
        for_each_outgoing(m, v, [&](HalfedgeId h) {
          const Vec3 p = m.position(v);
          const Vec3 centroid =
              (p + m.position(m.to(h)) + m.position(m.to(Mesh::next(h)))) * (1.0 / 3);
          const Vec3 truth = shape.surface->closest_point(p + 1e-3 * (centroid - p)).normal;
          const double c = std::clamp(dot(lsf::sector_normal(m, f, h), truth), -1.0, 1.0);
          const double deg = std::acos(c) * 180.0 / 3.141592653589793;
          sum += deg * deg;
          ++count;
        });
      }
    }
    EXPECT_LE(std::sqrt(sum / count), 0.01) << cad_family_name(family);
  }
}

// One level's points on the zipped cylinder's and cone's walls (smooth edges from one rim to
// the other), against the truth: the middle of the ruling through the chord's midpoint, from
// the two rims' arcs (lsf's ruled midpoint), is exact there, where the Hermite midpoint even of
// the true normals is not (the cone: 3 um RMS). RMS, mean over seeds 1-3: cylinder 2.8 um,
// cone 12.6 um before; here 1.0 and below 0.01 (the cylinder's rest: the host's fold guard
// pulls a few long wall edges' points to their chords).
TEST(LsfIdeal, ZippedWallOneLevelPointsOnTheRuledSurface) {
  for (const auto& [family, bound] :
       {std::pair{CadFamily::CappedCylinder, 2e-3}, std::pair{CadFamily::Cone, 1e-4}}) {
    double mean = 0;
    for (const std::uint64_t seed : kSeeds) {
      const auto wall_edge = [](const Mesh& m, EdgeId e) {
        const HalfedgeId h = m.halfedge(e);
        return std::abs(m.position(m.from(h)).z - m.position(m.to(h)).z) > 1.0;
      };
      const EdgePointError err = one_level_edge_point_error(family, seed, wall_edge);
      EXPECT_GT(err.count, 30) << cad_family_name(family) << " seed " << seed;
      mean += err.rms / kSeeds.size();
    }
    EXPECT_LE(mean, bound) << cad_family_name(family);  // mm
  }
}

// What made uniform lsf stall after two levels on the zipped cone (round 7: RMS / diagonal
// 1.66e-4, 1.74e-4, 1.81e-4 at L2-L4): its walls' first-level points were 8 um RMS off, an
// error every later level interpolates. RMS of L3 over L2 (the ideal: 0.25), mean over seeds
// 1-3: cone 1.23 before, 0.55 here; cylinder 0.67 before, 0.45 here.
TEST(LsfIdeal, ZippedConeAndCylinderRefineBeyondTheSecondLevel) {
  for (const auto& [family, bound] :
       {std::pair{CadFamily::Cone, 0.7}, std::pair{CadFamily::CappedCylinder, 0.6}}) {
    double mean = 0;
    for (const std::uint64_t seed : kSeeds) {
      const CadShape shape = make_cad_shape(family, {seed, 1.0});
      const Mesh input = to_mesh(shape.soup);
      Level level =
          refine_levels("lsf", Level{Mesh(input), detect_features(input, FeatureParams{})}, 2);
      const double l2 = sampled_rms_distance(level.mesh, *shape.surface, 2);
      level = refine_levels("lsf", std::move(level), 1);
      mean += sampled_rms_distance(level.mesh, *shape.surface, 2) / l2 / kSeeds.size();
    }
    EXPECT_LE(mean, bound) << cad_family_name(family);
  }
}

// One lsf level of the plate for each seed of kSeeds: `measure` returns the distances it
// takes from the level (at least `min_count` per seed); the RMS per seed, averaged over the
// seeds, and the largest distance.
struct PlateErrors {
  double rms = 0, worst = 0;
};
template <class Measure>
PlateErrors plate_level_errors(std::size_t min_count, Measure measure) {
  PlateErrors out;
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(CadFamily::Plate, {seed, 1.0});
    const Mesh input = to_mesh(shape.soup);
    const Level coarse{Mesh(input), detect_features(input, FeatureParams{})};
    const Level fine = refine_level("lsf", coarse);
    const std::vector<double> d = measure(shape, coarse, fine);
    EXPECT_GE(d.size(), min_count) << "seed " << seed;
    if (d.empty()) continue;
    double sum = 0;
    for (double x : d) {
      sum += x * x;
      out.worst = std::max(out.worst, x);
    }
    out.rms += std::sqrt(sum / double(d.size())) / double(kSeeds.size());
  }
  return out;
}

// The plate's strip midpoints after a level (smooth vertices between two 152 mm halves and
// short spokes across the strip): their normal across the two curves through them
// (two_curve_normal: the strip's straight line and the arc across it) instead of face sums
// and relaxed normals ~2 deg off. The second level's points on the short edges between two
// such midpoints, against the truth, RMS, mean over seeds 1-3: 20 um before, 0.8 um here.
TEST(LsfIdeal, PlateStripMidpointsSecondLevelPointsOnTheArc) {
  // The first level is the coarse one here: its short edges' points of the second.
  const PlateErrors e =
      plate_level_errors(21, [](const CadShape& shape, const Level&, const Level& coarse) {
        const Level fine = refine_level("lsf", coarse);
        const Mesh& m = coarse.mesh;
        std::vector<double> d;
        for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
          const HalfedgeId h = m.halfedge(EdgeId(e));
          if (coarse.features.kind(m.from(h)) != VertexKind::Smooth ||
              coarse.features.kind(m.to(h)) != VertexKind::Smooth ||
              distance(m.position(m.from(h)), m.position(m.to(h))) > 50.0)
            continue;
          const Vec3 p = fine.mesh.position(VertexId(m.num_vertices() + e));
          d.push_back(distance(p, shape.surface->closest_point(p).point));
        }
        return d;
      });
  EXPECT_LE(e.rms, 4e-3);  // mm
}

// The plate's end sections (issue 17, round 9): each outline is a flat side meeting two arcs at
// corners of a 6-12 degree crease, every vertex sharp. The 1-D rule continued the curve through
// those corners to the flat side's far end (203 mm away, off the arc's circle), whose quadratic
// is the chord there, and averaged it with the other end's: the arc's first chord kept half its
// sagitta. The outline lies in the end plane, so the distance to the surface does not see it;
// every strip from those points does (the 152 mm halves of the next level). One level's points
// on the outline's sharp edges against the true crease, seeds 1-3: RMS (mean over the seeds)
// 36 um and max 0.14 mm before; here 6 um and 21 um (the rest: the 4-point rule on 20-degree
// chords).
TEST(LsfIdeal, PlateOutlinePointsOnTheArc) {
  const PlateErrors e =
      plate_level_errors(21, [](const CadShape& shape, const Level& coarse, const Level& fine) {
        const Mesh& input = coarse.mesh;
        std::vector<double> d;
        for (const auto& [a, b] : shape.crease_edges) {
          const Vec3 pa = shape.soup.positions[a], pb = shape.soup.positions[b];
          if (pa.y != pb.y) continue;  // the four straight creases along the plate
          const EdgeId edge = find_edge(input, find_vertex(input, pa), find_vertex(input, pb));
          EXPECT_TRUE(edge.valid() && coarse.features.is_sharp(edge));
          if (!edge.valid()) continue;
          const Vec3 p = fine.mesh.position(VertexId(input.num_vertices() + edge.idx));
          d.push_back(distance(p, shape.surface->closest_crease_point(p)->point));
        }
        return d;
      });
  EXPECT_LE(e.rms, 10e-3);    // mm
  EXPECT_LE(e.worst, 50e-3);  // mm
}

// Issue 17's target on the plate: within 2x of the ideal at 2 levels (seeds 1-3, auto creases):
// 2.94x (0.19x the input) before the outline's corners ended its arcs
// (PlateOutlinePointsOnTheArc), 1.53x (0.10x) here.
TEST(LsfIdeal, PlateWithinTwiceTheIdeal) {
  const Ratios r = two_level_ratios(CadFamily::Plate);
  EXPECT_LE(r.to_ideal, 2.0);
  EXPECT_LE(r.to_input, 0.25);
}

// The plate's strips next to its flat-to-arc creases (issue 17, round 9): a corner's sector, or
// a crease vertex's beside a corner, reaches the other end section along the crease line, so
// ruled_foot did not take it as a strip, and its long edges got Hermite midpoints of normals
// from sector face sums (the ruled midpoint is exact on an extrusion). One level's points on the
// smooth edges of 100 mm or more with a corner at an end, against the truth, seeds 1-3: RMS
// (mean over the seeds) 1.9 um, max 8.6 um before; here to rounding (1e-15 mm).
TEST(LsfIdeal, PlateCornerStripPointsOnTheArc) {
  const PlateErrors e =
      plate_level_errors(5, [](const CadShape& shape, const Level& coarse, const Level& fine) {
        const Mesh& input = coarse.mesh;
        std::vector<double> d;
        for (std::uint32_t edge = 0; edge < input.num_edges(); ++edge) {
          const HalfedgeId h = input.halfedge(EdgeId(edge));
          const VertexId a = input.from(h), b = input.to(h);
          if (coarse.features.is_sharp(EdgeId(edge)) ||
              (coarse.features.kind(a) != VertexKind::Corner &&
               coarse.features.kind(b) != VertexKind::Corner) ||
              distance(input.position(a), input.position(b)) < 100.0)
            continue;
          const Vec3 p = fine.mesh.position(VertexId(input.num_vertices() + edge));
          d.push_back(distance(p, shape.surface->closest_point(p).point));
        }
        return d;
      });
  EXPECT_LE(e.rms, 1e-4);    // mm
  EXPECT_LE(e.worst, 5e-4);  // mm
}

// The guard normals of one lsf level of the plate (seeds 1-3), as the stencil relaxes them
// (relax_guard_normals), against the truth: `crease_rms`, over the arc-side spokes of the
// crease vertices made on the straight flat-to-arc creases (the truth's normal of the piece
// nearer the spoke's face); `smooth_rms`, over the smooth vertices with a two-curve normal (the
// strips' midpoints). Degrees.
struct PlateLevelNormals {
  double crease_rms = 0, smooth_rms = 0;
};
PlateLevelNormals plate_level_normals() {
  double crease2 = 0, smooth2 = 0;
  int creases = 0, smooth = 0;
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(CadFamily::Plate, {seed, 1.0});
    const Mesh input = to_mesh(shape.soup);
    const Level fine =
        refine_level("lsf", Level{Mesh(input), detect_features(input, FeatureParams{})});
    const Mesh& m = fine.mesh;
    const Features& f = fine.features;
    std::vector<lsf::GuardVertex> guard(m.num_vertices());
    for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
      if (f.kind(VertexId(v)) > VertexKind::Dart) continue;
      guard[v].one_sector = 1;
      guard[v].normal = lsf::sector_normal(m, f, m.halfedge(VertexId(v)));
      guard[v].spokes = lsf::ring_spoke_flags(m, VertexId(v));
    }
    lsf::SectorNormals sectors;
    lsf::relax_guard_normals(m, f, guard, sectors, /*lsf_terms=*/true);
    const lsf::GuardNormals normal_of{m, f, guard.data(), &sectors};
    for (std::uint32_t i = input.num_vertices(); i < m.num_vertices(); ++i) {
      const VertexId v(i);
      const Vec3 p = m.position(v);
      if (guard[i].two_curves) {
        const double deg = normal_angle_deg(shape.surface->closest_point(p), guard[i].normal);
        smooth2 += deg * deg;
        ++smooth;
      }
      if (f.kind(v) != VertexKind::Crease || std::abs(p.y) > 150.0) continue;
      const SurfacePoint s = shape.surface->closest_point(p);
      for_each_outgoing(m, v, [&](HalfedgeId h) {
        const Vec3 face =
            normalized(triangle_normal(p, m.position(m.to(h)), m.position(m.opposite(h))));
        const Vec3 truth =
            dot(s.normal, face) >= dot(s.other_normal, face) ? s.normal : s.other_normal;
        if (std::abs(truth.z) > 0.999) return;  // a flat side's spoke
        const double c = std::clamp(dot(normal_of(h), truth), -1.0, 1.0);
        const double deg = std::acos(c) * 180.0 / 3.141592653589793;
        crease2 += deg * deg;
        ++creases;
      });
    }
  }
  EXPECT_GT(creases, 20);
  EXPECT_GT(smooth, 60);
  return {std::sqrt(crease2 / std::max(creases, 1)), std::sqrt(smooth2 / std::max(smooth, 1))};
}

// The plate's crease lines after a level (issue 17, round 9): each midpoint's arc-side sector is
// three slivers in the chord plane of the arc's first strip (their face sums 3-7 degrees off the
// arc's normal, flat to the coplanar test in some seeds), which the Hermite midpoints of the
// next level's short edges across the arc and long edges along the plate multiply. Its one
// short edge across, to a strip midpoint whose two-curve normal is trusted, fixes its tilt
// about the crease line (relax_sliver_normals, anchored): 5.2 deg RMS before, here 0.03.
TEST(LsfIdeal, PlateCreaseLineMidpointNormalsOnTheArc) {
  EXPECT_LE(plate_level_normals().crease_rms, 0.1);
}

// The plate's strip midpoints after a level: their ring holds the split edge's two ends and, as
// long, the midpoints of the end outlines' chords beside them (152 mm). The two-curve normal
// took the circle through the longest spoke and the longest nearly opposite it, often a
// lopsided pair, whose tangent at the midpoint leaves the surface (on an extrusion only the
// symmetric pair's lies in it): tilts along the strip that the next level's 152 mm halves
// multiply. The pair the vertex is most nearly the midpoint of: 0.0145 deg RMS before, here
// 0.0003 (plate L2 RMS / ideal, seeds 9000-9005: 1.36 -> 1.23).
TEST(LsfIdeal, PlateStripMidpointNormalsOnTheArc) {
  EXPECT_LE(plate_level_normals().smooth_rms, 0.002);
}

}  // namespace
}  // namespace stlrefine
