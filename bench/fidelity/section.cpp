// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/section.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

namespace stlrefine::fidelity {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr double kPi = std::numbers::pi;

double azimuth_deg(const Vec3& p) {
  const double a = std::atan2(p.y, p.x) * 180.0 / kPi;
  return a < 0 ? a + 360.0 : a;
}

//! Signed angle from a to b in the xy plane, radians in (-pi, pi].
double signed_angle_xy(const Vec3& a, const Vec3& b) {
  return std::atan2(a.x * b.y - a.y * b.x, a.x * b.x + a.y * b.y);
}

}  // namespace

std::vector<SectionCurve> cut_horizontal(const Mesh& mesh, double z0) {
  auto above = [&](VertexId v) { return mesh.position(v).z >= z0; };

  // One point per crossed edge, shared by the (up to) two faces on it.
  const std::size_t ne = mesh.num_edges();
  std::vector<Vec3> edge_point(ne);
  std::vector<std::array<std::uint32_t, 2>> edge_faces(ne, {kNone, kNone});
  std::vector<std::array<std::uint32_t, 2>> face_edges(mesh.num_faces(), {kNone, kNone});
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    int found = 0;
    for (int k = 0; k < 3; ++k) {
      const HalfedgeId h = Mesh::halfedge(FaceId(f), k);
      const VertexId a = mesh.from(h), b = mesh.to(h);
      if (above(a) == above(b)) continue;
      const EdgeId e = mesh.edge(h);
      if (edge_faces[e.idx][0] == kNone) {
        const Vec3 &pa = mesh.position(a), &pb = mesh.position(b);
        const double t = (z0 - pa.z) / (pb.z - pa.z);
        edge_point[e.idx] = pa + (pb - pa) * t;
        edge_point[e.idx].z = z0;
        edge_faces[e.idx][0] = f;
      } else {
        edge_faces[e.idx][1] = f;
      }
      if (found < 2) face_edges[f][found++] = e.idx;
    }
  }

  std::vector<bool> used(ne, false);
  std::vector<SectionCurve> curves;
  auto walk = [&](std::uint32_t start) {
    SectionCurve c;
    std::uint32_t e = start, from_face = kNone;
    while (true) {
      used[e] = true;
      c.points.push_back(edge_point[e]);
      const auto& ef = edge_faces[e];
      const std::uint32_t f = ef[0] != from_face ? ef[0] : ef[1];
      if (f == kNone) break;  // reached a boundary: open curve
      const std::uint32_t next = face_edges[f][0] == e ? face_edges[f][1] : face_edges[f][0];
      if (next == start) {
        c.closed = true;
        break;
      }
      if (used[next]) break;
      from_face = f;
      e = next;
    }
    curves.push_back(std::move(c));
  };
  // Open curves first, from their boundary ends; then the loops.
  for (std::uint32_t e = 0; e < ne; ++e)
    if (!used[e] && edge_faces[e][0] != kNone && edge_faces[e][1] == kNone) walk(e);
  for (std::uint32_t e = 0; e < ne; ++e)
    if (!used[e] && edge_faces[e][0] != kNone) walk(e);
  return curves;
}

SectionStats analyse_section(const std::vector<SectionCurve>& curves, double r, double window,
                             std::size_t samples) {
  SectionStats s;
  s.curves = curves.size();
  const SectionCurve* loop = nullptr;
  for (const SectionCurve& c : curves)
    if (c.closed && (!loop || c.points.size() > loop->points.size())) loop = &c;
  if (!loop) return s;

  // Drop repeated points (a vertex exactly on the plane) and orient the loop ccw.
  std::vector<Vec3> p;
  for (const Vec3& q : loop->points)
    if (p.empty() || distance(p.back(), q) > 1e-12) p.push_back(q);
  if (p.size() > 1 && distance(p.front(), p.back()) <= 1e-12) p.pop_back();
  const std::size_t n = p.size();
  if (n < 3) return s;
  double area2 = 0;
  for (std::size_t i = 0; i < n; ++i) area2 += cross(p[i], p[(i + 1) % n]).z;
  if (area2 < 0) std::reverse(p.begin(), p.end());
  s.points = n;

  std::vector<double> len(n);
  for (std::size_t i = 0; i < n; ++i) {
    len[i] = distance(p[i], p[(i + 1) % n]);
    s.length += len[i];
    s.radius_max_dev = std::max(s.radius_max_dev, std::abs(std::hypot(p[i].x, p[i].y) - r));
  }

  // Tangent: each segment against the circle's tangent at the segment's midpoint.
  double sum_t2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = p[(i + 1) % n] - p[i];
    const Vec3 mid = (p[i] + p[(i + 1) % n]) * 0.5;
    const Vec3 circle_tangent{-mid.y, mid.x, 0};
    const double dev = signed_angle_xy(circle_tangent, d) * 180.0 / kPi;
    sum_t2 += len[i] * dev * dev;
    s.tangent_max_deg = std::max(s.tangent_max_deg, std::abs(dev));
    s.tangent.push_back({azimuth_deg(mid), dev});
  }
  s.tangent_rms_deg = std::sqrt(sum_t2 / s.length);
  {
    std::vector<double> centre(n);
    double acc = 0;
    for (std::size_t i = 0; i < n; ++i) centre[i] = acc + 0.5 * len[i], acc += len[i];
    for (std::size_t i = 0; i < n; ++i) {
      double sum = 0, weight = 0;
      for (std::size_t j = 0; j < n; ++j) {
        double gap = std::abs(centre[j] - centre[i]);
        gap = std::min(gap, s.length - gap);  // around the loop
        if (gap > 0.5 * window) continue;
        sum += len[j] * s.tangent[j].value;
        weight += len[j];
      }
      const double avg = sum / weight;
      s.tangent_smoothed.push_back({s.tangent[i].polar_deg, avg});
      s.tangent_smoothed_max_deg = std::max(s.tangent_smoothed_max_deg, std::abs(avg));
    }
  }

  // Tangent angle, unwrapped, at each segment's midpoint (arc length mid[i]); the
  // turning at vertex i is the step between segments i - 1 and i.
  std::vector<double> mid(n), angle(n);
  double turning = 0, at = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mid[i] = at + 0.5 * len[i];
    at += len[i];
    const Vec3 d = p[(i + 1) % n] - p[i];
    if (i == 0) {
      angle[0] = std::atan2(d.y, d.x);
    } else {
      const double theta = signed_angle_xy(p[i] - p[i - 1], d);
      angle[i] = angle[i - 1] + theta;
      turning += std::abs(theta);
    }
  }
  const double last_turn = signed_angle_xy(p[0] - p[n - 1], p[1] - p[0]);
  turning += std::abs(last_turn);
  const double total = angle[n - 1] + last_turn - angle[0];  // 2 pi for a ccw simple loop
  s.absolute_turning = turning / (2 * kPi);

  // Phi(s): piecewise linear through (mid[i], angle[i]), extended by whole turns.
  auto phi = [&](double x) {
    const double turns = std::floor((x - mid[0]) / s.length);
    x -= turns * s.length;
    const double base = turns * total;
    const auto it = std::upper_bound(mid.begin(), mid.end(), x);
    const std::size_t j = static_cast<std::size_t>(it - mid.begin()) - 1;  // mid[j] <= x
    const double x1 = j + 1 < n ? mid[j + 1] : mid[0] + s.length;
    const double a1 = j + 1 < n ? angle[j + 1] : angle[0] + total;
    return base + angle[j] + (a1 - angle[j]) * (x - mid[j]) / (x1 - mid[j]);
  };
  s.window = window;
  double sum_k2 = 0, prev_kr = 0, first_kr = 0;
  for (std::size_t j = 0; j < samples; ++j) {
    const double x = s.length * double(j) / double(samples);
    const double kr = (phi(x + 0.5 * window) - phi(x - 0.5 * window)) / window * r;
    sum_k2 += (kr - 1) * (kr - 1);
    s.curvature_max = std::max(s.curvature_max, std::abs(kr - 1));
    if (j == 0)
      first_kr = kr;
    else
      s.curvature_variation += std::abs(kr - prev_kr);
    prev_kr = kr;
    // The point at arc length x, for its azimuth.
    std::size_t seg = 0;
    double acc = 0;
    while (seg + 1 < n && acc + len[seg] < x) acc += len[seg++];
    const Vec3 q = p[seg] + (p[(seg + 1) % n] - p[seg]) * ((x - acc) / len[seg]);
    s.curvature.push_back({azimuth_deg(q), kr});
  }
  s.curvature_variation += std::abs(first_kr - prev_kr);
  s.curvature_rms = std::sqrt(sum_k2 / double(samples));
  return s;
}

}  // namespace stlrefine::fidelity
