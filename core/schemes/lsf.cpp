// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf.h"

#include <cstddef>
#include <memory>
#include <numbers>
#include <vector>

#include "core/parallel.h"
#include "core/schemes/lsf_kernels.h"
#include "core/schemes/lsf_rules.h"
#include "core/schemes/lsf_solver.h"

// The stencil: per vertex the sector fits (lsf_solver.h) or the batch kernels
// (lsf_kernels.h) give each smooth edge two estimates, the guard (lsf_rules.h) makes them an
// edge point.

namespace stlrefine {

namespace {

using lsf::fit_sample;
using lsf::ring_sample;
using lsf::Sample;
using lsf::SampleFit;
using lsf::sector_sample;

//! Walks v's ring once and fits one quadric per sector (the whole ring for smooth and dart
//! vertices), calling on_sector(fit, ring, begin) for each sector: points begin..begin +
//! fit.sample->size of `ring`. ring.spoke[i] is the outgoing half-edge to ring point i
//! (invalid for the point that closes an open fan), ring.sharp[i] whether it is sharp.
//! Crease sectors are scaled to pi, corners keep natural angles.
template <class OnSector>
void for_each_sector_fit(const Mesh& m, const Features& f, VertexId v, OnSector&& on_sector) {
  const HalfedgeId start = m.halfedge(v);
  if (!start.valid()) return;
  Sample& ring = ring_sample();
  const Vec3 p = m.position(v);
  const VertexKind kind = f.kind(v);
  if (kind == VertexKind::Smooth) {
    // No sharp spoke, and not on a boundary (boundary edges are sharp): a closed ring.
    // Through local pointers: stores to the sample's arrays would otherwise make the compiler
    // reload its fields after each one.
    HalfedgeId h = start;
    std::size_t n = 0, capacity = ring.capacity;
    double *x = ring.x, *y = ring.y, *z = ring.z;
    HalfedgeId* spoke = ring.spoke.data();
    do {
      if (n + 2 >= capacity) {
        ring.size = n;
        ring.reserve(n + 1);
        capacity = ring.capacity, x = ring.x, y = ring.y, z = ring.z, spoke = ring.spoke.data();
      }
      const Vec3 d = m.position(m.to(h)) - p;
      x[n] = d.x, y[n] = d.y, z[n] = d.z;
      spoke[n] = h;
      ++n;
      h = m.ccw_rotated(h);
    } while (h.valid() && h != start);
    ring.size = n;  // and ring.any_sharp stays false: ring.sharp is not read
    if (h.valid()) {
      on_sector(fit_sample(ring, true, 2.0 * std::numbers::pi), ring, std::size_t{0});
      return;
    }
    ring.clear();  // not expected: treat it like any other vertex
  }
  // Start a closed ring at a sharp spoke so every sector is a contiguous run.
  HalfedgeId first = start;
  if (!m.is_boundary(v) && kind >= VertexKind::Crease) {
    for_each_outgoing(m, v, [&](HalfedgeId h) {
      if (f.is_sharp(m.edge(h)) && !f.is_sharp(m.edge(first))) first = h;
    });
  }
  HalfedgeId h = first, last;
  do {
    ring.push(m.position(m.to(h)) - p, h, f.is_sharp(m.edge(h)));
    last = h;
    h = m.ccw_rotated(h);
  } while (h.valid() && h != first);
  const bool closed = h.valid();
  if (!closed) ring.push(m.position(m.from(Mesh::prev(last))) - p, HalfedgeId(), true);

  if (kind <= VertexKind::Dart) {
    // Smooth or dart: the whole ring, angles scaled to 2 pi (a dart's crease is ignored).
    on_sector(fit_sample(ring, true, 2.0 * std::numbers::pi), ring, std::size_t{0});
    return;
  }
  // Crease and corner: one fit per sector between consecutive sharp spokes, including the
  // two sharp neighbours that bound it.
  const double total = kind == VertexKind::Crease ? std::numbers::pi : 0.0;
  if (closed) {
    // The sector that wraps around ends at the first spoke.
    ring.push(Vec3(ring.x[0], ring.y[0], ring.z[0]), HalfedgeId(), true);
  }
  Sample& sector = sector_sample();
  std::size_t sector_begin = 0;
  for (std::size_t i = 1; i < ring.size; ++i) {
    if (!ring.sharp[i]) continue;
    sector.assign(ring, sector_begin, i - sector_begin + 1);
    on_sector(fit_sample(sector, false, total), ring, sector_begin);
    sector_begin = i;
  }
}

// The fitted surface of v at half of each smooth spoke's parameter, passed to
// sink(spoke, point); a degenerate sample gives the chord midpoint.
template <class Sink>
void vertex_estimates(const Mesh& m, const Features& f, VertexId v, Sink&& sink) {
  const Vec3 p = m.position(v);
  for_each_sector_fit(m, f, v, [&](const SampleFit& fit, const Sample& ring, std::size_t begin) {
    fit.half_points([&](std::size_t i, const Vec3& offset) {
      const std::size_t k = begin + i;
      if (ring.spoke[k].valid() && !(ring.any_sharp && ring.sharp[k]))
        sink(ring.spoke[k], p + offset);
    });
  });
}
}  // namespace

void LsfStencil::half_edge_estimates(const Mesh& m, const Features& f, VertexId v,
                                     std::span<Vec3> out) {
  vertex_estimates(m, f, v, [&](HalfedgeId s, const Vec3& point) { out[s.idx] = point; });
}

QuadricFit vertex_fit(const Mesh& m, const Features& f, VertexId v) {
  QuadricFit first;
  first.origin = m.position(v);
  bool have = false;
  if (f.kind(v) == VertexKind::Corner) return first;
  for_each_sector_fit(m, f, v, [&](const SampleFit& fit, const Sample&, std::size_t) {
    if (!have) first = fit.quadric(m.position(v)), have = true;
  });
  return first;
}
void LsfStencil::edge_points(const Level& coarse, std::span<Vec3> out) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  // Each smooth edge gets one estimate from each endpoint: the one along the edge's
  // lower-numbered half-edge goes straight into `out`, the other into `twin_estimate` (one
  // slot per edge, not per half-edge: half the memory, and the averaging pass below reads
  // both arrays in order; it adds the two in either order, which floating-point addition
  // allows). Every half-edge belongs to one vertex, so the writes never collide.
  // Raw storage, left uninitialised (every slot read is written first), from the plain heap,
  // not a BigVector: glibc hands the same pages back at the next level or refinement
  // instead of mapping (and the kernel zeroing) fresh ones each time, about 5% of an
  // armadillo refinement; huge pages are still asked for when it is large.
  struct RawVec3s {
    Vec3* data;
    std::size_t size;
    explicit RawVec3s(std::size_t n) : data(std::allocator<Vec3>().allocate(n)), size(n) {}
    ~RawVec3s() { std::allocator<Vec3>().deallocate(data, size); }
    RawVec3s(const RawVec3s&) = delete;
    RawVec3s& operator=(const RawVec3s&) = delete;
  } twin_estimate(m.num_edges());
  advise_huge_pages(twin_estimate.data, m.num_edges() * sizeof(Vec3));
  const lsf::EstimateSlots slots{out.data(), twin_estimate.data};
  auto sink = [&](HalfedgeId s, const Vec3& point) {
    *slots.at(m.edge(s), s.idx < m.twin(s).idx) = point;
  };
  std::vector<lsf::GuardVertex> guard(m.num_vertices());
  parallel_for_each_range(m.num_vertices(), [&](std::size_t begin, std::size_t end) {
    lsf::Batches batches(kernel_);
    for (std::size_t i = begin; i < end; ++i) {
      const VertexId v(static_cast<std::uint32_t>(i));
      const VertexKind kind = f.kind(v);
      const bool batched =
          kind <= VertexKind::Dart
              ? lsf::batch_smooth_vertex(m, v, slots, batches,
                                         kind == VertexKind::Smooth ? &guard[i] : nullptr)
          : kind == VertexKind::Crease ? lsf::batch_crease_vertex(m, f, v, slots, batches)
                                       : false;
      if (!batched) vertex_estimates(m, f, v, sink);
      // The guard's normal of a one-sector vertex, once (crease and corner vertices' sector
      // normals are found where they are needed).
      if (kind <= VertexKind::Dart && !(batched && kind == VertexKind::Smooth) &&
          m.halfedge(v).valid()) {
        guard[i].normal = lsf::sector_normal(m, f, m.halfedge(v));
        guard[i].spokes = lsf::ring_spoke_flags(m, v);
      }
      guard[i].one_sector = kind <= VertexKind::Dart;
      guard[i].batched_smooth = batched && kind == VertexKind::Smooth;
    }
    batches.flush();
    // The batch kernel's normals are the face sums alone: where a plane rules a ring that is
    // not all flat, its normal instead, as sector_normal gives for the others.
    for (std::size_t i = begin; i < end; ++i) {
      if (!guard[i].batched_smooth || guard[i].flat ||
          !(guard[i].spokes & lsf::GuardVertex::kNotEven))
        continue;
      Vec3 plane;
      if (lsf::dominant_plane(m, VertexId(static_cast<std::uint32_t>(i)), plane))
        guard[i].normal = plane;
    }
  });
  lsf::SectorNormals sectors;
  lsf::relax_guard_normals(m, f, guard, sectors, /*lsf_terms=*/true);
  const lsf::GuardNormals normal_of{m, f, guard.data(), &sectors};
  // The guard reads, per edge, the corners of its two faces, their four positions and its ends'
  // guard records: a chain of dependent loads at random places, which the edges before it
  // cannot hide. So they are prefetched, a stage of the chain at a time, kPrefetch edges apart
  // (no result depends on it).
  const std::span<const HalfedgeId> edge_halfedge = m.edge_halfedges(), twins = m.twins();
  const std::span<const VertexId> corners = m.corner_vertices();
  const std::span<const Vec3> positions = m.positions();
  constexpr std::size_t kPrefetch = 6;
  parallel_for_each_range(m.num_edges(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t e = begin; e < end; ++e) {
      if (e + 3 * kPrefetch < end) {  // the edge's twin and its first face's corners
        const HalfedgeId h = edge_halfedge[e + 3 * kPrefetch];
        __builtin_prefetch(&twins[h.idx]);
        __builtin_prefetch(&corners[h.idx]);
      }
      if (e + 2 * kPrefetch < end) {  // the other face's corners, the first face's positions
        const HalfedgeId h = edge_halfedge[e + 2 * kPrefetch], t = twins[h.idx];
        if (t.valid()) __builtin_prefetch(&corners[t.idx]);
        const VertexId a = corners[h.idx], b = corners[Mesh::next(h).idx];
        __builtin_prefetch(&positions[a.idx]);
        __builtin_prefetch(&positions[b.idx]);
        __builtin_prefetch(&positions[corners[Mesh::prev(h).idx].idx]);
        __builtin_prefetch(&guard[a.idx]);
        __builtin_prefetch(&guard[b.idx]);
      }
      if (e + kPrefetch < end) {  // the other face's far corner
        const HalfedgeId t = twins[edge_halfedge[e + kPrefetch].idx];
        if (t.valid()) __builtin_prefetch(&positions[corners[Mesh::prev(t).idx].idx]);
      }
      const EdgeId edge(static_cast<std::uint32_t>(e));
      if (f.is_sharp(edge)) {
        out[e] = lsf_guarded_curve_point(m, f, edge, lsf_curve_point(m, f, m.halfedge(edge)));
        continue;
      }
      out[e] = lsf::guarded_edge_point(normal_of, edge, out[e], twin_estimate.data[e]);
    }
  });
  // The children with every edge point known: the estimates are no longer needed, so their
  // storage holds the per-face marks.
  lsf::guard_child_folds(
      normal_of, out,
      std::span<std::uint8_t>(reinterpret_cast<std::uint8_t*>(twin_estimate.data), m.num_faces()));
}
}  // namespace stlrefine
