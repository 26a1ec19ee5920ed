// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/mesh/mesh.h"

namespace stlrefine::primitives {

//! Where a point stands against the input surface.
struct Nearest {
  Vec3 point;              //!< its closest point on the input
  std::uint32_t face = 0;  //!< the input face that point is on
  double distance = 0;     //!< mm
};

//! Where a vertex is pulled back to: just inside its bound (by 1e-14 of the diagonal, far above
//! the coordinates' rounding). At the bound itself, the distance measured again came out up to
//! 1e-4 of it over (xyz cube, a bound of 1e-12 of the diagonal on its exact planes: 3.4652e-11
//! for 3.4649e-11), and the report said the bound did not hold.
inline double just_inside(double bound, double diagonal) {
  return std::max(0.5 * bound, bound - 1e-14 * diagonal);
}

//! How the deviation bound pulls vertices back (issue 17). Pulled alone towards its closest
//! input point, a vertex dents the surface where its neighbours stay, and the thin faces of a
//! refined hull turn (sqrt3-interp 6 steps: slivers 0.1-0.7 mm long and 1e-5-1e-3 mm high,
//! turned 60-90 degrees by moves of 0.001-0.02 mm; 85-100 faces > 60 degrees from the truth
//! on the hull families over seeds 6000-6005, where refine() alone leaves none). So the
//! vertices around one pulled follow it, less the farther they are.
struct SmoothPullParams {
  //! The pull's falloff: a vertex at graph distance s (mm, along edges) from one pulled by a
  //! is pulled by a - slope * s in the same direction (the largest such over the pulled
  //! vertices). Smaller spreads wider (fewer turned faces, more vertices moved: at 0.02 the
  //! sphere's RMS grew 2%). (0, 1].
  double slope = 0.05;
  //! Rounds of pulling and locating again; the vertices still past their bound after them
  //! are pulled alone (the bound always holds). [1, 16].
  int rounds = 4;
  //! After the pull, a face it turned more than this from its own normal before (degrees)
  //! has its less pulled corners pulled further towards the input, the least needed (see
  //! smooth_pull): a sliver turns for any move of a corner off the plane of the others, so
  //! the sheet alone still turned 28-45 faces per hull family over six seeds. (0, 90].
  double unturn_degrees = 24;
  //! Throws Error(InvalidParameter) when a field is out of its range.
  void validate() const;
};

//! What smooth_pull did.
struct SmoothPullReport {
  std::size_t moved = 0;         //!< vertices moved (past their bound, and carried along)
  std::size_t violators = 0;     //!< past their bound before
  std::size_t pulled_alone = 0;  //!< still past it after the rounds: pulled alone
  double max_move = 0;           //!< mm
  int rounds = 0;                //!< rounds run
  std::size_t unturned = 0;      //!< times a turned face was set right (unturn phase)
  std::size_t still_turned = 0;  //!< faces left turned past unturn_degrees from before
};

//! How many vertices smooth_pull reaches at most in a mesh of `vertices`: 1/16 of them, at
//! least 4096. A bound deviates in a few places; where more are past it the rest are pulled
//! alone (the bound holds either way).
std::size_t smooth_pull_reach_cap(std::uint64_t vertices);

//! Bytes smooth_pull allocates for a mesh of `vertices` at most: the state of each vertex it
//! may reach (smooth_pull_reach_cap), its index entry, the heap and the vertex lists.
std::uint64_t smooth_pull_bytes(std::uint64_t vertices);

//! Pulls every movable vertex (movable[v]; input vertices and snapped ones are not) past its
//! bound (bound(nearest[v])) towards its closest input point to just inside the bound, and
//! the movable vertices around it with it (SmoothPullParams::slope): the surface moves as a
//! sheet. The moved vertices are located again (locate(p, hint face)) and the rounds repeat
//! while any is past its bound; after the last, those left are pulled alone. On return every
//! movable vertex is within its bound and `nearest` is current. Then each face the pull
//! turned more than SmoothPullParams::unturn_degrees from its normal before is set right,
//! the first of these that keeps every moved corner within its bound, each by the least
//! fraction of its way: a corner's move applied to the other movable corners (a translation
//! of the face as it was; the farthest pulled corner's first), a corner moved onto the plane
//! through the other two nearest the old normal, then within that plane towards the other
//! two's edge or the one of them nearer the input. The faces around a moved corner are
//! checked again (each face set right a few times at most, the work capped). Parallel where
//! it queries the pull; the unturn phase is sequential (it touches a few faces).
SmoothPullReport smooth_pull(
    Mesh& mesh, const std::vector<std::uint8_t>& movable, std::vector<Nearest>& nearest,
    const std::function<double(const Nearest& at)>& bound,
    const std::function<Nearest(const Vec3& p, std::uint32_t hint)>& locate, double diagonal,
    const SmoothPullParams& params);

}  // namespace stlrefine::primitives
