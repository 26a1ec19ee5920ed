// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Exact surfaces that test meshes are sampled from (the CAD-like families of cad_like.h),
// for measuring how far a refined mesh is from the shape it stands for. Every surface is
// the closed boundary of a solid, with outward normals; pieces meet tangentially except
// along the creases named below.

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "core/geometry/vec3.h"
#include "core/mesh/mesh.h"

namespace stlrefine::test {

//! The point of a surface nearest to a query point.
struct SurfacePoint {
  Vec3 point;
  Vec3 normal;  //!< outward, unit
  //! On a crease (two smooth pieces meeting at an angle): the other piece's outward unit
  //! normal; every unit vector between the two is a normal of the surface there. Equal to
  //! `normal` off creases. (Where three pieces meet, two of their normals.)
  Vec3 other_normal;

  bool on_crease() const { return other_normal != normal; }
};

//! Smallest angle (degrees) between the unit vector n and the normal(s) at s.
double normal_angle_deg(const SurfacePoint& s, const Vec3& n);

class TrueSurface {
 public:
  virtual ~TrueSurface() = default;

  //! The point of the surface nearest to p (one of them where several are equally near).
  //! Exact (closed form, to rounding) unless the surface says otherwise.
  virtual SurfacePoint closest_point(const Vec3& p) const = 0;

  //! Distance to the surface, negative inside the solid: the sign of (p - c) . (n + n')
  //! at the closest point c, exact for the convex creases of these surfaces.
  double signed_distance(const Vec3& p) const;

  //! `count` random points of the surface (every piece gets some), each with the normal its
  //! parametrisation gives. Made without closest_point, so tests can check one against the
  //! other. Crease points are not sampled on purpose (their other_normal equals normal).
  virtual std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const = 0;

  //! The nearest point of the surface's creases (curves where two pieces meet at an angle),
  //! with the normals of both pieces; nullopt when the surface has none.
  virtual std::optional<SurfacePoint> closest_crease_point(const Vec3& p) const;

  //! An offset from the surface below which the closest point of s + t n is s for every
  //! smooth point s and |t| <= reach() (the smallest radius of curvature, or less).
  virtual double reach() const = 0;
};

// --- the surfaces --------------------------------------------------------------------------

//! A point of a meridian (or cross-section) plane: u across, v along the axis.
struct Vec2 {
  double u = 0, v = 0;
};

//! One piece of a closed planar profile: a segment a -> b, or an arc around `centre`
//! counter-clockwise from angle a0 to a1 (radians, a0 < a1 <= a0 + 2 pi). The profile runs
//! with the solid on its left, so the outward normal is the right-hand normal of the
//! direction of travel (for a ccw arc: the radial direction; profiles here are convex where
//! they are curved). Consecutive pieces share their end points.
struct ProfilePiece {
  enum class Kind { Segment, Arc } kind = Kind::Segment;
  Vec2 a, b;
  Vec2 centre;
  double radius = 0;
  double a0 = 0, a1 = 0;

  static ProfilePiece segment(Vec2 a, Vec2 b);
  static ProfilePiece arc(Vec2 centre, double radius, double a0, double a1);
  //! The point at parameter t in [0, 1] and the outward normal there.
  Vec2 at(double t) const;
  Vec2 normal_at(double t) const;
  double length() const;
};

//! The surface swept by a profile in the (rho, z) half-plane (u = rho >= 0, v = z) turned
//! about the z axis: capped cylinders, cones, tubes, tori, spheres. Pieces that meet at an
//! angle (a cap and a side) make crease circles; segments on the axis are not creases.
std::shared_ptr<const TrueSurface> revolution_surface(std::vector<ProfilePiece> profile);

//! The prism over a convex profile in the (x, z) plane (u = x, v = z), from y = y0 to
//! y = y1 with flat end caps: the plate with rounded long sides. Creases where the end caps
//! meet the sides and wherever two profile pieces meet at an angle.
std::shared_ptr<const TrueSurface> extrusion_surface(std::vector<ProfilePiece> profile, double y0,
                                                     double y1);

//! Sphere of the given radius about `centre`.
std::shared_ptr<const TrueSurface> sphere_surface(Vec3 centre, double radius);

//! Ellipsoid x^2/a^2 + y^2/b^2 + z^2/c^2 = 1 (axes aligned, centred at the origin). The
//! closest point is Eberly's ("Distance from a point to an ellipse, an ellipsoid, or a
//! hyperellipsoid", 2013): the root of a monotone function by bisection to the last bit.
std::shared_ptr<const TrueSurface> ellipsoid_surface(double a, double b, double c);

//! Star-shaped blob r(d) d over unit directions d, r(d) = radius (1 + sum_k c_k h_k(d)),
//! with the low-order polynomial harmonics h_k of blob_harmonic():
//! a smooth closed surface that no quadric or torus fits.
//!
//! Its closest point is numeric: every direction within the cone that can hold a nearer
//! point than the radial projection of p is scanned on a 1.5-degree grid, and the best
//! grid points are polished by damped Newton on the sphere of directions until a step is
//! below 1e-14 rad. The returned point is on the surface to rounding (it is r(d) d)
//! and stationary: the tangential part of p - c is below 1e-10 of the radius (plus 1e-9
//! of |p - c|). It is the global nearest point unless another local minimum of the
//! distance lies within 1.5 degrees of it, which the coefficient range of the generator
//! rules out for query points within the surface's reach (tests check it against samples).
constexpr std::size_t kBlobHarmonics = 7;
std::shared_ptr<const TrueSurface> blob_surface(double radius,
                                                const std::array<double, kBlobHarmonics>& c);
//! The blob's point in the unit direction d: r(d) d.
Vec3 blob_point(double radius, const std::array<double, kBlobHarmonics>& c, const Vec3& d);
//! h_k(d) for k < kBlobHarmonics (d, 1 and 3 components), and its gradient in R^3.
double blob_harmonic(std::size_t k, const Vec3& d, Vec3* gradient = nullptr);

//! Box [-hx, hx] x [-hy, hy] x [-hz, hz] with every edge rounded by radius r (< each half
//! extent): planes, quarter-cylinder fillets and sphere-octant corners, tangent-continuous
//! (no crease). The boundary of the inner box grown by r.
std::shared_ptr<const TrueSurface> rounded_box_surface(Vec3 half_extent, double radius);

//! How far (degrees) the unit normal n of triangle (a, b, c) is from the true surface's: the
//! smallest normal_angle_deg at the closest points of its centroid and of its three corners.
//! Measured at the centroid alone, a face lying in a flat cap's plane a hair outside the
//! rim (the rim's curve rule bulges 0.05 mm past a cylinder's circle after six sqrt3 steps)
//! scored 90 degrees: its centroid is nearest to the side wall. Its own region is the one
//! its corners are on; a fold or a ridge agrees with the truth at none of the four points.
//! A closest point within `crease_snap` of a crease counts as on it (float32 rounding of an
//! STL puts flat faces a hair past their rim), and so does a point whose nearest crease point
//! is at most twice as far as the surface (a cap's face a hair past a rim the curve rule
//! bulged: the crease is as near as the error; a fold or ridge still agrees with neither
//! piece nor any normal between them).
double face_truth_angle_deg(const TrueSurface& surface, const Vec3& n, const Vec3& a, const Vec3& b,
                            const Vec3& c, double crease_snap = 0);

//! Faces of m more than `limit` degrees from the true normal (face_truth_angle_deg, with
//! its crease_snap); degenerate faces are not counted.
std::size_t faces_off_truth(const Mesh& m, const TrueSurface& surface, double limit,
                            double crease_snap = 0);

//! Area-weighted RMS distance to the surface over the centroids of a k x k split of every
//! face (coarse meshes take a larger k, so that every level is sampled about as densely).
double sampled_rms_distance(const Mesh& m, const TrueSurface& surface, int k);

}  // namespace stlrefine::test
