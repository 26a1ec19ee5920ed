// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/primitive.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

namespace stlrefine::primitives {

namespace {

// Any unit vector perpendicular to the unit vector u.
Vec3 perpendicular(const Vec3& u) {
  const Vec3 t = std::abs(u.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  return normalized(cross(u, t));
}

// p in the meridian frame of (origin, unit axis): h along the axis, rho from it, e the
// unit radial direction.
struct Meridian {
  double h, rho;
  Vec3 e;
};

Meridian meridian(const Vec3& origin, const Vec3& axis, const Vec3& p) {
  const Vec3 w = p - origin;
  const double h = dot(w, axis);
  const Vec3 radial = w - h * axis;
  const double rho = norm(radial);
  return {h, rho, rho > 0 ? radial * (1.0 / rho) : perpendicular(axis)};
}

Vec3 to_vec3(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

// The points moved to their centroid and scaled to unit extent, so that fits are
// conditioned alike at any size and position; parameters are mapped back at the end.
struct Normalised {
  Vec3 centre;
  double scale = 1;
  std::vector<Vec3> points;
  Vec3 to_world(const Vec3& p) const { return centre + scale * p; }
  Vec3 to_local(const Vec3& p) const { return (p - centre) * (1.0 / scale); }
};

Normalised normalise(std::span<const Vec3> points) {
  Normalised n;
  Vec3 sum;
  for (const Vec3& p : points) sum += p;
  n.centre = sum * (1.0 / double(points.size()));
  double extent = 0;
  for (const Vec3& p : points) extent = std::max(extent, distance(p, n.centre));
  n.scale = extent > 0 ? extent : 1;
  n.points.reserve(points.size());
  for (const Vec3& p : points) n.points.push_back(n.to_local(p));
  return n;
}

using Residual = std::function<double(const Eigen::VectorXd&, const Vec3&)>;

// Levenberg-Marquardt on sum of residual^2 with a central-difference Jacobian; returns the
// final sum of squares. Directions the residuals do not see (an axis vector's length, an
// axis point's position along the axis) are held by the damping.
double levenberg_marquardt(Eigen::VectorXd& x, const std::vector<Vec3>& pts, const Residual& f,
                           const std::function<void(Eigen::VectorXd&)>& tidy) {
  const Eigen::Index m = x.size();
  const auto n = static_cast<Eigen::Index>(pts.size());
  Eigen::VectorXd r(n);
  auto evaluate = [&](const Eigen::VectorXd& params, Eigen::VectorXd& out) {
    double sum = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      out[i] = f(params, pts[std::size_t(i)]);
      sum += out[i] * out[i];
    }
    return sum;
  };
  double cost = evaluate(x, r);
  double lambda = 1e-3;
  Eigen::MatrixXd jac(n, m);
  Eigen::VectorXd trial_r(n);
  for (int iter = 0; iter < 100 && std::isfinite(cost); ++iter) {
    for (Eigen::Index k = 0; k < m; ++k) {
      const double step = 1e-6 * std::max(1.0, std::abs(x[k]));
      Eigen::VectorXd xp = x, xm = x;
      xp[k] += step;
      xm[k] -= step;
      for (Eigen::Index i = 0; i < n; ++i)
        jac(i, k) = (f(xp, pts[std::size_t(i)]) - f(xm, pts[std::size_t(i)])) / (2 * step);
    }
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd jtr = jac.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 12 && !improved; ++tries) {
      Eigen::MatrixXd a = jtj;
      for (Eigen::Index k = 0; k < m; ++k) a(k, k) += lambda * jtj(k, k) + 1e-14;
      Eigen::VectorXd trial = x - a.ldlt().solve(jtr);
      tidy(trial);
      const double trial_cost = evaluate(trial, trial_r);
      if (std::isfinite(trial_cost) && trial_cost < cost) {
        const double gain = cost - trial_cost;
        x = trial;
        r = trial_r;
        cost = trial_cost;
        lambda = std::max(lambda / 10, 1e-12);
        improved = true;
        if (gain <= 1e-28 * double(n) || gain < 1e-12 * cost) return cost;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  return cost;
}

void normalise_axis(Eigen::VectorXd& x, Eigen::Index at) {
  const double len = x.segment<3>(at).norm();
  if (len > 0) x.segment<3>(at) /= len;
}

// Kasa's algebraic circle fit in 2D: centre and radius.
bool fit_circle_2d(const std::vector<std::array<double, 2>>& q, double& cx, double& cy,
                   double& radius) {
  if (q.size() < 3) return false;
  Eigen::MatrixXd a(q.size(), 3);
  Eigen::VectorXd b(q.size());
  for (std::size_t i = 0; i < q.size(); ++i) {
    a(Eigen::Index(i), 0) = 2 * q[i][0];
    a(Eigen::Index(i), 1) = 2 * q[i][1];
    a(Eigen::Index(i), 2) = 1;
    b[Eigen::Index(i)] = q[i][0] * q[i][0] + q[i][1] * q[i][1];
  }
  const Eigen::Vector3d s = a.colPivHouseholderQr().solve(b);
  cx = s[0];
  cy = s[1];
  const double r2 = s[2] + cx * cx + cy * cy;
  if (!(r2 > 0)) return false;
  radius = std::sqrt(r2);
  return true;
}

std::optional<Primitive> fit_plane(const Normalised& n) {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : n.points) {
    const Eigen::Vector3d v(p.x, p.y, p.z);
    cov += v * v.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Primitive out;
  out.type = PrimitiveType::Plane;
  out.axis = normalized(to_vec3(eig.eigenvectors().col(0)));
  out.point = n.centre;  // the centroid of the points lies on the least-squares plane
  return out;
}

std::optional<Primitive> fit_sphere(const Normalised& n) {
  if (n.points.size() < 6) return std::nullopt;
  Eigen::MatrixXd a(n.points.size(), 4);
  Eigen::VectorXd b(n.points.size());
  for (std::size_t i = 0; i < n.points.size(); ++i) {
    const Vec3& p = n.points[i];
    a.row(Eigen::Index(i)) << 2 * p.x, 2 * p.y, 2 * p.z, 1;
    b[Eigen::Index(i)] = dot(p, p);
  }
  const Eigen::Vector4d s = a.colPivHouseholderQr().solve(b);
  const double r2 = s[3] + s.head<3>().squaredNorm();
  if (!(r2 > 0)) return std::nullopt;
  Eigen::VectorXd x(4);
  x << s[0], s[1], s[2], std::sqrt(r2);
  levenberg_marquardt(
      x, n.points,
      [](const Eigen::VectorXd& v, const Vec3& p) {
        return distance(p, Vec3{v[0], v[1], v[2]}) - v[3];
      },
      [](Eigen::VectorXd&) {});
  if (!(x[3] > 0) || !std::isfinite(x[3])) return std::nullopt;
  Primitive out;
  out.type = PrimitiveType::Sphere;
  out.point = n.to_world({x[0], x[1], x[2]});
  out.radius = x[3] * n.scale;
  return out;
}

// Candidate axis directions of a surface of revolution from its face normals: the normals
// of a cylinder are perpendicular to the axis, those of a cone at a constant angle to it, so
// the axis is the direction in which the normals vary least (the smallest eigenvector of
// their covariance); on a narrow patch the middle one may be it.
std::vector<Vec3> axis_candidates(std::span<const Vec3> normals) {
  std::vector<Vec3> out;
  if (normals.size() < 3) return out;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Vec3& nv : normals) mean += Eigen::Vector3d(nv.x, nv.y, nv.z);
  mean /= double(normals.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& nv : normals) {
    const Eigen::Vector3d d = Eigen::Vector3d(nv.x, nv.y, nv.z) - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  out.push_back(normalized(to_vec3(eig.eigenvectors().col(0))));
  out.push_back(normalized(to_vec3(eig.eigenvectors().col(1))));
  return out;
}

// The point nearest (least squares) to the lines (c_i, n_i): normal lines of a surface of
// revolution meet its axis. In local coordinates.
std::optional<Vec3> normal_lines_point(const Normalised& n, std::span<const Vec3> normals,
                                       std::span<const Vec3> at) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const Eigen::Vector3d nv(normals[i].x, normals[i].y, normals[i].z);
    const Vec3 c = n.to_local(at[i]);
    const Eigen::Matrix3d proj = Eigen::Matrix3d::Identity() - nv * nv.transpose();
    a += proj;
    b += proj * Eigen::Vector3d(c.x, c.y, c.z);
  }
  const Eigen::Vector3d s = a.colPivHouseholderQr().solve(b);
  if (!s.allFinite()) return std::nullopt;
  return to_vec3(s);
}

double cylinder_residual(const Eigen::VectorXd& v, const Vec3& p) {
  const Vec3 u = normalized(Vec3{v[3], v[4], v[5]});
  const Vec3 w = p - Vec3{v[0], v[1], v[2]};
  return norm(w - dot(w, u) * u) - v[6];
}

double cone_residual(const Eigen::VectorXd& v, const Vec3& p) {
  const Vec3 u = normalized(Vec3{v[3], v[4], v[5]});
  const Vec3 w = p - Vec3{v[0], v[1], v[2]};
  const double h = dot(w, u);
  return norm(w - h * u) * std::cos(v[6]) - h * std::sin(v[6]);
}

double torus_residual(const Eigen::VectorXd& v, const Vec3& p) {
  const Vec3 u = normalized(Vec3{v[3], v[4], v[5]});
  const Vec3 w = p - Vec3{v[0], v[1], v[2]};
  const double h = dot(w, u);
  const double rho = norm(w - h * u);
  return std::hypot(rho - v[6], h) - v[7];
}

double max_abs_residual(const Eigen::VectorXd& x, const std::vector<Vec3>& pts,
                        double (*f)(const Eigen::VectorXd&, const Vec3&)) {
  double worst = 0;
  for (const Vec3& p : pts) worst = std::max(worst, std::abs(f(x, p)));
  return worst;
}

std::optional<Primitive> fit_cylinder_or_cone(PrimitiveType type, const Normalised& n,
                                              std::span<const Vec3> normals,
                                              std::span<const Vec3> normal_points) {
  const std::size_t need = type == PrimitiveType::Cylinder ? 8 : 10;
  if (n.points.size() < need || normals.size() != normal_points.size()) return std::nullopt;
  const std::optional<Vec3> axis_point = normal_lines_point(n, normals, normal_points);
  if (!axis_point) return std::nullopt;
  std::optional<Eigen::VectorXd> best;
  double best_err = 0;
  for (const Vec3& u : axis_candidates(normals)) {
    // rho = alpha h + beta along the axis: alpha 0 for a cylinder.
    Eigen::MatrixXd a(n.points.size(), 2);
    Eigen::VectorXd b(n.points.size());
    for (std::size_t i = 0; i < n.points.size(); ++i) {
      const Meridian m = meridian(*axis_point, u, n.points[i]);
      a.row(Eigen::Index(i)) << m.h, 1;
      b[Eigen::Index(i)] = m.rho;
    }
    const Eigen::Vector2d line = a.colPivHouseholderQr().solve(b);
    Eigen::VectorXd x(7);
    if (type == PrimitiveType::Cylinder) {
      // Start from the circle through the points projected along u.
      const Vec3 e1 = perpendicular(u), e2 = cross(u, e1);
      std::vector<std::array<double, 2>> q;
      for (const Vec3& p : n.points) q.push_back({dot(p, e1), dot(p, e2)});
      double cx = 0, cy = 0, radius = 0;
      if (!fit_circle_2d(q, cx, cy, radius)) continue;
      const Vec3 c = cx * e1 + cy * e2;
      x << c.x, c.y, c.z, u.x, u.y, u.z, radius;
    } else {
      if (!(std::abs(line[0]) > 1e-3)) continue;  // no opening: a cylinder, not a cone
      const Vec3 dir = line[0] > 0 ? u : -u;
      const Vec3 apex = *axis_point + (-line[1] / line[0]) * u;
      x << apex.x, apex.y, apex.z, dir.x, dir.y, dir.z, std::atan(std::abs(line[0]));
    }
    auto f = type == PrimitiveType::Cylinder ? &cylinder_residual : &cone_residual;
    levenberg_marquardt(x, n.points, f, [](Eigen::VectorXd& v) { normalise_axis(v, 3); });
    if (!x.allFinite()) continue;
    const double err = max_abs_residual(x, n.points, f);
    if (!best || err < best_err) {
      best = x;
      best_err = err;
    }
  }
  if (!best) return std::nullopt;
  const Eigen::VectorXd& x = *best;
  Primitive out;
  out.type = type;
  out.point = n.to_world({x[0], x[1], x[2]});
  out.axis = normalized(Vec3{x[3], x[4], x[5]});
  if (type == PrimitiveType::Cylinder) {
    if (!(x[6] > 0)) return std::nullopt;
    out.radius = x[6] * n.scale;
  } else {
    if (!(x[6] > 0 && x[6] < std::numbers::pi / 2)) return std::nullopt;
    out.angle = x[6];
  }
  return out;
}

std::optional<Primitive> fit_torus(const Normalised& n) {
  if (n.points.size() < 16) return std::nullopt;
  // A closed or nearly closed ring: the axis is the direction the points spread least in,
  // the centre their centroid; the meridian section is then a circle in (rho, h).
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : n.points) {
    const Eigen::Vector3d v(p.x, p.y, p.z);
    cov += v * v.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Vec3 u = normalized(to_vec3(eig.eigenvectors().col(0)));
  std::vector<std::array<double, 2>> q;
  for (const Vec3& p : n.points) {
    const Meridian m = meridian({}, u, p);
    q.push_back({m.rho, m.h});
  }
  double major = 0, h0 = 0, minor = 0;
  if (!fit_circle_2d(q, major, h0, minor)) return std::nullopt;
  const Vec3 c = h0 * u;
  Eigen::VectorXd x(8);
  x << c.x, c.y, c.z, u.x, u.y, u.z, major, minor;
  levenberg_marquardt(x, n.points, &torus_residual,
                      [](Eigen::VectorXd& v) { normalise_axis(v, 3); });
  if (!x.allFinite() || !(x[6] > 0) || !(x[7] > 0)) return std::nullopt;
  Primitive out;
  out.type = PrimitiveType::Torus;
  out.point = n.to_world({x[0], x[1], x[2]});
  out.axis = normalized(Vec3{x[3], x[4], x[5]});
  out.radius = x[6] * n.scale;
  out.minor = x[7] * n.scale;
  return out;
}

}  // namespace

const char* to_string(PrimitiveType type) {
  switch (type) {
    case PrimitiveType::Plane:
      return "plane";
    case PrimitiveType::Sphere:
      return "sphere";
    case PrimitiveType::Cylinder:
      return "cylinder";
    case PrimitiveType::Cone:
      return "cone";
    case PrimitiveType::Torus:
      return "torus";
  }
  return "?";
}

Vec3 Primitive::project(const Vec3& p) const {
  switch (type) {
    case PrimitiveType::Plane:
      return p - dot(p - point, axis) * axis;
    case PrimitiveType::Sphere: {
      const Vec3 d = p - point;
      const double len = norm(d);
      return point + radius * (len > 0 ? d * (1.0 / len) : perpendicular(axis));
    }
    case PrimitiveType::Cylinder: {
      const Meridian m = meridian(point, axis, p);
      return point + m.h * axis + radius * m.e;
    }
    case PrimitiveType::Cone: {
      // The generator in the meridian plane is t (sin a, cos a) in (rho, h).
      const Meridian m = meridian(point, axis, p);
      const double s = std::sin(angle), c = std::cos(angle);
      const double t = std::max(0.0, m.rho * s + m.h * c);
      return point + (t * c) * axis + (t * s) * m.e;
    }
    case PrimitiveType::Torus: {
      const Meridian m = meridian(point, axis, p);
      const double dr = m.rho - radius;
      const double len = std::hypot(dr, m.h);
      const double cr = len > 0 ? dr / len : 1, ch = len > 0 ? m.h / len : 0;
      return point + (minor * ch) * axis + (radius + minor * cr) * m.e;
    }
  }
  return p;
}

Vec3 Primitive::normal_at(const Vec3& p) const {
  if (type == PrimitiveType::Plane) return axis;
  if (type == PrimitiveType::Sphere) return normalized(p - point);
  const Meridian m = meridian(point, axis, p);
  if (!(m.rho > 0)) return {};
  switch (type) {
    case PrimitiveType::Cylinder:
      return m.e;
    case PrimitiveType::Cone:
      // Perpendicular to the generator (sin a, cos a) in (rho, h).
      return std::cos(angle) * m.e - std::sin(angle) * axis;
    case PrimitiveType::Torus: {
      const Vec3 core = point + radius * m.e;
      return normalized(p - core);
    }
    default:
      return {};
  }
}

std::optional<Vec3> project_to_intersection(const Primitive& a, const Primitive& b, const Vec3& p,
                                            double tolerance) {
  if (a.type == PrimitiveType::Plane && b.type == PrimitiveType::Plane) {
    const Vec3 dir = cross(a.axis, b.axis);
    const double len2 = dot(dir, dir);
    if (!(len2 > 1e-20)) return std::nullopt;
    // The point of both planes nearest to p: p moved by a combination of the two normals.
    const double ra = dot(a.point - p, a.axis), rb = dot(b.point - p, b.axis);
    const double nn = dot(a.axis, b.axis);
    const double det = 1 - nn * nn;
    const double s = (ra - nn * rb) / det, t = (rb - nn * ra) / det;
    return p + s * a.axis + t * b.axis;
  }
  Vec3 x = p;
  for (int i = 0; i < 2000; ++i) {
    x = b.project(a.project(x));
    if (a.distance(x) <= tolerance && b.distance(x) <= tolerance) return x;
  }
  return std::nullopt;
}

std::optional<Primitive> fit_primitive(PrimitiveType type, std::span<const Vec3> points,
                                       std::span<const Vec3> normals,
                                       std::span<const Vec3> normal_points) {
  if (points.size() < 3) return std::nullopt;
  const Normalised n = normalise(points);
  switch (type) {
    case PrimitiveType::Plane:
      return fit_plane(n);
    case PrimitiveType::Sphere:
      return fit_sphere(n);
    case PrimitiveType::Cylinder:
    case PrimitiveType::Cone:
      return fit_cylinder_or_cone(type, n, normals, normal_points);
    case PrimitiveType::Torus:
      return fit_torus(n);
  }
  return std::nullopt;
}

}  // namespace stlrefine::primitives
