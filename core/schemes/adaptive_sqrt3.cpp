// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 driver (adaptive_sqrt3.h): the criteria, refining a triangle with its
// closure (spec 3.6), the loop over the levels and the count at the cap.
#include "core/schemes/adaptive_sqrt3.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/geometry/point_triangle.h"
#include "core/parallel.h"
#include "core/refine.h"
#include "core/schemes/adaptive_sqrt3_hierarchy.h"

namespace stlrefine {

using namespace adaptive_sqrt3_detail;

bool AdaptiveSqrt3::Hierarchy::wants_refinement(FaceId t) {
  const int l = level(t);
  const std::array<VertexId, 3> v = tris_[t].v;
  const Vec3 a = position(v[0], l), b = position(v[1], l), c = position(v[2], l);
  if (criteria_.angle_deg > 0) {
    const Vec3 n = triangle_normal(a, b, c);
    const double cos_limit = std::cos(criteria_.angle_deg * std::numbers::pi / 180.0);
    for (std::uint8_t k = 0; k < 3; ++k) {
      if (sharp(he(t, k))) continue;  // a crease is meant to be sharp
      const HalfedgeId tw = twin(he(t, k));
      if (!tw.valid()) continue;
      const std::array<VertexId, 3> w = tris_[Mesh::face(tw)].v;
      const Vec3 m = triangle_normal(position(w[0], l), position(w[1], l), position(w[2], l));
      if (turned_past(n, m, cos_limit)) return true;
    }
  }
  return criteria_.tol > 0 && deviation(t, criteria_.tol / kTail) > criteria_.tol / kTail;
}

void AdaptiveSqrt3::Hierarchy::cover(FaceId t, std::vector<FaceId>& out) {
  // The level l + 1 triangles over t: its children, and across every edge that is flipped
  // the child of the other side (the two make the flipped quad).
  for (std::uint8_t k = 0; k < 3; ++k) {
    const HalfedgeId h = he(t, k);
    out.push_back(child(h));
    if (makes_flip_child(h)) out.push_back(child(twin(h)));
  }
}

// Largest distance from `flat` of the piecewise-linear surface of level l + 2 over it, or
// a value above `limit` as soon as one is found. `fine` holds the level l + 1 triangles
// over `flat`; the level l + 2 triangles over those are clipped to the prism over `flat`
// and measured at the corners of what is left (the distance to a triangle is convex, so its
// largest over a polygon is at a corner). Across a sharp edge (bit k of `sharp`: edge k)
// there is no neighbour: the finer triangles never cross it, and what bulges beyond it (a
// crease or boundary curve bending in the plane) is this triangle's, so the prism is not cut
// there. With `folds`, a finer triangle over `flat` facing away from it counts as too far.
double AdaptiveSqrt3::Hierarchy::height_over(const std::array<Vec3, 3>& flat, std::uint8_t sharp,
                                             std::vector<FaceId> fine, int l, double limit,
                                             bool folds) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const Vec3 n = cross(flat[1] - flat[0], flat[2] - flat[0]);
  const double n2 = dot(n, n);
  if (!(n2 > 0)) return kInfinity;  // degenerate: refine it
  const double inv = 1.0 / std::sqrt(n2);
  std::vector<FaceId> finer;
  for (FaceId c : fine) cover(c, finer);
  std::sort(finer.begin(), finer.end());
  finer.erase(std::unique(finer.begin(), finer.end()), finer.end());
  std::array<Vec3, 3> wall;  // inward normals of the prism's sides
  for (int k = 0; k < 3; ++k) wall[k] = cross(n, flat[(k + 1) % 3] - flat[k]);
  auto distance_to_flat = [&](const Vec3& p, bool inside) {
    return inside ? std::abs(dot(p - flat[0], n)) * inv
                  : point_triangle_distance(p, flat[0], flat[1], flat[2]);
  };
  double worst = 0;
  for (FaceId f : finer) {
    const std::array<VertexId, 3> v = tris_[f].v;
    const std::array<Vec3, 3> p{position(v[0], l + 2), position(v[1], l + 2),
                                position(v[2], l + 2)};
    // Side of every wall for every corner; the common case is a triangle inside the prism.
    std::array<std::array<double, 3>, 3> side{};
    bool cut = false, beyond = false;
    for (int k = 0; k < 3; ++k) {
      int out = 0;
      for (int i = 0; i < 3; ++i) {
        side[i][k] = dot(p[i] - flat[k], wall[k]);
        out += side[i][k] < 0;
      }
      if ((sharp >> k) & 1) continue;
      cut |= out > 0;
      beyond |= out == 3;
    }
    if (beyond) continue;  // wholly outside the prism
    if (!cut) {
      for (int i = 0; i < 3; ++i) {
        bool in = true;
        for (int k = 0; k < 3; ++k) in = in && side[i][k] >= 0;
        worst = std::max(worst, distance_to_flat(p[i], in));
      }
    } else {  // Sutherland-Hodgman against the non-sharp sides
      std::array<Vec3, 9> poly{p[0], p[1], p[2]}, clipped;
      std::size_t count = 3;
      for (int k = 0; k < 3 && count > 0; ++k) {
        if ((sharp >> k) & 1) continue;
        std::size_t m = 0;
        for (std::size_t i = 0; i < count; ++i) {
          const Vec3& a = poly[i];
          const Vec3& b = poly[(i + 1) % count];
          const double da = dot(a - flat[k], wall[k]), db = dot(b - flat[k], wall[k]);
          if (da >= 0) clipped[m++] = a;
          if ((da >= 0) != (db >= 0)) clipped[m++] = a + (da / (da - db)) * (b - a);
        }
        poly = clipped;
        count = m;
      }
      if (count == 0) continue;
      // Inside every side that was cut; without sharp sides, inside the prism.
      for (std::size_t i = 0; i < count; ++i)
        worst = std::max(worst, distance_to_flat(poly[i], sharp == 0));
    }
    if (folds && dot(cross(p[1] - p[0], p[2] - p[0]), n) <= 0) return kInfinity;
    if (worst > limit) return worst;
  }
  return worst;
}

double AdaptiveSqrt3::Hierarchy::deviation(FaceId t, double limit) {
  // How far the surface of two levels finer lies from t. Two levels, because one adds only
  // the face point, which sees no curvature along t's edges; after two every edge is
  // trisected. The finer *surface*, not only its new points: on irregular meshes the new
  // points of two steps can all lie away from t's edges, while the limit surface is often
  // farthest from t at the middle of an edge (measured on bunny_low: the points within tol,
  // the uniform level at the cap 1.65 tol away there; see bench/RESULTS.md "## sqrt3").
  const int l = level(t);
  const std::array<VertexId, 3> v = tris_[t].v;
  std::vector<FaceId> fine;
  cover(t, fine);
  return height_over({position(v[0], l), position(v[1], l), position(v[2], l)}, tris_[t].sharp,
                     std::move(fine), l, limit, false);
}

double AdaptiveSqrt3::Hierarchy::piece_deviation(HalfedgeId h, double limit) {
  // The piece (from, to, apex) of a refined triangle whose edge h is not flipped yet, because
  // the triangle across is not refined. It lies over the flipped quad of h. Its sharp edges,
  // as result() marks them: in a trisecting level the two next to the cut sharp edge s are
  // thirds of it. Where a finer triangle over it folds over (the apex can lie outside the
  // quad on thin triangles: OpenSCAD's polar fans), points of the finer surface can lie
  // outside the prism of every output face; measured 1.01 tol on sphere_fn16.
  const int l = level(Mesh::face(h));
  const HalfedgeId s = trisects(l) ? sharp_of(Mesh::face(h)) : HalfedgeId();
  std::uint8_t sharp_bits = 0;
  if (s.valid() && h == Mesh::prev(s)) sharp_bits |= 2;
  if (s.valid() && h == Mesh::next(s)) sharp_bits |= 4;
  std::vector<FaceId> fine{child(h), child(twin(h))};
  return height_over({position(from(h), l), position(to(h), l), position(apex(h), l + 1)},
                     sharp_bits, std::move(fine), l, limit, true);
}

bool AdaptiveSqrt3::Hierarchy::refine_across_pieces_over_tolerance() {
  // A piece is an output face too: where one is too far from the surface, refine the
  // triangle across, which flips the edge and replaces the piece by finer triangles. A
  // piece, once measured, keeps its measure: the triangle across can only become refined.
  std::vector<FaceId> across;
  auto add = [&](FaceId t) {
    if (across.size() == across.capacity()) {  // reserved before it doubles
      const std::size_t capacity = std::max<std::size_t>(1024, 2 * across.capacity());
      need(held_bytes() + capacity * sizeof(FaceId));
      across.reserve(capacity);
      transient_bytes_ = capacity * sizeof(FaceId);
    }
    across.push_back(t);
  };
  const auto count = static_cast<std::uint32_t>(tris_.size());
  for (std::uint32_t i = 0; i < count; ++i) {
    const FaceId t(i);
    if (!refined(t) || flag(t, kPiecesChecked)) continue;
    tris_[t].flags |= kPiecesChecked;
    for (std::uint8_t k = 0; k < 3; ++k) {
      const HalfedgeId h = he(t, k);
      if (!makes_flip_child(h)) continue;
      const HalfedgeId tw = twin(h);
      if (refined(Mesh::face(tw))) continue;
      throw_if_cancelled();
      const double limit = criteria_.tol / kTail;
      if (piece_deviation(h, limit) > limit) add(Mesh::face(tw));
    }
  }
  for (FaceId t : across) {
    if (refined(t)) continue;
    const std::size_t before = refined_count_;
    refine(t);
    ++stats_.refined_by_criterion;
    stats_.refined_by_closure += refined_count_ - before - 1;
  }
  transient_bytes_ = 0;
  return !across.empty();
}

void AdaptiveSqrt3::Hierarchy::refine(FaceId t) {
  if (refined(t)) return;
  ensure_exists(t);
  // Spec 3.6 step 1: every level-l triangle around t's corners exists (its stencil is in
  // the mesh). Either way every edge neighbour exists, so the result conforms.
  std::vector<FaceId> around;
  for (std::uint8_t k = 0; k < 3; ++k) {
    if (criteria_.closure == Sqrt3Closure::Stencil) {
      gather_fan(he(t, k), around);
    } else if (const HalfedgeId tw = twin(he(t, k)); tw.valid()) {
      around.push_back(Mesh::face(tw));
    }
  }
  for (FaceId u : around) ensure_exists(u);
  if (refined(t)) throw internal("a triangle was refined while its neighbourhood was made");

  // One split adds two faces; flips change no count.
  const std::uint64_t faces = input_faces_ + 2 * (refined_count_ + 1);
  if (faces > max_faces_)
    throw Error(
        ErrorCode::BudgetExceeded, "face_budget",
        "adaptive refinement would make more than max_faces = " + std::to_string(max_faces_) +
            " faces (stopped at " + std::to_string(faces - 2) + ")")
        .with_field("max_faces");
  throw_if_cancelled();
  tris_[t].flags |= kRefined;
  ++refined_count_;

  // The triangles that exist now: children kept whole, and both flip children of every old
  // edge whose other side was refined before.
  for (std::uint8_t k = 0; k < 3; ++k) {
    const HalfedgeId h = he(t, k);
    if (!makes_flip_child(h)) {
      enqueue(child(h));
      continue;
    }
    const HalfedgeId tw = twin(h);
    if (!refined(Mesh::face(tw))) continue;
    enqueue(child(h));
    enqueue(child(tw));
  }
  // A sharp edge is trisected on both of its sides at once (no T-junction).
  if (trisects(level(t))) {
    const HalfedgeId s = sharp_of(t);
    const HalfedgeId across = s.valid() ? twin(s) : HalfedgeId();
    if (across.valid()) refine(Mesh::face(across));
  }
}

void AdaptiveSqrt3::Hierarchy::run(std::uint64_t max_faces, const std::atomic<bool>* cancel,
                                   const std::function<void(int)>& level_started) {
  max_faces_ = max_faces;
  cancel_ = cancel;
  scope_cancel_ = detail::current_cancel_flag;
  if (input_faces_ > max_faces)
    throw Error(ErrorCode::BudgetExceeded, "face_budget",
                "the input has more than max_faces = " + std::to_string(max_faces) + " faces")
        .with_field("max_faces");
  for (std::uint32_t t = 0; t < input_faces_; ++t) enqueue(FaceId(t));
  int announced = -1;
  for (;;) {
    int l = 0;
    while (l < static_cast<int>(queue_.size()) && queue_[l].empty()) ++l;
    if (l == static_cast<int>(queue_.size())) {
      if (criteria_.tol > 0 && refine_across_pieces_over_tolerance()) continue;
      break;
    }
    if (l > announced) {
      announced = l;
      if (level_started) level_started(l);
    }
    const FaceId t = queue_[l].front();
    queue_[l].pop_front();
    throw_if_cancelled();
    if (refined(t) || !wants_refinement(t)) continue;
    const std::size_t before = refined_count_;
    refine(t);
    ++stats_.refined_by_criterion;
    stats_.refined_by_closure += refined_count_ - before - 1;
  }
  // At the cap some faces may still ask for more: say how many. Measuring a face at the
  // cap makes the two levels below it, which nothing else needs: up to 9 triangles per
  // face, several times the whole hierarchy. They are dropped in batches (an eighth of the
  // hierarchy) and remade where the next batch needs them again. Every face at the cap
  // exists already (refine() makes the children it brings into existence).
  const Checkpoint mark = checkpoint();
  const std::uint64_t base = held_bytes();
  const std::uint64_t batch = std::max<std::uint64_t>(base / 8, std::uint64_t{16} << 20);
  for (std::uint32_t i = 0; i < mark.tris; ++i) {
    const FaceId t(i);
    if (level(t) != criteria_.max_level || refined(t) || !exists(t)) continue;
    throw_if_cancelled();
    if (wants_refinement(t)) {
      ++stats_.over_criterion_at_cap;
      // How far, and where: the report says where the cap stopped it.
      const double d =
          criteria_.tol > 0 ? deviation(t, std::numeric_limits<double>::infinity()) : 0.0;
      if (std::isfinite(d) && d > stats_.max_over_tolerance) {
        const auto& v = tris_[t].v;
        const int l = level(t);
        stats_.max_over_tolerance = d;
        stats_.worst_over_tolerance_at =
            (position(v[0], l) + position(v[1], l) + position(v[2], l)) * (1.0 / 3.0);
      }
    }
    if (held_bytes() > base + batch) rollback(mark);
  }
  rollback(mark);
}

void AdaptiveSqrt3::Hierarchy::rollback(const Checkpoint& c) {
  // Everything made after the checkpoint goes; so do the links older triangles and
  // vertices got to it (children, neighbours, face and trisection points, homes). They are
  // all caches of what the uniform hierarchy is: made again, they come out the same.
  const auto tris = static_cast<std::uint32_t>(c.tris);
  const auto verts = static_cast<std::uint32_t>(c.verts);
  auto dropped_face = [&](FaceId f) { return f.valid() && f.idx >= tris; };
  auto dropped_halfedge = [&](HalfedgeId h) {
    return h.valid() && h != kUnknownTwin && Mesh::face(h).idx >= tris;
  };
  auto dropped_vertex = [&](VertexId v) { return v.valid() && v.idx >= verts; };
  for (std::uint32_t t = 0; t < tris; ++t) {
    Tri& x = tris_[t];
    for (int k = 0; k < 3; ++k) {
      if (dropped_face(x.child[k])) x.child[k] = FaceId();
      if (dropped_halfedge(x.twin[k])) x.twin[k] = kUnknownTwin;
    }
    if (dropped_vertex(x.point)) x.point = VertexId();
    if (dropped_vertex(x.point2)) x.point2 = VertexId();
  }
  for (std::uint32_t v = 0; v < verts; ++v)
    if (dropped_halfedge(verts_[v].home)) verts_[v].home = HalfedgeId();
  tris_.truncate(c.tris);
  verts_.truncate(c.verts);
  alpha_.truncate(c.verts);
  guard_point_.truncate(c.verts);
  corner_normal_.truncate(c.tris);
  pool_.truncate(c.slots);
  known_.truncate(c.slots);
}

}  // namespace stlrefine
