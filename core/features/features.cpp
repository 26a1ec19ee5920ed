// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/features/features.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <span>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"

namespace stlrefine {

void FeatureParams::validate() const {
  require_in_range("crease_angle", crease_angle_deg, 0.0, 180.0);
  if (crease_mode != CreaseMode::Auto && crease_mode != CreaseMode::Angle)
    throw Error(ErrorCode::InvalidParameter, "crease_angle", "unknown crease mode");
}

const char* to_string(CreaseMode mode) {
  return mode == CreaseMode::Angle ? "angle" : "auto";
}

const char* to_string(VertexKind kind) {
  switch (kind) {
    case VertexKind::Smooth:
      return "smooth";
    case VertexKind::Dart:
      return "dart";
    case VertexKind::Crease:
      return "crease";
    case VertexKind::Corner:
      return "corner";
  }
  return "smooth";
}

Features::Features(const Mesh& mesh, BigVector<std::uint8_t> sharp_edge)
    : sharp_edge_(std::move(sharp_edge)) {
  if (sharp_edge_.size() != mesh.num_edges())
    throw Error(ErrorCode::Internal, "feature_size", "sharp flags do not match the edges");
  for (std::size_t e = 0; e < sharp_edge_.size(); ++e) {
    if (mesh.is_boundary(EdgeId(e))) sharp_edge_[e] = 1;
    num_sharp_ += sharp_edge_[e];
  }
  const std::size_t nv = mesh.num_vertices();
  kind_.resize(nv);
  curve_neighbours_.resize(nv);
  parallel_for_each_index(nv, [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    int sharp = 0;
    std::array<VertexId, 2> ends{};
    auto note = [&](HalfedgeId h, VertexId far) {
      if (!is_sharp(mesh.edge(h))) return;
      if (sharp < 2) ends[sharp] = far;
      ++sharp;
    };
    HalfedgeId last;
    for_each_outgoing(mesh, v, [&](HalfedgeId h) {
      note(h, mesh.to(h));
      last = h;
    });
    // The incoming boundary half-edge closing an open fan is an edge of v too.
    if (last.valid() && mesh.is_boundary(v)) note(Mesh::prev(last), mesh.from(Mesh::prev(last)));
    kind_[i] = sharp == 0   ? VertexKind::Smooth
               : sharp == 1 ? VertexKind::Dart
               : sharp == 2 ? VertexKind::Crease
                            : VertexKind::Corner;
    curve_neighbours_[i] = sharp == 2 ? ends : std::array<VertexId, 2>{};
  });
}

Features Features::from_parts(BigVector<std::uint8_t> sharp_edge, BigVector<VertexKind> kind,
                              BigVector<std::array<VertexId, 2>> curve_neighbours) {
  Features f;
  f.sharp_edge_ = std::move(sharp_edge);
  f.kind_ = std::move(kind);
  f.curve_neighbours_ = std::move(curve_neighbours);
  f.num_sharp_ = static_cast<std::size_t>(
      std::count_if(f.sharp_edge_.begin(), f.sharp_edge_.end(), [](std::uint8_t s) { return s; }));
  return f;
}

VertexId Features::curve_beyond(VertexId x, VertexId other) const {
  if (kind(x) != VertexKind::Crease) return VertexId();
  const auto& n = curve_neighbours_[x.idx];
  // Both sharp edges of x may end at `other` (a two-edge loop): then there is no distinct
  // vertex beyond and the end condition applies.
  if (n[0] == other) return n[1] == other ? VertexId() : n[1];
  if (n[1] == other) return n[0];
  return VertexId();  // (x, other) is not one of x's sharp edges
}

std::size_t Features::count(VertexKind k) const {
  return static_cast<std::size_t>(std::count(kind_.begin(), kind_.end(), k));
}

std::optional<SectionTangent> section_tangent(std::span<const SectionPoint> points) {
  if (points.empty()) return std::nullopt;
  // The circle through the origin with centre c: d^2 + h^2 = 2 (c_d d + c_h h), each
  // equation divided by d^2 + h^2 so near and far points count alike.
  double m00 = 0, m01 = 0, m11 = 0, r0 = 0, r1 = 0;
  double lo = std::numbers::pi, hi = -std::numbers::pi, sum = 0, near = HUGE_VAL, far = 0;
  for (const SectionPoint& p : points) {
    const double rr = p.d * p.d + p.h * p.h;
    const double x = 2 * p.d / rr, y = 2 * p.h / rr;
    m00 += x * x;
    m01 += x * y;
    m11 += y * y;
    r0 += x;
    r1 += y;
    const double dir = std::atan2(p.h, p.d);
    lo = std::min(lo, dir);
    hi = std::max(hi, dir);
    sum += dir;
    near = std::min(near, std::sqrt(rr));
    far = std::max(far, std::sqrt(rr));
  }
  const double det = m00 * m11 - m01 * m01;
  if (hi - lo < kSectionSpreadDeg * std::numbers::pi / 180.0 ||
      far - near < kSectionDistanceSpread * far || !(det > 1e-12 * m00 * m11))
    return SectionTangent{sum / static_cast<double>(points.size()), HUGE_VAL, false};
  const double cd = (m11 * r0 - m01 * r1) / det, ch = (m00 * r1 - m01 * r0) / det;
  // The tangent is perpendicular to the centre, pointing to the points' side (d > 0).
  return SectionTangent{ch >= 0 ? std::atan2(-cd, ch) : std::atan2(cd, -ch), std::hypot(cd, ch),
                        true};
}

double dihedral_angle_deg(const Mesh& mesh, EdgeId e) {
  const HalfedgeId h = mesh.halfedge(e);
  const HalfedgeId t = mesh.twin(h);
  if (!t.valid()) return 0.0;
  const Vec3 n1 = normalized(mesh.face_normal(Mesh::face(h)));
  const Vec3 n2 = normalized(mesh.face_normal(Mesh::face(t)));
  if (n1 == Vec3{} || n2 == Vec3{}) return 0.0;  // no direction on a zero-area face
  // atan2 of |n1 x n2| and n1.n2 is accurate for small and large angles alike.
  return std::atan2(norm(cross(n1, n2)), dot(n1, n2)) * 180.0 / std::numbers::pi;
}

namespace {

Features detect_by_angle(const Mesh& mesh, const FeatureParams& params) {
  BigVector<std::uint8_t> sharp(mesh.num_edges());
  // angle > theta  <=>  n1.n2 < cos(theta) |n1| |n2|: no normalisation, no atan2.
  const double cos_limit = std::cos(params.crease_angle_deg * std::numbers::pi / 180.0);
  const bool disabled = params.crease_angle_deg >= 180.0;
  // Each face's normal once (an inner face has three edges, so the per-edge test would
  // compute it three times); the same values, so the same flags.
  BigVector<Vec3> normal(disabled ? 0 : mesh.num_faces());
  if (!disabled)
    parallel_for_each_index(mesh.num_faces(), [&](std::size_t f) {
      normal[f] = mesh.face_normal(FaceId(static_cast<std::uint32_t>(f)));
    });
  parallel_for_each_index(mesh.num_edges(), [&](std::size_t e) {
    const HalfedgeId h = mesh.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    const HalfedgeId t = mesh.twin(h);
    sharp[e] = 0;
    if (!t.valid() || disabled) return;
    const Vec3& n1 = normal[Mesh::face(h).idx];
    const Vec3& n2 = normal[Mesh::face(t).idx];
    sharp[e] = turned_past(n1, n2, cos_limit);
  });
  return Features(mesh, std::move(sharp));
}

// Auto mode (see detect_features in the header).
Features detect_auto(const Mesh& mesh) {
  const std::size_t nf = mesh.num_faces(), ne = mesh.num_edges();
  constexpr double kDeg = std::numbers::pi / 180.0;
  // Per face: the unit normal.
  BigVector<Vec3> normal(nf);
  parallel_for_each_index(nf, [&](std::size_t f) {
    normal[f] = normalized(mesh.face_normal(FaceId(static_cast<std::uint32_t>(f))));
  });
  // Per edge: the dihedral (radians; 0 at boundaries and next to zero-area faces).
  BigVector<double> angle(ne);
  BigVector<std::uint8_t> sharp(ne);
  parallel_for_each_index(ne, [&](std::size_t e) {
    const HalfedgeId h = mesh.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    const HalfedgeId t = mesh.twin(h);
    angle[e] = 0;
    sharp[e] = 0;
    if (!t.valid()) return;
    const Vec3& n1 = normal[Mesh::face(h).idx];
    const Vec3& n2 = normal[Mesh::face(t).idx];
    if (n1 == Vec3{} || n2 == Vec3{}) return;
    angle[e] = std::atan2(norm(cross(n1, n2)), dot(n1, n2));
  });
  // Why an edge is sharp: its dihedral alone, a planar face on one side, standing out.
  constexpr std::uint8_t kAlways = 1, kPlanarSide = 2, kStandsOut = 3, kBetweenWalls = 4;
  const double always = kAutoCreaseAlwaysDeg * kDeg;
  const double flat = kAutoCreaseFlatDeg * kDeg;
  // Planar regions: faces joined across edges flatter than kAutoCreaseFlatDeg, with their
  // areas. A plane is told from a chord of a curved surface (the flat polygon capping a
  // coarse sphere, which meets its band at the band's full segment angle) by its size.
  std::vector<std::uint32_t> region(nf);
  for (std::uint32_t f = 0; f < nf; ++f) region[f] = f;
  auto find = [&](std::uint32_t f) {
    while (region[f] != f) f = region[f] = region[region[f]];
    return f;
  };
  for (std::uint32_t e = 0; e < ne; ++e) {
    const HalfedgeId h = mesh.halfedge(EdgeId(e));
    const HalfedgeId t = mesh.twin(h);
    if (!t.valid() || angle[e] >= flat) continue;
    if (normal[Mesh::face(h).idx] == Vec3{} || normal[Mesh::face(t).idx] == Vec3{}) continue;
    const std::uint32_t a = find(Mesh::face(h).idx), b = find(Mesh::face(t).idx);
    if (a != b) region[std::max(a, b)] = std::min(a, b);
  }
  std::vector<double> region_area(nf, 0.0);
  for (std::uint32_t f = 0; f < nf; ++f)
    region_area[find(f)] += 0.5 * norm(mesh.face_normal(FaceId(f)));
  for (std::uint32_t f = 0; f < nf; ++f) region[f] = find(f);
  // The face of half-edge h, seen from its edge: the largest dihedral of its two other edges
  // and of the edges beyond them that do not touch h's edge (across a split quad, the edge
  // parallel to h's: a coarse smooth surface bends there as much as at h's edge, a crease
  // does not), leaving out the always-sharp ones; and whether it lies in a plane with a
  // neighbour and bends nowhere else (a face of a planar region).
  struct Side {
    double bend = 0;
    double own = 0;  // the largest dihedral of the face's two other edges alone
    bool planar = false;
  };
  const double planes = kAutoCreasePlanesDeg * kDeg;
  auto side = [&](HalfedgeId h) {
    Side s;
    bool coplanar_neighbour = false;
    double own = 0;
    const VertexId a = mesh.from(h), b = mesh.to(h);
    for (const HalfedgeId g : {Mesh::next(h), Mesh::prev(h)}) {
      const EdgeId eg = mesh.edge(g);
      const HalfedgeId across = mesh.twin(g);
      if (!across.valid() || angle[eg.idx] >= always) continue;
      coplanar_neighbour |= angle[eg.idx] < flat;
      // A fan triangle of a cap touching two rim edges is still planar.
      if (angle[eg.idx] < planes) own = std::max(own, angle[eg.idx]);
      for (const HalfedgeId k : {Mesh::next(across), Mesh::prev(across)}) {
        const EdgeId ek = mesh.edge(k);
        if (mesh.from(k) == a || mesh.from(k) == b || mesh.to(k) == a || mesh.to(k) == b) continue;
        if (angle[ek.idx] < always) s.bend = std::max(s.bend, angle[ek.idx]);
      }
    }
    s.bend = std::max(s.bend, own);
    s.own = own;
    s.planar = coplanar_neighbour && own < flat;
    return s;
  };
  // A planar side is a plane when its region is large against the other face's height
  // over the edge (kAutoCreasePlaneSize of them squared).
  auto is_plane = [&](HalfedgeId planar, HalfedgeId other) {
    const double len = norm(mesh.position(mesh.to(planar)) - mesh.position(mesh.from(planar)));
    if (len == 0) return false;
    const double height = norm(mesh.face_normal(Mesh::face(other))) / len;
    const double size = kAutoCreasePlaneSize * height;
    // Both its area and its width across the edge (area over the edge's length: a strip of
    // a zipped cylinder side, long along the edge, and one facet of an arc are chords too;
    // they are 2-4.5 times the next facet's height) count.
    const double area = region_area[region[Mesh::face(planar).idx]];
    return area >= size * size && area >= kAutoCreasePlaneWidth * height * len;
  };
  // Smoothness across an edge (the planar-side rules' last test). The vertices beside edge
  // (a, b) on one side: those of the faces within `rings` steps of face `start`, not
  // crossing the edge, an always-sharp edge or into region `blocked`, in the section across
  // the edge: d along `out`, h along `down`. Left out: d <= 0 or > `reach`,
  // and vertices beyond the edge's ends by more than kBeyond d (a fanned corner's centre
  // is not on the fillet's section).
  constexpr double kBeyond = 0.1;
  auto beside = [&](HalfedgeId edge, std::uint32_t start, std::uint32_t blocked, int rings,
                    const Vec3& down, const Vec3& out, double reach) {
    const VertexId va = mesh.from(edge), vb = mesh.to(edge);
    const Vec3 pa = mesh.position(va);
    const double len = norm(mesh.position(vb) - pa);
    const Vec3 along = (1.0 / len) * (mesh.position(vb) - pa);
    std::vector<std::uint32_t> faces{start};
    for (std::size_t begin = 0; rings-- > 0;) {
      const std::size_t end = faces.size();
      for (std::size_t i = begin; i < end; ++i)
        for (int k = 0; k < 3; ++k) {
          const HalfedgeId g = Mesh::halfedge(FaceId(faces[i]), k);
          const HalfedgeId across = mesh.twin(g);
          if (!across.valid() || mesh.edge(g) == mesh.edge(edge) ||
              angle[mesh.edge(g).idx] >= always)
            continue;
          const std::uint32_t f = Mesh::face(across).idx;
          if (region[f] != blocked && std::find(faces.begin(), faces.end(), f) == faces.end())
            faces.push_back(f);
        }
      begin = end;
    }
    std::vector<VertexId> seen;
    std::vector<SectionPoint> points;
    for (const std::uint32_t f : faces)
      for (int k = 0; k < 3; ++k) {
        const VertexId v = mesh.from(Mesh::halfedge(FaceId(f), k));
        if (v == va || v == vb || std::find(seen.begin(), seen.end(), v) != seen.end()) continue;
        seen.push_back(v);
        const Vec3 q = mesh.position(v) - pa;
        const double d = dot(q, out), s = dot(q, along);
        if (d > 0 && d <= reach && std::max({0.0, -s, s - len}) <= kBeyond * d)
          points.push_back({d, dot(q, down)});
      }
    return points;
  };
  // planar's face and other's meet at the edge; true when the surface is smooth across it.
  // The other side's points from its face and the faces next to it (one more ring when they
  // do not fix a circle: two points on a coarse fillet's section at one distance); the
  // planar side's from three rings of faces (through a one-facet "plane" to the surface
  // beyond it), but no farther than the other side's radius and kReach times its farthest
  // point: the far side of a real plane does not belong to this section.
  constexpr double kReach = 8.0;
  const double excess = kAutoCreaseExcessDeg * kDeg;
  auto smooth_across = [&](HalfedgeId planar, HalfedgeId other) {
    const Vec3& n = normal[Mesh::face(planar).idx];
    const Vec3 edge_dir = mesh.position(mesh.to(other)) - mesh.position(mesh.from(other));
    Vec3 out = normalized(cross(n, edge_dir));
    const Vec3 apex = mesh.position(mesh.to(Mesh::next(other))) - mesh.position(mesh.from(other));
    if (dot(apex, out) < 0) out = -1.0 * out;
    // Heights are taken from the plane towards the side the other face bends to.
    const Vec3 down = dot(apex, n) > 0 ? n : -1.0 * n;
    const std::uint32_t other_face = Mesh::face(other).idx, planar_face = Mesh::face(planar).idx;
    std::vector<SectionPoint> curved;
    std::optional<SectionTangent> t_other;
    for (int rings = 1; rings <= 2 && !(t_other && t_other->fitted); ++rings) {
      curved = beside(other, other_face, region[planar_face], rings, down, out, HUGE_VAL);
      t_other = section_tangent(curved);
    }
    if (!t_other) return false;  // nothing to compare: the dihedral rules decide
    double reach = 0;
    for (const SectionPoint& p : curved) reach = std::max(reach, kReach * p.d);
    reach = std::min(reach, t_other->radius);
    const std::vector<SectionPoint> flat_side =
        beside(other, planar_face, region[other_face], 3, down, -1.0 * out, reach);
    const double t_planar = section_tangent(flat_side).value_or(SectionTangent{}).elevation;
    // Straight across when the two tangents are opposite: elevations that cancel.
    return std::abs(t_other->elevation + t_planar) < excess;
  };
  parallel_for_each_index(ne, [&](std::size_t e) {
    const HalfedgeId h = mesh.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    const HalfedgeId t = mesh.twin(h);
    if (!t.valid()) return;
    const double a = angle[e];
    const Side s1 = side(h), s2 = side(t);
    if (a >= always) {
      sharp[e] = kAlways;
    } else if (s1.planar && s2.planar && a >= planes) {
      // Two planar regions at a steep angle: the walls of an embossed letter, a chamfer. A
      // coarse prism's facets meet at less (a 24-gon's at 15 degrees).
      sharp[e] = kAlways;
    } else if (s1.planar && s2.planar && is_plane(h, t) != is_plane(t, h)) {
      // A plane meeting a planar strip (a fillet's chord between two rulings sampled
      // alike): the strip bends at its far (parallel) edge; as below against that.
      const bool h_plane = is_plane(h, t);
      const Side& strip = h_plane ? s2 : s1;
      sharp[e] =
          a >= 0.5 * strip.bend + excess && !(h_plane ? smooth_across(h, t) : smooth_across(t, h))
              ? kPlanarSide
              : 0;
    } else if (s1.planar != s2.planar &&
               (a >= planes || (s1.planar ? is_plane(h, t) : is_plane(t, h)))) {
      // A plane meeting a curved region: tangent-continuous, the dihedral is about half the
      // curved side's own bend (its face's other edges: the chords of a fillet); more than
      // that by `excess` is a crease.
      sharp[e] = a >= 0.5 * std::max(s1.own, s2.own) + excess &&
                         (a >= planes || !(s1.planar ? smooth_across(h, t) : smooth_across(t, h)))
                     ? kPlanarSide
                     : 0;
    } else {
      const double around = std::max(s1.bend, s2.bend);
      const bool stands_out =
          a >= around + kAutoCreaseStandOutDeg * kDeg && a >= kAutoCreaseRatio * around;
      // Two planar faces that bend nowhere but here (every other edge around them flat or
      // steep): two walls of an extruded polygon, not chords of a curve (a coarse prism's
      // facets bend alike at their far edges). Such an edge runs between the steep edges
      // capping the walls, so it is kept without continuing a chain (the xyz cube's letter
      // walls meet at 32 degrees).
      const bool walls = s1.planar && s2.planar && around < flat;
      sharp[e] = !stands_out ? 0 : walls ? kBetweenWalls : kStandsOut;
    }
  });
  // A crease is a chain: an edge found by standing out alone needs, at both of its ends, a
  // sharp edge that continues it (turns by less than kAutoCreaseTurnDeg).
  const double cos_turn = std::cos(kAutoCreaseTurnDeg * kDeg);
  auto continued_at = [&](VertexId v, VertexId other, EdgeId self) {
    const Vec3 d = normalized(mesh.position(v) - mesh.position(other));
    bool found = false;
    auto look = [&](HalfedgeId g, VertexId far) {
      const EdgeId eg = mesh.edge(g);
      if (found || eg == self || !sharp[eg.idx]) return;
      found = dot(d, normalized(mesh.position(far) - mesh.position(v))) >= cos_turn;
    };
    HalfedgeId last;
    for_each_outgoing(mesh, v, [&](HalfedgeId g) {
      look(g, mesh.to(g));
      last = g;
    });
    if (last.valid() && mesh.is_boundary(v)) look(Mesh::prev(last), mesh.from(Mesh::prev(last)));
    return found;
  };
  BigVector<std::uint8_t> keep(ne);
  parallel_for_each_index(ne, [&](std::size_t e) {
    keep[e] = sharp[e];
    if (sharp[e] != kStandsOut) return;
    const EdgeId self(static_cast<std::uint32_t>(e));
    const HalfedgeId h = mesh.halfedge(self);
    keep[e] = continued_at(mesh.from(h), mesh.to(h), self) &&
              continued_at(mesh.to(h), mesh.from(h), self);
  });
  // Gaps in a chain: an edge that continues sharp edges at both of its ends, bends at least
  // kAutoCreaseGapRatio as much as they do and stands out (kAutoCreaseRatio) against its
  // faces' other edges is part of the same crease (a fillet's tangent line whose dihedral
  // wavers around the planar-side threshold would otherwise alternate sharp and smooth,
  // leaving darts). Repeated while it adds edges (a few passes: each fills gaps one edge
  // long from both sides).
  auto continued_by = [&](VertexId v, VertexId other, EdgeId self) {
    // The smallest dihedral of the sharp edges continuing (other, v) beyond v; 0 for none.
    const Vec3 d = normalized(mesh.position(v) - mesh.position(other));
    double best = 0;
    auto look = [&](HalfedgeId g, VertexId far) {
      const EdgeId eg = mesh.edge(g);
      if (eg == self || !keep[eg.idx] || mesh.is_boundary(eg)) return;
      if (dot(d, normalized(mesh.position(far) - mesh.position(v))) < cos_turn) return;
      best = best == 0 ? angle[eg.idx] : std::min(best, angle[eg.idx]);
    };
    HalfedgeId last;
    for_each_outgoing(mesh, v, [&](HalfedgeId g) {
      look(g, mesh.to(g));
      last = g;
    });
    if (last.valid() && mesh.is_boundary(v)) look(Mesh::prev(last), mesh.from(Mesh::prev(last)));
    return best;
  };
  for (int pass = 0; pass < 8; ++pass) {
    std::vector<std::uint32_t> add;
    for (std::uint32_t e = 0; e < ne; ++e) {
      if (keep[e] || angle[e] == 0) continue;
      const EdgeId self(e);
      const HalfedgeId h = mesh.halfedge(self);
      const HalfedgeId t = mesh.twin(h);
      if (!t.valid()) continue;
      const double around = std::max(side(h).bend, side(t).bend);
      if (angle[e] < kAutoCreaseRatio * around) continue;
      const double at_from = continued_by(mesh.from(h), mesh.to(h), self);
      const double at_to = continued_by(mesh.to(h), mesh.from(h), self);
      if (at_from == 0 || at_to == 0) continue;
      if (angle[e] >= kAutoCreaseGapRatio * std::min(at_from, at_to)) add.push_back(e);
    }
    if (add.empty()) break;
    for (const std::uint32_t e : add) keep[e] = 1;
  }
  // A crease runs until it meets another feature: an edge found by any rule but its steep
  // dihedral that meets no other sharp (or boundary) edge at either end is dropped (on a
  // rounded box's zipped fillets a lone edge of a twisted strip can pass the planar-side
  // rule), and so is a steep one that does not stand out either (a fold of two slivers on
  // a coarse zipped torus, 65 degrees among 20-38 degree bends).
  auto lone_end = [&](VertexId v, EdgeId self) {
    bool other = false;
    HalfedgeId last;
    auto look = [&](HalfedgeId g) {
      const EdgeId eg = mesh.edge(g);
      other |= eg != self && (keep[eg.idx] || mesh.is_boundary(eg));
    };
    for_each_outgoing(mesh, v, [&](HalfedgeId g) {
      look(g);
      last = g;
    });
    if (last.valid() && mesh.is_boundary(v)) look(Mesh::prev(last));
    return !other;
  };
  {
    std::vector<std::uint32_t> lone;
    for (std::uint32_t e = 0; e < ne; ++e) {
      if (!keep[e]) continue;
      const HalfedgeId h = mesh.halfedge(EdgeId(e));
      // A steep edge stays unless it also bends no more than its faces do around it.
      if (sharp[e] == kAlways &&
          (!mesh.twin(h).valid() ||
           angle[e] >= kAutoCreaseRatio * std::max(side(h).bend, side(mesh.twin(h)).bend)))
        continue;
      if (lone_end(mesh.from(h), EdgeId(e)) && lone_end(mesh.to(h), EdgeId(e))) lone.push_back(e);
    }
    for (const std::uint32_t e : lone) keep[e] = 0;
  }
  // Flags are 0 or 1 from here on (Features counts them by adding).
  parallel_for_each_index(ne, [&](std::size_t e) { sharp[e] = keep[e] != 0; });
  return Features(mesh, std::move(sharp));
}

}  // namespace

Features detect_features(const Mesh& mesh, const FeatureParams& params) {
  params.validate();
  return params.crease_mode == CreaseMode::Angle ? detect_by_angle(mesh, params)
                                                 : detect_auto(mesh);
}

}  // namespace stlrefine
