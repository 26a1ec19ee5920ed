// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/build_mesh.h"

#include <algorithm>
#include <cmath>
#include <queue>

#include "core/error.h"

namespace stlrefine {

namespace {

constexpr std::uint32_t kNone = HalfedgeId::kInvalid;

// Triangles over compacted vertex ids, index-degenerate facets removed.
struct CleanSoup {
  BigVector<Vec3> positions;
  BigVector<VertexId> corners;  // 3 per face
};

CleanSoup drop_degenerate_and_unused(const IndexedSoup& soup, IngestReport& report) {
  CleanSoup out;
  std::vector<std::uint32_t> remap(soup.positions.size(), kNone);
  out.corners.reserve(soup.triangles.size() * 3);
  for (const auto& t : soup.triangles) {
    for (std::uint32_t i : t) {
      if (i >= soup.positions.size())
        throw Error(ErrorCode::Internal, "bad_index", "triangle index out of range");
    }
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
      ++report.index_degenerate_removed;
      continue;
    }
    for (std::uint32_t i : t) {
      if (remap[i] == kNone) {
        remap[i] = static_cast<std::uint32_t>(out.positions.size());
        out.positions.push_back(soup.positions[i]);
      }
      out.corners.push_back(VertexId(remap[i]));
    }
  }
  report.isolated_vertices_removed = soup.positions.size() - out.positions.size();
  return out;
}

// A pairing of half-edges into twins, before orientation is repaired: pairs may still
// run in the same direction (inconsistent winding).
struct Pairing {
  std::vector<std::uint32_t> partner;  // per half-edge, kNone when unpaired
};

// Order of the faces around a non-manifold edge lo->hi, by the angle of their third
// vertex about the edge axis.
struct FanEntry {
  double angle;
  std::uint32_t halfedge;
  bool forward;  // the half-edge runs lo -> hi
};

// Pairs the faces at an edge shared by more than two facets. Walking ccw about the axis
// lo->hi, a facet running hi->lo followed by one running lo->hi enclose solid between
// them (their normals point out of the wedge): those two are twins. The rest are cut.
void pair_non_manifold(const CleanSoup& s, std::vector<FanEntry>& fan, Pairing& pairing) {
  const std::uint32_t h0 = fan[0].halfedge;
  const VertexId a = fan[0].forward ? s.corners[h0] : s.corners[h0 % 3 == 2 ? h0 - 2 : h0 + 1];
  const VertexId b = fan[0].forward ? s.corners[h0 % 3 == 2 ? h0 - 2 : h0 + 1] : s.corners[h0];
  const Vec3 pa = s.positions[a.idx];
  const Vec3 axis = normalized(s.positions[b.idx] - pa);
  Vec3 e1, e2;
  for (auto& entry : fan) {
    const std::uint32_t h = entry.halfedge;
    const VertexId o = s.corners[h % 3 == 0 ? h + 2 : h - 1];
    Vec3 w = s.positions[o.idx] - pa;
    w -= axis * dot(w, axis);
    if (&entry == &fan[0]) {
      e1 = normalized(w);
      e2 = cross(axis, e1);
    }
    entry.angle = std::atan2(dot(w, e2), dot(w, e1));
  }
  std::sort(fan.begin(), fan.end(), [](const FanEntry& x, const FanEntry& y) {
    return x.angle < y.angle || (x.angle == y.angle && x.halfedge < y.halfedge);
  });
  const std::size_t k = fan.size();
  for (std::size_t i = 0; i < k; ++i) {
    const FanEntry& cur = fan[i];
    const FanEntry& nxt = fan[(i + 1) % k];
    if (!cur.forward && nxt.forward && pairing.partner[cur.halfedge] == kNone &&
        pairing.partner[nxt.halfedge] == kNone) {
      pairing.partner[cur.halfedge] = nxt.halfedge;
      pairing.partner[nxt.halfedge] = cur.halfedge;
    }
  }
}

Pairing pair_halfedges(const CleanSoup& s, IngestReport& report) {
  const std::size_t nh = s.corners.size();
  const std::size_t nv = s.positions.size();
  auto from = [&](std::uint32_t h) { return s.corners[h].idx; };
  auto to = [&](std::uint32_t h) { return s.corners[h % 3 == 2 ? h - 2 : h + 1].idx; };

  // Bucket half-edges by their lower endpoint (counting sort), then group by the upper.
  std::vector<std::uint32_t> offset(nv + 1, 0);
  for (std::uint32_t h = 0; h < nh; ++h) ++offset[std::min(from(h), to(h)) + 1];
  for (std::size_t v = 0; v < nv; ++v) offset[v + 1] += offset[v];
  std::vector<std::uint32_t> bucket(nh);
  {
    std::vector<std::uint32_t> fill(offset.begin(), offset.end() - 1);
    for (std::uint32_t h = 0; h < nh; ++h) bucket[fill[std::min(from(h), to(h))]++] = h;
  }

  Pairing pairing{std::vector<std::uint32_t>(nh, kNone)};
  std::vector<FanEntry> fan;
  for (std::size_t v = 0; v < nv; ++v) {
    auto* begin = bucket.data() + offset[v];
    auto* end = bucket.data() + offset[v + 1];
    auto upper = [&](std::uint32_t h) { return std::max(from(h), to(h)); };
    std::sort(begin, end, [&](std::uint32_t x, std::uint32_t y) {
      return upper(x) < upper(y) || (upper(x) == upper(y) && x < y);
    });
    for (auto* run = begin; run != end;) {
      auto* run_end = run;
      while (run_end != end && upper(*run_end) == upper(*run)) ++run_end;
      const std::size_t count = run_end - run;
      if (count == 2) {
        pairing.partner[run[0]] = run[1];
        pairing.partner[run[1]] = run[0];
        if (from(run[0]) == from(run[1])) ++report.inconsistent_edges;
      } else if (count > 2) {
        ++report.non_manifold_edges;
        fan.clear();
        for (auto* p = run; p != run_end; ++p)
          fan.push_back({0.0, *p, from(*p) == static_cast<std::uint32_t>(v)});
        pair_non_manifold(s, fan, pairing);
      }
      run = run_end;
    }
  }
  return pairing;
}

// Chooses a winding per face so every paired edge runs both ways. Breadth-first over each
// connected sheet; the winding most of the sheet's facets already had wins. A pair that
// cannot be made consistent (non-orientable sheet) is cut.
std::vector<std::uint8_t> orient_faces(const CleanSoup& s, Pairing& pairing, IngestReport& report) {
  const std::size_t nf = s.corners.size() / 3;
  std::vector<std::uint8_t> flip(nf, 0), seen(nf, 0);
  std::vector<std::uint32_t> component;
  std::queue<std::uint32_t> queue;
  for (std::uint32_t seed = 0; seed < nf; ++seed) {
    if (seen[seed]) continue;
    component.clear();
    seen[seed] = 1;
    queue.push(seed);
    while (!queue.empty()) {
      const std::uint32_t f = queue.front();
      queue.pop();
      component.push_back(f);
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t h = 3 * f + k;
        const std::uint32_t t = pairing.partner[h];
        if (t == kNone) continue;
        const std::uint32_t g = t / 3;
        // Same start vertex means the two facets wind the same way along the edge.
        const bool same_direction = s.corners[h] == s.corners[t];
        const std::uint8_t wanted = flip[f] ^ (same_direction ? 1 : 0);
        if (!seen[g]) {
          seen[g] = 1;
          flip[g] = wanted;
          queue.push(g);
        } else if (flip[g] != wanted) {
          pairing.partner[h] = kNone;
          pairing.partner[t] = kNone;
          ++report.non_orientable_cuts;
        }
      }
    }
    std::size_t flipped = 0;
    for (std::uint32_t f : component) flipped += flip[f];
    if (2 * flipped > component.size()) {
      for (std::uint32_t f : component) flip[f] ^= 1;
      flipped = component.size() - flipped;
    }
    report.faces_reoriented += flipped;
  }
  return flip;
}

// Splits every vertex whose corners form more than one fan: the first fan keeps the id,
// each other fan gets a copy of the position.
void split_fans(BigVector<Vec3>& positions, BigVector<VertexId>& corners,
                const BigVector<HalfedgeId>& twin, IngestReport& report) {
  const std::size_t nh = corners.size();
  auto ccw = [&](std::uint32_t h) { return twin[h % 3 == 0 ? h + 2 : h - 1].idx; };
  auto cw = [&](std::uint32_t h) {
    const std::uint32_t t = twin[h].idx;
    return t == kNone ? kNone : (t % 3 == 2 ? t - 2 : t + 1);
  };
  std::vector<std::uint8_t> visited(nh, 0);
  std::vector<std::uint32_t> fans_at(positions.size(), 0);
  const std::size_t original_vertices = positions.size();
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (visited[h]) continue;
    // Find the most clockwise half-edge of h's fan, then claim the fan walking ccw.
    std::uint32_t start = h;
    for (std::uint32_t c = cw(start); c != kNone && c != h; c = cw(c)) start = c;
    const VertexId v = corners[h];
    VertexId id = v;
    if (fans_at[v.idx]++ > 0) {
      id = VertexId(static_cast<std::uint32_t>(positions.size()));
      positions.push_back(positions[v.idx]);
      ++report.vertices_duplicated;
    }
    std::uint32_t g = start;
    do {
      visited[g] = 1;
      corners[g] = id;
      g = ccw(g);
    } while (g != kNone && g != start);
  }
  for (std::size_t v = 0; v < original_vertices; ++v)
    if (fans_at[v] > 1) ++report.non_manifold_vertices;
}

}  // namespace

IngestResult build_mesh(const IndexedSoup& soup) {
  IngestResult result;
  IngestReport& report = result.report;
  report.input_triangles = soup.triangles.size();
  report.input_vertices = soup.positions.size();

  CleanSoup clean = drop_degenerate_and_unused(soup, report);
  if (clean.corners.empty()) {
    throw Error(ErrorCode::NotTriangleMesh, "no_faces",
                soup.triangles.empty() ? "the mesh has no triangles"
                                       : "every triangle is degenerate (two identical corners)");
  }

  Pairing pairing = pair_halfedges(clean, report);
  const std::vector<std::uint8_t> flip = orient_faces(clean, pairing, report);

  // Reversing a face (v0,v1,v2) -> (v0,v2,v1) maps its half-edge k to 2-k.
  const std::size_t nh = clean.corners.size();
  auto moved = [&](std::uint32_t h) { return flip[h / 3] ? 3 * (h / 3) + (2 - h % 3) : h; };
  for (std::size_t f = 0; f < flip.size(); ++f)
    if (flip[f]) std::swap(clean.corners[3 * f + 1], clean.corners[3 * f + 2]);
  BigVector<HalfedgeId> twin(nh);
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (pairing.partner[h] != kNone) twin[moved(h)] = HalfedgeId(moved(pairing.partner[h]));
  }

  split_fans(clean.positions, clean.corners, twin, report);
  result.mesh =
      Mesh::from_parts(std::move(clean.positions), std::move(clean.corners), std::move(twin));
  for (std::size_t f = 0; f < result.mesh.num_faces(); ++f) {
    if (dot(result.mesh.face_normal(FaceId(f)), result.mesh.face_normal(FaceId(f))) == 0)
      ++report.zero_area_faces;
  }
  return result;
}

}  // namespace stlrefine
