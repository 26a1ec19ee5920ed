// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/dominant_planes.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"

namespace stlrefine {

HalfedgeId sector_walk_start(const Mesh& m, const Features& features, VertexId v) {
  const HalfedgeId start = m.halfedge(v);
  if (!start.valid() || m.is_boundary(v)) return start;
  HalfedgeId h = start;
  do {
    if (features.is_sharp(m.edge(h))) return h;
    h = m.ccw_rotated(h);
  } while (h != start);
  return start;
}

namespace {

FacePlane face_plane(const Mesh& m, std::uint32_t f) {
  const auto [a, b, c] = m.face_vertices(FaceId(f));
  const Vec3 &pa = m.position(a), &pb = m.position(b), &pc = m.position(c);
  const Vec3 t = cross(pb - pa, pc - pa);
  return {normalized(t), pa, std::max({norm(pb - pa), norm(pc - pb), norm(pa - pc)}),
          0.5 * norm(t)};
}

double max_abs(const Vec3& v) {
  return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

}  // namespace

bool DominantPlanes::on_plane(std::uint32_t f, const Vec3& q, double size) const {
  const FacePlane& pl = plane[f];
  const double magnitude = std::max(max_abs(q), max_abs(pl.p));
  return std::abs(dot(q - pl.p, pl.n)) <= 1e-6 * std::max(pl.size, size) + 4.8e-7 * magnitude;
}

bool DominantPlanes::coplanar(const Mesh& m, std::uint32_t f, std::uint32_t g) const {
  if (f == g) return true;
  const auto [a, b, c] = m.face_vertices(FaceId(g));
  const double size = plane[g].size;
  return on_plane(f, m.position(a), size) && on_plane(f, m.position(b), size) &&
         on_plane(f, m.position(c), size);
}

Vec3 DominantPlanes::project(std::uint32_t f, const Vec3& q) const {
  const FacePlane& pl = plane[f];
  return q - dot(q - pl.p, pl.n) * pl.n;
}

std::uint64_t dominant_planes_bytes(const Mesh& m) {
  return (sizeof(FacePlane) + 3) * std::uint64_t(m.num_faces());
}

DominantPlanes dominant_planes(const Mesh& m, const Features& features) {
  constexpr double kDominance = 2.0;
  const std::size_t nf = m.num_faces();
  DominantPlanes out;
  out.plane.resize(nf);
  out.dominant.assign(3 * nf, 0);
  parallel_for_each_index(
      nf, [&](std::size_t f) { out.plane[f] = face_plane(m, static_cast<std::uint32_t>(f)); });
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    const HalfedgeId start = sector_walk_start(m, features, v);
    if (!start.valid()) return;
    std::vector<HalfedgeId> sector;
    HalfedgeId h = start;
    while (true) {
      sector.push_back(h);
      const HalfedgeId next = m.ccw_rotated(h);
      const bool end = !next.valid() || next == start;
      if (end || features.is_sharp(m.edge(next))) {
        double total = 0;
        for (HalfedgeId g : sector) total += out.plane[g.idx / 3].area;
        for (HalfedgeId g : sector) {
          const std::uint32_t f = g.idx / 3;
          if (out.plane[f].area == 0) continue;
          double held = 0, off = 0, largest_on = 0, largest_off = 0;
          bool lost = false;
          for (HalfedgeId o : sector) {
            const double a = out.plane[o.idx / 3].area;
            if (out.coplanar(m, f, o.idx / 3)) {
              held += a;
              largest_on = std::max(largest_on, a);
            } else {
              largest_off = std::max(largest_off, a);
              off += a;
              // Over half the area off the plane: it cannot dominate (the margin is far
              // above the sums' rounding, so the answer is the full count's). On a scan
              // every face's plane loses after two or three of its neighbours.
              if (2 * off > total * (1 + 1e-9)) {
                lost = true;
                break;
              }
            }
          }
          out.dominant[g.idx] =
              !lost && 2 * held >= total && largest_on >= kDominance * largest_off;
        }
        sector.clear();
      }
      if (end) break;
      h = next;
    }
  });
  return out;
}

}  // namespace stlrefine
