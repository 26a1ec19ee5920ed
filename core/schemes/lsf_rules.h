// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// LSF's per-edge rules besides the fits (lsf.h): the 1-D rule of sharp edges
// (lsf_curve_point, defined in lsf_rules.cpp) and the guard of issue 17 that checks each edge
// point against the surface's normals (sector normals, planar patches, the Hermite midpoint,
// the pull-back of folding children). Internal to the lsf*.cpp files: the stencil (lsf.cpp)
// runs them, the batch kernels (lsf_kernels.cpp) find the smooth vertices' guard normals.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "core/schemes/lsf.h"

namespace stlrefine::lsf {

// The guard's sector normal (issue 17, see sector_normal below), summed face by face: on even
// rings weighted by the sine of each face's angle at the vertex, on fans and zippers by the
// faces' areas, blended by the ratio of the longest to the shortest spoke (kEvenSpokes to
// kUnevenSpokes). e1, e2: the face's two spokes, counter-clockwise.
inline constexpr double kEvenSpokes = 3.0, kUnevenSpokes = 12.0;
// At a smooth or dart vertex (square_areas), the area-weighted part leans further towards the
// largest faces as the ring gets more uneven: from the area-weighted sum at a spoke ratio of
// kLargeFacesFrom to the sum weighted by the squared areas at kLargeFacesAt. A CAD exporter
// makes a face large only where the surface under it is nearly flat across it, so on a fan or
// zipper the largest faces' normals are the surface's (the rounded box: a flat face or a
// fillet's long strips beside a corner's small fan, whose faces lean by tens of degrees).
// Even rings (a hull's, below a ratio of 6) keep their normals bit for bit.
inline constexpr double kLargeFacesFrom = 6.0, kLargeFacesAt = 16.0;
// `flat`: every face so far within kFlatSine of the first one (see flat_ring below).
inline constexpr double kFlatSine = 0.5e-3;
struct NormalSum {
  Vec3 angle_sum, area_sum, area2_sum, first;
  double shortest = std::numeric_limits<double>::infinity(), longest = 0;
  bool flat = true;
  bool square_areas = false;  // set for a smooth or dart vertex's ring (area2_sum summed)

  void add(const Vec3& e1, const Vec3& e2) {
    const Vec3 n = cross(e1, e2);
    const double l1 = dot(e1, e1), l2 = dot(e2, e2);
    if (dot(first, first) == 0) {
      first = n;
    } else if (flat) {
      const Vec3 c = cross(first, n);
      flat = dot(c, c) <= (kFlatSine * kFlatSine) * (dot(first, first) * dot(n, n)) &&
             dot(first, n) > 0;
    }
    area_sum += n;
    if (square_areas) area2_sum += std::sqrt(dot(n, n)) * n;
    if (l1 * l2 > 0) angle_sum += (1.0 / std::sqrt(l1 * l2)) * n;
    shortest = std::min(shortest, std::min(l1, l2));
    longest = std::max(longest, std::max(l1, l2));
  }
  Vec3 normal() const {
    const double ratio = longest > 0 && shortest > 0 ? std::sqrt(longest / shortest) : 1.0;
    const double w = std::clamp((ratio - kEvenSpokes) / (kUnevenSpokes - kEvenSpokes), 0.0, 1.0);
    Vec3 area = normalized(area_sum);
    if (square_areas) {
      const double w2 =
          std::clamp((ratio - kLargeFacesFrom) / (kLargeFacesAt - kLargeFacesFrom), 0.0, 1.0);
      if (w2 > 0) area = normalized((1.0 - w2) * area + w2 * normalized(area2_sum));
    }
    return normalized((1.0 - w) * normalized(angle_sum) + w * area);
  }
  //! GuardVertex::spokes of these faces' spokes.
  std::uint8_t spoke_flags() const;
};
//! The guard's normal of from(h)'s faces within the crease-bounded sector that holds h (its
//! whole ring at a smooth or dart vertex): NormalSum::normal of them, or at a smooth or dart
//! vertex whose faces are not all flat (NormalSum::flat) and whose spokes are not even
//! (GuardVertex::kNotEven) the normal of the plane that rules its ring (dominant_plane). Unit, or
//! zero when the sector has no direction.
Vec3 sector_normal(const Mesh& m, const Features& f, HalfedgeId h);

//! Whether a plane rules v's ring (issue 17, the rounded box: a flat face meeting fillets
//! tangentially, with no crease between them): at least two of v's faces lie in the plane of
//! its largest face to the rounding of the coordinates (as the plane rule of the edge guard
//! tells it), those faces hold at least half of the ring's face area, and no other face there
//! is larger than 0.75 of the largest. Then the surface's normal at v is the plane's (the
//! plane and a tangent fillet share it along their seam), set in `normal` (unit); the
//! face-weighted normals lean towards the fillet's and the corner's faces by degrees, which a
//! long edge's Hermite midpoint multiplies by its length.
bool dominant_plane(const Mesh& m, VertexId v, Vec3& normal);

// What the edge guard reads of a vertex, packed in one record (the edge pass reads two per
// edge, at random): its guard normal when it has one sector (smooth or dart), and for a batched
// smooth vertex whether all its faces are within kFlatSine of one another (then the plane rule
// cannot fire at an edge between two such vertices, see guarded_edge_point).
struct alignas(32) GuardVertex {
  //! spokes: the longest spoke at least kEvenSpokes / kUnevenSpokes times the shortest.
  static constexpr std::uint8_t kNotEven = 1, kUneven = 2;
  Vec3 normal;
  std::uint8_t one_sector = 0;
  std::uint8_t flat = 0;
  std::uint8_t batched_smooth = 0;  // the normal came from the batch kernel (no dominant_plane)
  std::uint8_t spokes = 0;          // of a one-sector vertex
  //! A crease vertex with a sector normal in SectorNormals (relax_sliver_normals).
  std::uint8_t sectors_relaxed = 0;
  //! Its normal was relaxed by relax_normals (then the edge guard takes the Hermite midpoint
  //! between two such vertices).
  std::uint8_t relaxed = 0;
  //! Its normal is the two-curve normal (two_curve_normal): relax_normals leaves it.
  std::uint8_t two_curves = 0;
  //! relax_normals with curvature terms: the plain chord symmetry did not hold along its ring
  //! (kCurvedResidual), so its equations got the curvature terms.
  std::uint8_t curved = 0;
};

//! Crease vertices' sector normals that replace sector_normal (relax_sliver_normals), per
//! outgoing half-edge of the sector, sorted by half-edge.
struct SectorNormals {
  std::vector<std::pair<std::uint32_t, Vec3>> by_halfedge;
  const Vec3* find(HalfedgeId h) const {
    const auto it = std::lower_bound(by_halfedge.begin(), by_halfedge.end(), h.idx,
                                     [](const std::pair<std::uint32_t, Vec3>& entry,
                                        std::uint32_t i) { return entry.first < i; });
    return it != by_halfedge.end() && it->first == h.idx ? &it->second : nullptr;
  }
};
inline std::uint8_t NormalSum::spoke_flags() const {
  return (longest >= (kEvenSpokes * kEvenSpokes) * shortest ? GuardVertex::kNotEven : 0) |
         (longest >= (kUnevenSpokes * kUnevenSpokes) * shortest ? GuardVertex::kUneven : 0);
}
//! GuardVertex::spokes of v's ring (a walk).
std::uint8_t ring_spoke_flags(const Mesh& m, VertexId v);

//! The guard's normal source: `guard`'s record of from(h) when it has one sector, else the
//! relaxed sector normal in `sectors`, else sector_normal (walked). Without records (null)
//! always walked.
struct GuardNormals {
  const Mesh& mesh;
  const Features& features;
  const GuardVertex* guard = nullptr;
  const SectorNormals* sectors = nullptr;
  Vec3 operator()(HalfedgeId h) const {
    if (guard != nullptr) {
      const GuardVertex& g = guard[mesh.from(h).idx];
      if (g.one_sector) return g.normal;
      if (g.sectors_relaxed && sectors != nullptr)
        if (const Vec3* n = sectors->find(h)) return *n;
    }
    return sector_normal(mesh, features, h);
  }
  //! Whether from(h) is a smooth or dart vertex whose ring is a fan or zipper (its longest spoke
  //! at least kUnevenSpokes times its shortest), or any vertex with such a ring when `sliver`.
  bool uneven(HalfedgeId h, bool sliver) const {
    const VertexId v = mesh.from(h);
    if (!sliver && features.kind(v) > VertexKind::Dart) return false;
    if (guard != nullptr && guard[v.idx].one_sector)
      return (guard[v.idx].spokes & GuardVertex::kUneven) != 0;
    return (ring_spoke_flags(mesh, v) & GuardVertex::kUneven) != 0;
  }
};

//! Relaxes the guard normals of the smooth vertices towards the chord symmetry of a
//! smooth surface: along every edge (v, w), n_v . c + n_w . c = 0 for the unit chord c (exact
//! for circles, spheres, cylinders and planes, to third order in the chord elsewhere, and
//! across tangent seams: whatever the tessellation). Each round solves, per vertex, the least
//! squares of those equations over its ring with its neighbours' normals of the previous round,
//! damped towards its own; up to `rounds` Jacobi rounds (deterministic, parallel) per connected
//! component of the vertices that move, fewer when it converges or stops converging. Neighbours
//! with more than one sector give the normal of the sector holding the edge (sector_normal).
//! The vertices that move: smooth one-sector vertices whose ring or a neighbour's is not even
//! (GuardVertex::spokes), unless all their faces lie in one plane. On a surface whose vertices
//! lie on it the equations hold for its true normals, and converged rounds find them (issue
//! 17's rounded box, fillets and sphere corners: 5.6 and 4.2 -> 0.04 deg RMS). Those whose
//! equations then hold along their ring are marked GuardVertex::relaxed; the others get their
//! face sums back.
//! With `curvature_terms` (lsf's own guard; sqrt3's guard keeps the plain equations), a second
//! pass adds the equations' third-order terms -(L / 6) (k_w - k_v) (k the normal curvatures
//! along the chord, from the LSF fits) along the edges between two vertices whose ring residual
//! stays above kCurvedResidual and whose rings are not fans or zippers (issue 17's torus: the
//! normal curvature changes by 0.05 / mm between neighbouring rings, and the plain equations
//! tilted its normals by 2 degrees).
void relax_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard, int rounds,
                   bool curvature_terms = false);
//! The most rounds LsfStencil runs: Jacobi rounds carry a correction one ring per round, and
//! the rounded box's fillets and corners need most of 100 to agree (issue 17, seeds 6000-6005,
//! L2 RMS / ideal: 30 rounds 2.6, 100 rounds 1.7).
inline constexpr int kRelaxRounds = 100;

//! Corrects the crease vertices' sector normals at the ends of slivers' long edges (an edge
//! kSliverAspect times longer than the narrower face's height across it: issue 17's plate,
//! 305 mm strips zipped between two end sections) to the chord symmetry n_v . c + n_w . c = 0
//! along those edges. The strips' face sums tilt along the strip by the sagitta of a few
//! millimetres of arc over 305 mm (about 1e-4 rad), which a long edge's Hermite midpoint
//! multiplies by its length. A sector normal only turns about its crease curve (it stays
//! across it), and only in a sector of slivers that is not flat; an equation joins two such
//! sectors; Kaczmarz sweeps give the least tilts that meet them (exact on extrusions of
//! circles). What the sums leave free, one alternating tilt per connected run, is averaged
//! out only over many strips: runs of fewer than kSliverRunNodes sectors keep the face sums.
//! A short edge from such a sector to a smooth vertex with a trusted normal (GuardVertex::relaxed)
//! adds its equation with that normal held: the run's free tilt is then fixed, and a flat
//! sector of slivers that breaks it by more than 1e-3 moves too (the plate's crease-line
//! midpoints after a level, whose slivers lie in the chord plane of the arc's first strip).
//! `sectors` receives the moved sector normals (GuardVertex::sectors_relaxed marks their
//! vertices). Where no crease vertex has a sliver edge, one scan of the vertex kinds.
void relax_sliver_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard,
                          SectorNormals& sectors);

//! At a smooth vertex v whose ring is a sliver's midpoint (two long spokes, nearly opposite,
//! kTwoCurvesRatio times longer than every other; of several such pairs, the one v is most
//! nearly the midpoint of): the normal across the tangents at v of the circle through the long
//! spokes' ends and of the circle through the two short neighbours
//! most across them, one on each side (issue 17, round 8: the plate's strip midpoints after a
//! level, whose face sums and relaxed normals were ~2 deg off). Both curves lie on the surface,
//! so its normal is across both: exact on extrusions of circles. Writes `normal` (unit, on
//! the side of `face_sum`) and returns true, unless the ring is not such a midpoint or the
//! normal turns more than 10 degrees from face_sum.
bool two_curve_normal(const Mesh& m, VertexId v, const Vec3& face_sum, Vec3& normal);
inline constexpr double kTwoCurvesRatio = 4.0;

//! Sets every smooth one-sector vertex's guard normal to its two_curve_normal where it has one
//! (rings that are not even, GuardVertex::kUneven), marked two_curves and relaxed (trusted).
void two_curve_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard);

//! At a relaxed smooth vertex where the plain chord symmetry did not hold (GuardVertex::curved:
//! its ring is not a fan or zipper, and the curvature changes along its edges), the
//! normal of its LSF fit (the whole ring's quadric, c1 x c2) when it lies within
//! kFitNormalDegrees of the relaxed normal (issue 17, the torus: the Hermite midpoints of the
//! fits' normals were 9 um RMS off the truth at the first level, of the relaxed ones 13-15;
//! the hulls alike). The fit's normal errors vary smoothly from vertex to vertex, which the
//! Hermite midpoint (it reads the normals' difference) mostly cancels. Where the symmetry holds
//! (the rounded box's pieces, cylinders, cones), and at fits far from the relaxed normal, the
//! relaxed normal stays (the fits there made the cone's L2 10% and the rounded box's L3 17%
//! worse).
void fit_guard_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard);
inline constexpr double kFitNormalDegrees = 5.0;

//! The guard normals: two_curve_normals, relax_normals, relax_sliver_normals; with `lsf_terms`
//! (LsfStencil's) relax_normals' curvature terms and then fit_guard_normals.
inline void relax_guard_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard,
                                SectorNormals& sectors, bool lsf_terms = false) {
  two_curve_normals(m, f, guard);
  relax_normals(m, f, guard, kRelaxRounds, lsf_terms);
  if (lsf_terms) fit_guard_normals(m, f, guard);
  relax_sliver_normals(m, f, guard, sectors);
}

//! lsf_guarded_edge_point (lsf.h) with the normals from `normals` (and, with records, the
//! flat flags that skip the plane rule's walks).
Vec3 guarded_edge_point(const GuardNormals& normals, EdgeId e, const Vec3& lower_estimate,
                        const Vec3& upper_estimate);

//! lsf_guard_child_folds (lsf.h) with the normals from `normals`.
void guard_child_folds(const GuardNormals& normals, std::span<Vec3> points,
                       std::span<std::uint8_t> marks);

}  // namespace stlrefine::lsf
