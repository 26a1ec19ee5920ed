// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

namespace stlrefine::fidelity {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
//! Faces meeting at less than this are one smooth piece for labelling (rims are 90 deg).
constexpr double kPatchBreakDeg = 60.0;

double dihedral_deg(const Vec3& n0, const Vec3& n1) {
  return std::acos(std::clamp(dot(n0, n1), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

//! Labels every face with the surface piece it belongs to: faces are grouped into smooth
//! patches (flood fill across edges flatter than kPatchBreakDeg), and each patch takes the
//! piece most of its face centroids are closest to. Robust where a single face near a rim
//! would be closer to the other piece.
std::vector<std::uint32_t> face_pieces(const Mesh& mesh, const TrueSurface& surface,
                                       const std::vector<Vec3>& unit_normal) {
  const std::size_t nf = mesh.num_faces();
  std::vector<std::uint32_t> patch(nf, kNone);
  std::vector<std::uint32_t> label;
  std::vector<std::uint32_t> stack;
  for (std::uint32_t seed = 0; seed < nf; ++seed) {
    if (patch[seed] != kNone) continue;
    const auto id = static_cast<std::uint32_t>(label.size());
    std::vector<std::size_t> votes(surface.pieces().size(), 0);
    patch[seed] = id;
    stack.push_back(seed);
    while (!stack.empty()) {
      const std::uint32_t f = stack.back();
      stack.pop_back();
      const auto v = mesh.face_vertices(FaceId(f));
      const Vec3 c = (mesh.position(v[0]) + mesh.position(v[1]) + mesh.position(v[2])) * (1.0 / 3);
      ++votes[surface.closest(c).piece];
      for (int k = 0; k < 3; ++k) {
        const HalfedgeId t = mesh.twin(Mesh::halfedge(FaceId(f), k));
        if (!t.valid()) continue;
        const std::uint32_t g = Mesh::face(t).idx;
        if (patch[g] != kNone) continue;
        if (dihedral_deg(unit_normal[f], unit_normal[g]) >= kPatchBreakDeg) continue;
        patch[g] = id;
        stack.push_back(g);
      }
    }
    label.push_back(
        static_cast<std::uint32_t>(std::max_element(votes.begin(), votes.end()) - votes.begin()));
  }
  std::vector<std::uint32_t> piece(nf);
  for (std::size_t f = 0; f < nf; ++f) piece[f] = label[patch[f]];
  return piece;
}

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(dot(a, b), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

}  // namespace

Metrics measure(const Mesh& mesh, const TrueSurface& surface, double crease_angle_deg,
                std::size_t samples) {
  Metrics m;
  const std::size_t nf = mesh.num_faces();
  m.faces = nf;
  m.vertices = mesh.num_vertices();

  std::vector<Vec3> unit_normal(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    unit_normal[f] = normalized(mesh.face_normal(FaceId(static_cast<std::uint32_t>(f))));
    if (unit_normal[f] == Vec3{}) ++m.degenerate_faces;
  }

  // Normals are compared with the true normal of the piece (side, cap, ...) nearest to the
  // face's centroid, not to each sample: near a rim a side face's sample can be closer to
  // the cap plane than to the side, but its normal should still be the side's.
  std::vector<std::uint32_t> own_piece(nf);
  for (std::uint32_t f = 0; f < nf; ++f) {
    const auto fv = mesh.face_vertices(FaceId(f));
    own_piece[f] = static_cast<std::uint32_t>(
        surface
            .closest((mesh.position(fv[0]) + mesh.position(fv[1]) + mesh.position(fv[2])) *
                     (1.0 / 3))
            .piece);
  }

  // --- distance and normal deviation, sampled inside the faces
  const int k = std::clamp(static_cast<int>(std::ceil(
                               std::sqrt(double(samples) / double(std::max<std::size_t>(nf, 1))))),
                           3, 32);
  double sum_w = 0, sum_d2 = 0, sum_a2 = 0;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const auto fv = mesh.face_vertices(FaceId(f));
    const Vec3 &a = mesh.position(fv[0]), &b = mesh.position(fv[1]), &c = mesh.position(fv[2]);
    const Vec3& n = unit_normal[f];
    const double w = 0.5 * norm(mesh.face_normal(FaceId(f))) / (k * k);
    auto at = [&](double s, double t) { return a + (b - a) * s + (c - a) * t; };
    auto rms_sample = [&](double s, double t) {
      const Vec3 p = at(s, t);
      const double d = surface.closest(p).distance;
      sum_d2 += w * d * d;
      sum_w += w;
      if (n != Vec3{}) {
        const double ang = angle_deg(n, surface.normal(p, own_piece[f]));
        sum_a2 += w * ang * ang;
        m.normal_max_deg = std::max(m.normal_max_deg, ang);
      }
    };
    // The k^2 sub-triangles of a k x k barycentric split have equal area: their centroids
    // are an area-weighted sample.
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j) {
        rms_sample((i + 1.0 / 3) / k, (j + 1.0 / 3) / k);
        if (i + j + 1 < k) rms_sample((i + 2.0 / 3) / k, (j + 2.0 / 3) / k);
      }
    for (int i = 0; i <= k; ++i)
      for (int j = 0; i + j <= k; ++j) {
        const Vec3 p = at(double(i) / k, double(j) / k);
        const double d = surface.closest(p).distance;
        if (d > m.max) {
          m.max = d;
          m.worst_point = p;
          m.worst_face = FaceId(f);
        }
      }
    if (n != Vec3{}) {
      const Vec3 centroid = (a + b + c) * (1.0 / 3);
      if (angle_deg(n, surface.normal(centroid, own_piece[f])) > 90.0) ++m.folds;
    }
  }
  m.rms = sum_w > 0 ? std::sqrt(sum_d2 / sum_w) : 0;
  m.normal_rms_deg = sum_w > 0 ? std::sqrt(sum_a2 / sum_w) : 0;

  // --- sharp edges
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h) {
    const HalfedgeId t = mesh.twin(HalfedgeId(h));
    if (!t.valid() || t.idx < h) continue;
    if (dihedral_deg(unit_normal[h / 3], unit_normal[t.idx / 3]) > crease_angle_deg)
      ++m.sharp_edges;
  }

  // --- caps and rims, from the piece each vertex's faces belong to
  const std::vector<std::uint32_t> piece = face_pieces(mesh, surface, unit_normal);
  const std::size_t nv = mesh.num_vertices();
  std::vector<std::uint32_t> vertex_piece(nv, kNone);
  std::vector<bool> mixed(nv, false);
  for (std::uint32_t f = 0; f < nf; ++f)
    for (const VertexId v : mesh.face_vertices(FaceId(f))) {
      if (vertex_piece[v.idx] == kNone)
        vertex_piece[v.idx] = piece[f];
      else if (vertex_piece[v.idx] != piece[f])
        mixed[v.idx] = true;
    }
  const bool has_rims = std::isfinite(surface.rim_distance({0, 0, 0}));
  bool has_caps = false;
  for (const ProfilePiece& p : surface.pieces()) has_caps = has_caps || p.flat_cap;
  if (has_caps) m.cap_max = 0;
  if (has_rims) m.rim_max = 0;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (vertex_piece[v] == kNone) continue;  // isolated
    const Vec3& p = mesh.position(VertexId(v));
    const bool rim = mixed[v] || mesh.is_boundary(VertexId(v));
    if (rim && has_rims) {
      ++m.rim_vertices;
      m.rim_max = std::max(m.rim_max, surface.rim_distance(p));
    }
    if (!mixed[v] && surface.pieces()[vertex_piece[v]].flat_cap) {
      ++m.cap_vertices;
      m.cap_max = std::max(m.cap_max, surface.cap_plane_distance(p, vertex_piece[v]));
    }
  }
  return m;
}

}  // namespace stlrefine::fidelity
