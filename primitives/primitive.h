// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <optional>
#include <span>

#include "core/geometry/vec3.h"

namespace stlrefine::primitives {

enum class PrimitiveType { Plane, Sphere, Cylinder, Cone, Torus };

//! "plane", "sphere", "cylinder", "cone", "torus".
const char* to_string(PrimitiveType type);

//! One analytic surface a CAD exporter tessellates. Which fields mean what:
//! - plane: `point` on it, `axis` its unit normal;
//! - sphere: `point` the centre, `radius`;
//! - cylinder: `point` on the axis, `axis` unit direction, `radius`;
//! - cone: `point` the apex, `axis` unit direction towards the opening, `angle` the
//!   half-angle in radians (0, pi/2); only the nappe the axis points into;
//! - torus: `point` the centre, `axis` unit, `radius` the major radius (centre to the core
//!   circle), `minor` the minor (tube) radius.
struct Primitive {
  PrimitiveType type = PrimitiveType::Plane;
  Vec3 point;
  Vec3 axis{0, 0, 1};
  double radius = 0;
  double minor = 0;
  double angle = 0;

  //! The nearest point of the surface to p (for a point on the axis of a surface of
  //! revolution, one of them).
  Vec3 project(const Vec3& p) const;
  //! |p - project(p)|.
  double distance(const Vec3& p) const { return stlrefine::distance(p, project(p)); }
  //! The unit normal of the surface at project(p), pointing away from the axis or centre
  //! (a plane: `axis`); zero where it has none (p on the axis of a surface of revolution).
  Vec3 normal_at(const Vec3& p) const;
};

//! The point nearest to p on the intersection curve of a and b: closed form for two planes
//! (their line), otherwise alternating projection (exact in one step for a plane and a
//! surface of revolution whose axis is perpendicular to it: a circle). nullopt when the
//! surfaces do not meet near p (parallel planes) or the iteration does not reach
//! `tolerance` on both surfaces.
std::optional<Vec3> project_to_intersection(const Primitive& a, const Primitive& b, const Vec3& p,
                                            double tolerance);

//! Least-squares fit of `type` to points (Eigen; plane by PCA, the others by an algebraic
//! or normal-based start and Levenberg-Marquardt on the geometric distances). `normals`
//! (unit, with `normal_points` where they were taken, e.g. face normals at centroids) give
//! the axis of cylinders and cones; may be empty for the other types. nullopt when the
//! points are too few for the type or the fit degenerates.
std::optional<Primitive> fit_primitive(PrimitiveType type, std::span<const Vec3> points,
                                       std::span<const Vec3> normals,
                                       std::span<const Vec3> normal_points);

}  // namespace stlrefine::primitives
