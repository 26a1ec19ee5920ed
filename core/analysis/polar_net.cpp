// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/analysis/polar_net.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <utility>

#include "core/error.h"

namespace stlrefine::analysis {

int PolarLayout::ring_of(int position) {
  int r = 1;
  while (r * (r + 1) / 2 <= position) ++r;
  return r;
}

void PolarLayout::lattice(int position, int& a, int& b) {
  const int r = ring_of(position);
  b = position - (r - 1) * r / 2;
  a = r - b;
}

PolarNet make_polar_net(int n, int rings) {
  if (n < 3 || rings < 1)
    throw Error(ErrorCode::Internal, "bad_polar_net", "a polar net needs valence >= 3, rings >= 1");
  PolarNet net;
  net.layout = {n, rings};
  const PolarLayout& lay = net.layout;
  BigVector<Vec3> positions(lay.size());
  positions[0] = {0, 0, 0};
  auto spoke = [n](int k) {
    const double t = 2 * std::numbers::pi * k / n;
    return Vec3(std::cos(t), std::sin(t), 0);
  };
  for (int p = 0; p < lay.positions(); ++p) {
    int a, b;
    PolarLayout::lattice(p, a, b);
    for (int k = 0; k < n; ++k) positions[lay.index(p, k)] = a * spoke(k) + b * spoke(k + 1);
  }
  // Vertex of lattice point (a, b) of sector k, a + b <= rings.
  auto vid = [&](int k, int a, int b) -> std::uint32_t {
    if (a == 0 && b == 0) return 0;
    if (a == 0) return static_cast<std::uint32_t>(lay.index(PolarLayout::position(b, 0), k + 1));
    return static_cast<std::uint32_t>(lay.index(PolarLayout::position(a, b), k));
  };
  // Sector k:  (a,b+1) --- (a+1,b+1)     up: (a,b), (a+1,b), (a,b+1)
  //              |  \   down  |          down: (a+1,b), (a+1,b+1), (a,b+1)
  //            (a,b) --- (a+1,b)         (counter-clockwise: u_k+1 is 60 degrees past u_k)
  BigVector<VertexId> corners;
  for (int k = 0; k < n; ++k) {
    for (int a = 0; a < rings; ++a) {
      for (int b = 0; a + b < rings; ++b) {
        for (std::uint32_t v : {vid(k, a, b), vid(k, a + 1, b), vid(k, a, b + 1)})
          corners.push_back(VertexId(v));
        if (a + b + 2 <= rings)
          for (std::uint32_t v : {vid(k, a + 1, b), vid(k, a + 1, b + 1), vid(k, a, b + 1)})
            corners.push_back(VertexId(v));
      }
    }
  }
  net.mesh = mesh_from_triangles(std::move(positions), std::move(corners));
  net.ids.resize(lay.size());
  for (int i = 0; i < lay.size(); ++i) net.ids[i] = VertexId(static_cast<std::uint32_t>(i));
  return net;
}

Mesh mesh_from_triangles(BigVector<Vec3> positions, BigVector<VertexId> corners) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> directed;
  for (std::uint32_t h = 0; h < corners.size(); ++h) {
    const std::uint32_t next = h % 3 == 2 ? h - 2 : h + 1;
    directed[{corners[h].idx, corners[next].idx}] = h;
  }
  BigVector<HalfedgeId> twins(corners.size());
  for (const auto& [edge, h] : directed) {
    const auto it = directed.find({edge.second, edge.first});
    twins[h] = it == directed.end() ? HalfedgeId() : HalfedgeId(it->second);
  }
  return Mesh::from_parts(std::move(positions), std::move(corners), std::move(twins));
}

namespace {

// The outgoing half-edge that continues g straight through to(g) on the lattice: three
// turns from the way back. Invalid when to(g) is on a boundary.
HalfedgeId straight_on(const Mesh& m, HalfedgeId g) {
  HalfedgeId h = m.twin(g);
  for (int i = 0; i < 3 && h.valid(); ++i) h = m.ccw_rotated(h);
  return h;
}

bool interior_valence6(const Mesh& m, VertexId v) {
  return !m.is_boundary(v) && m.valence(v) == 6;
}

}  // namespace

std::vector<VertexId> walk_polar_net(const Mesh& m, HalfedgeId spoke0, int rings) {
  const VertexId centre = m.from(spoke0);
  if (m.is_boundary(centre)) return {};
  const int n = m.valence(centre);
  if (n < 3) return {};
  const PolarLayout lay{n, rings};
  std::vector<VertexId> ids(lay.size());
  ids[0] = centre;
  HalfedgeId spoke = spoke0;
  for (int k = 0; k < n; ++k, spoke = m.ccw_rotated(spoke)) {
    HalfedgeId along = spoke;  // arrives at (k, a, 0) in direction u_k
    for (int a = 1; a <= rings; ++a) {
      const VertexId x = m.to(along);
      if (!interior_valence6(m, x)) return {};
      ids[lay.index(PolarLayout::position(a, 0), k)] = x;
      const HalfedgeId ahead = straight_on(m, along);
      if (!ahead.valid()) return {};
      // u_k+1 is the next direction counter-clockwise; walk it for b = 1..rings - a.
      HalfedgeId side = m.ccw_rotated(ahead);
      for (int b = 1; a + b <= rings && side.valid(); ++b) {
        const VertexId y = m.to(side);
        if (!interior_valence6(m, y)) return {};
        ids[lay.index(PolarLayout::position(a, b), k)] = y;
        if (a + b < rings) side = straight_on(m, side);
      }
      if (!side.valid()) return {};
      along = ahead;
    }
  }
  std::vector<VertexId> sorted = ids;
  std::sort(sorted.begin(), sorted.end(), [](VertexId x, VertexId y) { return x.idx < y.idx; });
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return {};
  return ids;
}

}  // namespace stlrefine::analysis
