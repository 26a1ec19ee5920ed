// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The analytic surfaces the fidelity benchmark measures against. Every shape is a surface
// of revolution about the z axis, so it is given by its profile in the (rho, z) half-plane
// (rho = distance from the axis): line segments (caps, cylinder sides) and circular arcs
// (sphere, torus). The nearest point of such a surface to p lies in p's meridian half-plane,
// so the 3-D distance is exactly the 2-D distance from (rho(p), z(p)) to the profile.

#include <cstddef>
#include <vector>

#include "core/geometry/vec3.h"

namespace stlrefine::fidelity {

struct Vec2 {
  double r = 0, z = 0;  //!< distance from the axis, height
};

//! One piece of a profile: a segment a -> b, or a circular arc around `centre` from angle
//! `a0` to `a1` (radians, a0 < a1, counter-clockwise). The profile is traversed so that the
//! solid lies on the left: the outward normal is the right-hand normal of the direction of
//! travel (for an arc traversed ccw around its centre, the radial direction).
struct ProfilePiece {
  enum class Kind { Segment, Arc } kind = Kind::Segment;
  Vec2 a, b;              //!< segment ends
  Vec2 centre;            //!< arc centre
  double radius = 0;      //!< arc radius
  double a0 = 0, a1 = 0;  //!< arc angles
  bool flat_cap = false;  //!< a planar face (z = const): its vertices must stay in the plane
};

//! What the true surface says about one point.
struct Closest {
  double distance = 0;
  std::size_t piece = 0;  //!< the nearest piece (lowest index among ties)
};

class TrueSurface {
 public:
  explicit TrueSurface(std::vector<ProfilePiece> pieces) : pieces_(std::move(pieces)) {}

  const std::vector<ProfilePiece>& pieces() const { return pieces_; }

  Closest closest(const Vec3& p) const;
  //! Smallest angle (degrees) between the unit vector `n` and the outward surface normal at
  //! p's closest point. Where that point is a corner of the profile (a rim), every piece
  //! meeting there is tried and the smallest angle is taken.
  double normal_angle_deg(const Vec3& p, const Vec3& n) const;
  //! Outward unit normal of piece `i` at the point of it nearest to p.
  Vec3 normal(const Vec3& p, std::size_t i) const;
  //! Distance from p to the nearest profile corner circle (a rim: where two pieces meet at
  //! an angle, or where an open profile ends); a large value when there is none.
  double rim_distance(const Vec3& p) const;
  //! For a flat cap piece: |z - z_cap|.
  double cap_plane_distance(const Vec3& p, std::size_t piece) const;

 private:
  std::vector<ProfilePiece> pieces_;
};

}  // namespace stlrefine::fidelity
