// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf_rules.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_map>
#include <vector>

#include "core/geometry/hermite.h"
#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

// The least ratio of the chord beyond an endpoint to the edge's own chord for which the
// 1-D rule fits its quadratic (spec 5 gap 3); below it the endpoint's estimate is linear.
constexpr double kCurveSpacingRatio = 0.2;

// A sharp polyline through a corner continues along another of its sharp edges when that one
// turns from it by less than this (degrees): a rim crossed by a crease the angle found on a
// coarse wall (issue 17's zipped tube: an inner rim's chord of 3.8 mm left 0.33 mm off its
// circle when the corner ended the curve). A corner of a box (90 degrees) still ends it.
namespace {
constexpr double kCornerThroughDeg = 45.0;
// How far the vertex beyond a corner may lie from the circle through the corner and the next two
// curve vertices, per unit of its distance, for the curve to continue through the corner.
constexpr double kCurveThroughCornerTol = 1e-2;

// The distance of q from the circle through p0, p1 and p2 (from their line when they are nearly
// on one).
double circle_distance(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& q) {
  const Vec3 u = p1 - p0, x = p2 - p0, n = cross(u, x);
  const double n2 = dot(n, n);
  if (!(n2 > 1e-24 * dot(u, u) * dot(x, x))) {
    const Vec3 d = normalized(x), r = q - p0;
    return norm(r - dot(r, d) * d);
  }
  const Vec3 centre = p0 + (1.0 / (2.0 * n2)) * cross(dot(u, u) * x - dot(x, x) * u, n);
  const Vec3 r = q - centre, axis = (1.0 / std::sqrt(n2)) * n;
  const double off_plane = dot(r, axis);
  const Vec3 in_plane = r - off_plane * axis;
  return std::hypot(off_plane, norm(in_plane) - distance(p0, centre));
}

// The sharp neighbour of corner x that continues the curve from `next` through x (the one
// turning least), or invalid when each turns by kCornerThroughDeg or more.
VertexId corner_beyond(const Mesh& m, const Features& f, VertexId x, VertexId next) {
  const Vec3 px = m.position(x), forward = normalized(px - m.position(next));
  const double min_cos = std::cos(kCornerThroughDeg * std::numbers::pi / 180.0);
  VertexId best;
  double best_cos = min_cos;
  auto consider = [&](VertexId w) {
    if (w == next) return;
    const double c = dot(forward, normalized(m.position(w) - px));
    if (c > best_cos) best_cos = c, best = w;
  };
  for_each_outgoing(m, x, [&](HalfedgeId s) {
    if (f.is_sharp(m.edge(s))) consider(m.to(s));
    if (!m.twin(Mesh::prev(s)).valid()) consider(m.from(Mesh::prev(s)));  // boundary coming in
  });
  return best;
}
}  // namespace

Vec3 lsf_curve_point(const Mesh& m, const Features& f, HalfedgeId h) {
  const VertexId a = m.from(h), b = m.to(h);
  // Quadratic through (prev, x, next) at chord parameters (-d0, 0, d1), evaluated at d1/2;
  // false where the curve gives no neighbour beyond x (an end, a corner) or it is too near.
  auto endpoint_estimate = [&](VertexId x, VertexId next, Vec3& estimate) {
    const Vec3& px = m.position(x);
    const Vec3& pn = m.position(next);
    VertexId before = f.curve_beyond(x, next);
    if (!before.valid() && f.kind(x) == VertexKind::Corner) {
      before = corner_beyond(m, f, x, next);
      // Through a corner only along one smooth curve: the vertex beyond on the circle (or
      // line) through x, next and the curve vertex after next (a rim crossed by a false
      // crease). Where a flat side meets an arc at a shallow crease (issue 17's plate outline,
      // 6-12 degrees) the flat's far end is off the arc's circle by its length, and the
      // quadratic through it is the chord: the arc's chord midpoint, its sagitta off.
      // When next is a corner too, the vertex after it is the one its own curve continues
      // to; with none, three points say nothing of a curve and the corner ends it (a polygon's
      // outline, the xyz cube's letters: 0.2 mm bows on edges between two corners).
      VertexId after = f.curve_beyond(next, x);
      if (!after.valid() && f.kind(next) == VertexKind::Corner)
        after = corner_beyond(m, f, next, x);
      if (before.valid() &&
          !(after.valid() && circle_distance(px, pn, m.position(after), m.position(before)) <=
                                 kCurveThroughCornerTol * distance(px, m.position(before))))
        before = VertexId();
    }
    if (!before.valid()) return false;
    const Vec3& pb = m.position(before);
    const double d0 = distance(pb, px), d1 = distance(px, pn);
    // A neighbour beyond much nearer than the edge is long (an arc's last short chord before
    // a long straight one, issue 17's plate outline): its bend, extrapolated over the long
    // edge, would bow a straight edge by a large fraction of its length. Linear, as at an end.
    if (d0 <= 0 || d1 <= 0 || d0 < kCurveSpacingRatio * d1) {
      estimate = 0.5 * (px + pn);
      return true;
    }
    const double w_before = -d1 * d1 / (4.0 * d0 * (d0 + d1));
    const double w_x = (d0 + 0.5 * d1) / (2.0 * d0);
    const double w_next = (d0 + 0.5 * d1) / (2.0 * (d0 + d1));
    estimate = w_before * pb + w_x * px + w_next * pn;
    return true;
  };
  Vec3 ea, eb;
  const bool has_a = endpoint_estimate(a, b, ea), has_b = endpoint_estimate(b, a, eb);
  if (has_a && has_b) return 0.5 * (ea + eb);
  // At an end or a corner the other end's quadratic alone: it interpolates the edge's ends and
  // the curve vertex beyond, where the linear end estimate halves the arc's sagitta.
  if (has_a || has_b) return has_a ? ea : eb;
  return 0.5 * (m.position(a) + m.position(b));
}

namespace lsf {

// --- The edge-point guard (issue 17) --------------------------------------------------------
//
// The two endpoint fits are only as good as their samples: on CAD tessellations (fans,
// zipped strips, regions whose every vertex is a crease vertex, flat faces beside fillets) a
// one-sided or mixed sample extrapolates, by up to the edge's length. Each estimate is
// checked against what the surface's normals allow, and the edge point is built from the
// estimates that pass, in this order of preference:
//  1. the mean of the endpoint estimates that agree with the normals (both, or the better
//     conditioned one);
//  2. else the cubic Hermite midpoint of the edge from those normals (the chord midpoint when
//     the normals say the edge is straight: a planar region stays planar);
// and finally pulled back towards the chord while one of its child faces would turn more than
// 60 degrees from the normals.

// The unit tangent at crease vertex v of its crease curve: the derivative at v of the quadratic
// through its two sharp neighbours in chord-length parameters (second-order accurate on
// unevenly sampled rims); zero when v has not exactly two sharp neighbours apart from it.
Vec3 crease_tangent(const Mesh& m, const Features& f, VertexId v) {
  std::array<VertexId, 2> ends;
  int count = 0;
  bool more = false;
  auto add = [&](VertexId w) { count < 2 ? void(ends[count++] = w) : void(more = true); };
  for_each_outgoing(m, v, [&](HalfedgeId s) {
    if (f.is_sharp(m.edge(s))) add(m.to(s));
    // A boundary edge coming in has no outgoing half-edge: found from its face.
    if (!m.twin(Mesh::prev(s)).valid()) add(m.from(Mesh::prev(s)));
  });
  if (count < 2 || more) return {};
  const Vec3 p = m.position(v), p0 = m.position(ends[0]), p1 = m.position(ends[1]);
  const double d0 = distance(p, p0), d1 = distance(p, p1);
  if (!(d0 > 0) || !(d1 > 0)) return {};
  return normalized((-d1 / (d0 * (d0 + d1))) * p0 + ((d1 - d0) / (d0 * d1)) * p +
                    (d0 / (d1 * (d0 + d1))) * p1);
}

// A crease vertex's sector normal with its component along the crease curve removed: a curve
// on a surface is perpendicular to its normal, on either side of a crease. The face sums alone
// lean along the curve by degrees where a rim is zipped to a differently sampled one (issue 17:
// 2.4 deg RMS on the zipped cylinder, cone and tube walls, 0.3 after), and a long sliver's
// Hermite midpoint multiplies that by its length.
Vec3 across_crease(const Mesh& m, const Features& f, VertexId v, const Vec3& normal) {
  const Vec3 t = crease_tangent(m, f, v);
  const Vec3 n = normal - dot(normal, t) * t;
  // Keep the face sums where the curve runs nearly along them (a degenerate sample).
  return dot(n, n) > 0.25 ? normalized(n) : normal;
}

// The unit tangent at v of the sharp polyline that leaves it towards w: of the circle through
// v, w and the curve vertex beyond w (the chord where w ends the curve).
Vec3 curve_tangent_towards(const Mesh& m, const Features& f, VertexId v, VertexId w) {
  const Vec3 p0 = m.position(v), p1 = m.position(w);
  const double s1 = distance(p0, p1);
  const VertexId beyond = f.curve_beyond(w, v);
  if (!beyond.valid() || !(s1 > 0)) return normalized(p1 - p0);
  const Vec3 p2 = m.position(beyond);
  // The tangent at p0 of the circle through p0, p1, p2: exact on arcs and lines, where the
  // chord-length quadratic at its end leans by ~a sixth of the turn per chord squared (the
  // plate's outline arcs: 0.5-0.9 deg at its corners, which a 305 mm strip's Hermite midpoint
  // multiplies by the arc's sagitta).
  const Vec3 a = p1 - p0, b = p2 - p0, n = cross(a, b);
  const double n2 = dot(n, n);
  if (!(n2 > 1e-24 * dot(a, a) * dot(b, b))) return normalized(a);  // (nearly) a line
  const Vec3 centre = (1.0 / (2.0 * n2)) * cross(dot(a, a) * b - dot(b, b) * a, n);  // from p0
  const Vec3 t = normalized(cross(n, -1.0 * centre));
  return dot(t, a) >= 0 ? t : -1.0 * t;
}

// The sines below which two curves leaving a corner count as one line (their cross product
// says nothing of the normal).
constexpr double kCurvesApartSine = 0.34;  // 20 degrees

// A corner's sector normal: perpendicular to both sharp curves that bound the sector (towards
// w0 and w1), on the side of the face sums. Both curves lie on the sector's surface, so its
// normal at the corner is across both; the face sums of a zipped sector lean by degrees.
// The face sums when the curves leave nearly along one line.
Vec3 between_curves(const Mesh& m, const Features& f, VertexId v, VertexId w0, VertexId w1,
                    const Vec3& normal) {
  if (w0 == w1) return normal;
  const Vec3 c = cross(curve_tangent_towards(m, f, v, w0), curve_tangent_towards(m, f, v, w1));
  if (!(dot(c, c) > kCurvesApartSine * kCurvesApartSine)) return normal;
  const Vec3 n = normalized(c);
  return dot(n, normal) >= 0 ? n : -n;
}

// How far (cosine: 10 degrees) a strip's ruled normal (ruled_strip_normal) may turn from the
// face sums before they are kept: a wall that is not ruled between its two curves.
constexpr double kRuledTurnCosine = 0.984807753012208;
// The longest sector ruled_strip_normal reads (faces).
constexpr int kRuledMaxFaces = 64;
// How far a ruled midpoint may lie from the Hermite midpoint, as a fraction of its offset.
constexpr double kRuledSlack = 0.5;
// How far a foot may lie from the other end's curve circle (ruled_midpoint), per unit of
// their distance.
constexpr double kRuledCircleTol = 1e-2;

// The point of the polyline `chain` (curve vertices, in order) where (p - a) . t changes sign,
// on the circle through the chord's ends and a neighbour (exact on arcs and lines); false when
// it never does.
bool foot_on_curve(const Mesh& m, std::span<const VertexId> chain, const Vec3& a, const Vec3& t,
                   Vec3& foot) {
  for (std::size_t i = 0; i + 1 < chain.size(); ++i) {
    const Vec3 p0 = m.position(chain[i]), p1 = m.position(chain[i + 1]);
    const double g0 = dot(p0 - a, t), g1 = dot(p1 - a, t);
    if (g0 == 0) return foot = p0, true;  // (a corner straight across a corner)
    if ((g0 > 0) == (g1 > 0) || g0 == g1) continue;
    const Vec3 q = p0 + (g0 / (g0 - g1)) * (p1 - p0);
    if (chain.size() < 3) return foot = q, true;
    const Vec3 p2 = m.position(i > 0 ? chain[i - 1] : chain[i + 2]);
    // The circle through p0, p1, p2 (centre relative to p0), as curve_tangent_towards.
    const Vec3 u = p1 - p0, w = p2 - p0, n = cross(u, w);
    const double n2 = dot(n, n);
    if (!(n2 > 1e-24 * dot(u, u) * dot(w, w))) return foot = q, true;  // a line
    const Vec3 centre = p0 + (1.0 / (2.0 * n2)) * cross(dot(u, u) * w - dot(w, w) * u, n);
    foot = centre + distance(p0, centre) * normalized(q - centre);
    return true;
  }
  return false;
}

// The extreme spokes of the crease-bounded sector of from(h) that holds h.
void sector_ends(const Mesh& m, const Features& f, HalfedgeId h, HalfedgeId& first,
                 HalfedgeId& last) {
  first = last = h;
  for (HalfedgeId s = cw_within_patch(m, f, h); s.valid() && s != h; s = cw_within_patch(m, f, s))
    first = s;
  for (HalfedgeId s = ccw_within_patch(m, f, h); s.valid() && s != h; s = ccw_within_patch(m, f, s))
    last = s;
}

bool sliver_face(const Mesh& m, HalfedgeId h);

// Whether the crease vertex v = from(first)'s sector (its extreme spokes `first` and `last`, as
// sector_normal walks it) is a strip zipped between v's crease curve and another: every face's
// far edge on the other curve, the first and last faces reaching it from v's own curve
// neighbours by smooth edges (a zipped cylinder, cone or tube wall, an annulus, the plate's
// long strips). Then sets `foot`, the point of the far curve straight across from v
// (perpendicular to v's crease tangent, set in `tangent`), `own`, two vertices of v's curve
// beside v for its circle, and returns true. One end of the strip may instead be a sharp line
// joining a corner of each curve (the plate's flat-to-arc creases, joining its end sections):
// the end face of a crease vertex next to such a corner reaches the far curve along it, and a
// corner's sector is bounded by it on one side (its own curve is the other bounding one, its
// tangent that curve's circle's). That end face must be a sliver (kSliverAspect).
bool ruled_foot(const Mesh& m, const Features& f, HalfedgeId first, HalfedgeId last, Vec3& foot,
                Vec3& tangent, std::array<VertexId, 2>& own) {
  const VertexId v = m.from(first);
  const bool corner = f.kind(v) == VertexKind::Corner;
  std::array<VertexId, kRuledMaxFaces + 3> chain;
  std::size_t n = 1;  // chain[0]: a curve vertex before the far run, when there is one
  bool far_first = false, far_last = false;  // an end face along a line joining the curves
  for (HalfedgeId s = first;; s = ccw_within_patch(m, f, s)) {
    if (!s.valid() || n == kRuledMaxFaces) return false;
    const bool end = s == first || s == last;
    if (f.is_sharp(m.edge(Mesh::next(s))) == end) {
      // (only along a sliver: on the xyz cube's letters, walls a few times longer than tall
      // between two outlines, these midpoints doubled the largest distance from the input)
      if (!end || first == last || !sliver_face(m, s)) return false;
      (s == first ? far_first : far_last) = true;
      // A crease vertex's end face may reach the far curve by that line from a corner of its
      // own curve (the plate's strips next to its flat-to-arc creases).
      if (!corner && f.kind(s == first ? m.to(s) : m.opposite(s)) != VertexKind::Corner)
        return false;
    }
    if (s != first || (corner && far_first)) chain[n++] = m.to(s);
    if (s == last) break;
  }
  if (corner) {
    if (far_first == far_last) return false;
    if (far_last) chain[n++] = m.opposite(last);
    own[0] = far_first ? m.opposite(last) : m.to(first);
    own[1] = f.curve_beyond(own[0], v);
    if (!own[1].valid()) return false;
    tangent = curve_tangent_towards(m, f, v, own[0]);
  } else {
    if (far_first && far_last) return false;
    own = f.curve_neighbours(v);
    tangent = crease_tangent(m, f, v);
  }
  if (n < 2) return false;
  for (std::size_t i = 1; i < n; ++i)
    if (f.kind(chain[i]) < VertexKind::Crease) return false;
  // One more curve vertex at each end (their neighbours along the far curve).
  VertexId before, after;
  if (n >= 3) {
    before = f.curve_beyond(chain[1], chain[2]);
    after = f.curve_beyond(chain[n - 1], chain[n - 2]);
  } else if (f.kind(chain[1]) == VertexKind::Crease) {
    before = f.curve_neighbours(chain[1])[0];
    after = f.curve_neighbours(chain[1])[1];
  } else {
    // A lone far vertex at a corner (the plate's strip next to a flat-to-arc crease, whose
    // other end is the crease line's): the far curve leaves it on the strip's side, the bound
    // of the corner's sector holding the edge to v that is not on v's own curve.
    HalfedgeId s = first;
    while (m.to(s) != chain[1] && s != last) s = ccw_within_patch(m, f, s);
    HalfedgeId first_c, last_c;
    sector_ends(m, f, m.twin(s), first_c, last_c);
    for (const VertexId w : {m.to(first_c), m.opposite(last_c)})
      if (w != v && w != own[0] && w != own[1] && f.kind(w) >= VertexKind::Crease) after = w;
    if (after.valid()) {
      const VertexId beyond = f.curve_beyond(after, chain[1]);
      chain[n++] = after;
      after = beyond;
    }
  }
  std::size_t begin = 1;
  if (before.valid()) chain[0] = before, begin = 0;
  if (after.valid()) chain[n++] = after;
  return dot(tangent, tangent) > 0 &&
         foot_on_curve(m, std::span(chain).subspan(begin, n - begin), m.position(v), tangent, foot);
}

// The point at fraction w of the angle from p to q along the circle through p, q and `third`
// (along the chord when they are nearly on a line).
Vec3 arc_point(const Vec3& p, const Vec3& q, const Vec3& third, double w) {
  const Vec3 u = q - p, x = third - p, n = cross(u, x);
  const double n2 = dot(n, n);
  if (!(n2 > 1e-24 * dot(u, u) * dot(x, x))) return p + w * u;
  const Vec3 centre = p + (1.0 / (2.0 * n2)) * cross(dot(u, u) * x - dot(x, x) * u, n);
  const Vec3 r0 = p - centre, r1 = q - centre;
  const double angle = std::atan2(norm(cross(r0, r1)), dot(r0, r1));
  if (!(std::sin(angle) > 1e-9)) return p + w * u;
  return centre +
         (1.0 / std::sin(angle)) * (std::sin((1.0 - w) * angle) * r0 + std::sin(w * angle) * r1);
}

// The point of smooth edge a -> b (ha) between two crease vertices whose sectors at the edge are
// ruled strips (ruled_foot) between their two curves: the middle of the ruling halfway between
// the edge's ends, from the arcs of each curve between its end of the edge and the other end's
// foot. Exact on the walls of revolved and extruded profiles (a cone's: the Hermite midpoint of
// its true normals is 3e-3 mm RMS off on issue 17's zipped cone, round 8). False when either
// sector is not a strip.
bool ruled_midpoint(const Mesh& m, const Features& f, HalfedgeId ha, Vec3& point) {
  const VertexId va = m.from(ha), vb = m.to(ha);
  if (f.kind(va) < VertexKind::Crease || f.kind(vb) < VertexKind::Crease) return false;
  HalfedgeId first, last;
  Vec3 foot_a, foot_b, t;
  std::array<VertexId, 2> own_a, own_b;
  sector_ends(m, f, ha, first, last);
  if (!ruled_foot(m, f, first, last, foot_a, t, own_a)) return false;
  sector_ends(m, f, m.twin(ha), first, last);
  if (!ruled_foot(m, f, first, last, foot_b, t, own_b)) return false;
  // The third point of each curve's circle: the end's curve neighbour farther from the foot.
  // Each foot must lie on the circle (or line) through the other end and its curve
  // neighbours, which then gives the arc between them: a foot on another piece of the curve
  // (the plate's outline, arc and flat meeting at an unmarked crease) makes no ruled midpoint.
  auto third = [&](VertexId v, const std::array<VertexId, 2>& nb, const Vec3& foot, Vec3& point) {
    const Vec3 p = m.position(v), p0 = m.position(nb[0]), p1 = m.position(nb[1]);
    point = dot(p0 - foot, p0 - foot) >= dot(p1 - foot, p1 - foot) ? p0 : p1;
    return circle_distance(p0, p, p1, foot) <= kRuledCircleTol * distance(p, foot);
  };
  Vec3 third_a, third_b;
  if (!third(va, own_a, foot_b, third_a) || !third(vb, own_b, foot_a, third_b)) return false;
  // The ruling through the chord's midpoint: at fraction w of the way from a to b across the
  // rulings (from the chords of the two arcs), at v along it.
  const Vec3 a = m.position(va), b = m.position(vb), mid = 0.5 * (a + b);
  const Vec3 across = (foot_b - a) + (b - foot_a);
  const double across2 = dot(across, across);
  if (!(across2 > 0)) return false;
  const double w = std::clamp(dot(b - foot_a, across) / across2, 0.0, 1.0);
  const Vec3 near = arc_point(a, foot_b, third_a, w);
  const Vec3 far = arc_point(foot_a, b, third_b, w);
  const Vec3 ruling = far - near;
  const double ruling2 = dot(ruling, ruling);
  if (!(ruling2 > 0)) return false;
  point = near + std::clamp(dot(mid - near, ruling) / ruling2, 0.0, 1.0) * ruling;
  return true;
}

// The normal of a ruled strip (ruled_foot) at v = from(first): its surface is taken as ruled
// across the strip, so the normal is across both the crease tangent and the direction to the
// foot. Exact on the walls of revolved and extruded profiles, where the face sums tilt across
// the curve by the chords' sagittas over the strip's width (issue 17, round 8: 0.17-0.2 deg RMS
// on the zipped cylinder and cone, which the long edges' Hermite midpoints multiply by their
// length, and which chord-symmetry relaxation cannot see: a tilt of opposite signs at the two
// curves meets it too). `fallback` (the face sums held across the curve) when the sector is not
// such a strip or the ruled normal turns more than kRuledTurnCosine from it.
Vec3 ruled_strip_normal(const Mesh& m, const Features& f, HalfedgeId first, HalfedgeId last,
                        const Vec3& fallback) {
  Vec3 foot, t;
  std::array<VertexId, 2> own;
  if (!ruled_foot(m, f, first, last, foot, t, own)) return fallback;
  Vec3 normal = normalized(cross(t, foot - m.position(m.from(first))));
  if (dot(normal, fallback) < 0) normal = -normal;
  return dot(normal, fallback) >= kRuledTurnCosine ? normal : fallback;
}

// The normal of from(h)'s faces within the crease-bounded sector that holds half-edge h: on
// even rings weighted by the faces' angles at the vertex, on fans and zippers by their areas.
// Unit, or zero when the sector has no direction.
Vec3 sector_normal(const Mesh& m, const Features& f, HalfedgeId h) {
  // A smooth or dart vertex has one sector, its whole ring: walked from its own half-edge, so
  // the sum is the same, bit for bit, whichever spoke asks (and equals the per-vertex cache).
  if (f.kind(m.from(h)) <= VertexKind::Dart) h = m.halfedge(m.from(h));
  const Vec3 p = m.position(m.from(h));
  NormalSum sum;
  sum.square_areas = f.kind(m.from(h)) <= VertexKind::Dart;
  auto add = [&](HalfedgeId s) {
    sum.add(m.position(m.to(s)) - p, m.position(m.to(Mesh::next(s))) - p);
  };
  constexpr int kMaxWalk = 4096;  // a valence no mesh has; only guards a broken one
  // A smooth vertex has no sharp spoke and no boundary: its ring is walked without looking
  // at the features.
  const bool smooth = f.kind(m.from(h)) == VertexKind::Smooth;
  HalfedgeId s = h, last = h;
  int steps = 0;
  do {  // counter-clockwise up to a sharp spoke (or all the way round)
    add(s);
    last = s;
    s = smooth ? m.ccw_rotated(s) : ccw_within_patch(m, f, s);
  } while (s.valid() && s != h && ++steps < kMaxWalk);
  HalfedgeId first = h;         // (the sector's bounding spokes: to(first), from(prev(last)))
  if (!s.valid() && !smooth) {  // then clockwise from h, the faces on its other side
    s = cw_within_patch(m, f, h);
    steps = 0;
    while (s.valid() && s != h && ++steps < kMaxWalk) {
      add(s);
      first = s;
      s = cw_within_patch(m, f, s);
    }
  }
  // Angle weights suit even rings (a hull's); on a fan or zipper (spokes of very different
  // lengths) the few short spokes' faces may belong to another surface piece (a fillet's end
  // touching a rounded corner): there the area-weighted normal, dominated by the long faces,
  // is the better guess. Where a plane rules a smooth ring, its normal.
  Vec3 plane;
  if (f.kind(m.from(h)) <= VertexKind::Dart && !(sum.flat && dot(sum.first, sum.first) > 0) &&
      (sum.spoke_flags() & GuardVertex::kNotEven) && dominant_plane(m, m.from(h), plane))
    return plane;
  if (f.kind(m.from(h)) == VertexKind::Crease)
    return ruled_strip_normal(m, f, first, last, across_crease(m, f, m.from(h), sum.normal()));
  if (f.kind(m.from(h)) == VertexKind::Corner && !s.valid())
    return between_curves(m, f, m.from(h), m.to(first), m.from(Mesh::prev(last)), sum.normal());
  return sum.normal();
}

namespace {

// Faces whose normals are closer than this (sine of the angle) are coplanar: far below any
// dihedral of a curved surface's tessellation, above the rounding of float STL coordinates.
constexpr double kCoplanarSine = 1e-3;

// Planar patches are told by exact coplanarity, to the rounding of the coordinates: a corner
// within kPatchTol of the face's size plus kFloatRounding of its coordinates' magnitude (four
// float32 ulps: float STL coordinates of a CAD plane) from the plane. Not an angle: no two
// faces of a tessellated smooth surface are that flat, however fine.
constexpr double kPatchTol = 1e-6;
constexpr double kFloatRounding = 4.0 / (1 << 24);

[[gnu::always_inline]] inline bool coplanar(const Vec3& t0, const Vec3& t1,
                                            double sine = kCoplanarSine) {
  const Vec3 c = cross(t0, t1);
  return dot(c, c) <= (sine * sine) * (dot(t0, t0) * dot(t1, t1)) && dot(t0, t1) > 0;
}

// Whether face (p, q, r), of normal n = (q - p) x (r - p), lies, facing the same way, in the
// plane through p of normal t (unnormalised), to the rounding above (squared, without a root:
// the tolerance is taken as the root of the sum of its two terms' squares, times sqrt 2).
bool in_plane(const Vec3& t, const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& n) {
  if (!(dot(n, t) > 0)) return false;
  const double magnitude = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  const Vec3 pq = q - p, pr = r - p;
  const double size2 = std::max(dot(pq, pq), dot(pr, pr));
  const double tol2 = 2.0 * ((kPatchTol * kPatchTol) * size2 +
                             (kFloatRounding * magnitude) * (kFloatRounding * magnitude));
  const double dq = dot(pq, t), dr = dot(pr, t);
  return std::max(dq * dq, dr * dr) <= tol2 * dot(t, t);
}

bool in_plane(const Vec3& t, const Vec3& p, const Vec3& q, const Vec3& r) {
  return in_plane(t, p, q, r, cross(q - p, r - p));
}

// Whether the face of h (normal t, unnormalised) is coplanar with the face across one of its
// two other edges.
bool in_planar_patch(const Mesh& m, HalfedgeId h, const Vec3& t) {
  for (const HalfedgeId side : {Mesh::next(h), Mesh::prev(h)}) {
    const HalfedgeId across = m.twin(side);
    if (!across.valid()) continue;
    const Vec3 p = m.position(m.from(across)), q = m.position(m.to(across)),
               r = m.position(m.opposite(across));
    if (coplanar(t, triangle_normal(p, q, r)) && in_plane(t, p, q, r)) return true;
  }
  return false;
}

// How much of an edge end's face area (a fraction) must lie in the plane of the edge's faces
// for that plane to rule the edge (at a smooth vertex, of its ring; at a crease or corner
// vertex, of the sector: a crease-bounded plane fills it), and how much smaller than the
// plane's largest face there its other faces must be (a fraction): a flat face beside a fillet
// is several times wider than the fillet's strips, while the exactly planar split quads of a coarse
// torus or cylinder are as wide as their neighbours (on a coarse torus the angle creases,
// issue 17 item 5, cut bands whose sectors are two faces of a quad and one of the next).
constexpr double kPlaneAreaShare = 0.5;
constexpr double kPlaneDominance = 0.75;

// Whether the faces of from(h)'s crease-bounded sector that holds h (its whole ring when it
// is smooth) which lie in the plane of normal t (unnormalised), to the rounding of the
// coordinates, hold at least kPlaneAreaShare of the sector's face area and its largest face
// dominates the others (kPlaneDominance); `bends` is set when one
// of from(h)'s faces, in any sector, turns from t by more than kCoplanarSine (only asked while
// the answer can matter: when this returns true and `bends` was false).
bool planar_end(const Mesh& m, const Features& f, HalfedgeId h, const Vec3& t, bool& bends) {
  const VertexId v = m.from(h);
  const Vec3 p = m.position(v);
  double planar = 0, total = 0, largest_planar = 0, largest_other = 0;
  // Every face: whether it bends (and, for a smooth vertex, its share); then, at a crease or
  // corner vertex, the sector's shares.
  const bool whole_ring = f.kind(v) == VertexKind::Smooth;
  auto add = [&](HalfedgeId s, bool bend_only) {
    const Vec3 q = m.position(m.to(s)), r = m.position(m.opposite(s));
    const Vec3 n = cross(q - p, r - p);
    const bool near = coplanar(t, n);
    bends = bends || !near;
    if (bend_only) return;
    const double area = norm(n);
    total += area;
    if (near && in_plane(t, p, q, r, n)) {
      planar += area;
      largest_planar = std::max(largest_planar, area);
    } else {
      largest_other = std::max(largest_other, area);
    }
  };
  if (whole_ring) for_each_outgoing(m, v, [&](HalfedgeId s) { add(s, false); });
  if (!whole_ring) {  // the sector, as sector_normal walks it
    constexpr int kMaxWalk = 4096;
    HalfedgeId s = h;
    int steps = 0;
    do {
      add(s, false);
      s = ccw_within_patch(m, f, s);
    } while (s.valid() && s != h && ++steps < kMaxWalk);
    if (!s.valid()) {
      s = cw_within_patch(m, f, h);
      steps = 0;
      while (s.valid() && s != h && ++steps < kMaxWalk) {
        add(s, false);
        s = cw_within_patch(m, f, s);
      }
    }
  }
  const bool rules = total > 0 && planar >= kPlaneAreaShare * total &&
                     largest_other <= kPlaneDominance * largest_planar;
  // The faces outside the sector only tell whether something bends, which matters only when
  // the plane rules here, and not once a face has bent (the sector's faces were asked first).
  if (!whole_ring && rules && !bends) for_each_outgoing(m, v, [&](HalfedgeId s) { add(s, true); });
  return rules;
}

// How much wider across an edge a planar patch's face must be than the face on the other side
// for the edge to count as the patch's straight border.
constexpr double kPatchWidthRatio = 2.0;

// How far an endpoint estimate may be from the Hermite midpoint of the normals, as a fraction
// of the Hermite midpoint's own offset from the chord (plus 1e-3 of the chord).
constexpr double kHermiteSlack = 1.0;

// The slack instead of kHermiteSlack when an end of the edge is a smooth or dart vertex whose
// ring is a fan or zipper (GuardNormals::uneven), or any vertex with such a ring at an end of a
// sliver's long edge: measured on issue 17's families, seeds 1000-1005, L2: rounded box 0.54 ->
// 0.47, plate (with kSliverAspect) 0.61 -> 0.43 of the input; the other families unchanged.
constexpr double kUnevenHermiteSlack = 0.5;

// The slack instead of kHermiteSlack when an end of the edge is a crease or corner vertex:
// measured on issue 17's families, seeds 6000-6005, L2 RMS / ideal: cone 3.6 -> 1.9 (0.25: 2.6),
// plate 3.7 -> 3.3, cylinder 1.7 -> 1.8, tube 2.5 -> 2.6; the crease-free families unchanged.
constexpr double kCreaseHermiteSlack = 0.0;

// An edge at least this many times longer than the height across it of the narrower of its two
// faces is a sliver's long edge. Measured: 15 also changes the zipped cylinder and tube walls
// (worse); 30 and 60 only the plate's strips (aspect ~100).
constexpr double kSliverAspect = 30.0;

// The child-fold pass: how many halving rounds before the edges of a face still folding go to
// their chords, and the cosine of the screening angle (45 degrees) against the parent face.
constexpr int kFoldRounds = 6;
constexpr double kScreenCosine = 0.7071067811865476;

// Whether triangle (p, q, r) turns more than 60 degrees from the unit normal n (a degenerate
// one does not count).
[[gnu::always_inline]] inline bool turns_over_60(const Vec3& p, const Vec3& q, const Vec3& r,
                                                 const Vec3& n) {
  const Vec3 t = triangle_normal(p, q, r);
  const double d = dot(t, n);
  return d < 0 ? dot(t, t) > 0 : d * d < 0.25 * dot(t, t);  // cos < 1/2, without a root
}

// Pulls the edge point of edge a -> b towards the chord midpoint while a 1-to-4 child of one
// of its faces would turn more than 60 degrees from that face's normal (the other edges' points
// taken at their midpoints); at the midpoint when halving eight times is not enough. Face k
// is (a, b, opposite[k]) when normals[k] is its outward normal and (b, a, opposite[k]) when
// -normals[k] is (the test below is the same with both signs flipped).
Vec3 pull_back_folds(const Vec3& a, const Vec3& b, const std::array<Vec3, 2>& opposite,
                     const std::array<Vec3, 2>& normals, int sides, const Vec3& point) {
  const Vec3 mid = 0.5 * (a + b);
  auto folds = [&](const Vec3& q) {
    for (int k = 0; k < sides; ++k) {
      const Vec3 c = opposite[k], n = normals[k];
      const Vec3 ac = 0.5 * (a + c), bc = 0.5 * (b + c);
      if (turns_over_60(a, q, ac, n) || turns_over_60(q, b, bc, n) || turns_over_60(q, bc, ac, n))
        return true;
    }
    return false;
  };
  Vec3 q = point;
  bool folded = folds(q);  // (each point tested once: most are not pulled at all)
  for (int i = 0; i < 8 && folded; ++i) {
    q = mid + 0.5 * (q - mid);
    folded = folds(q);
  }
  return folded ? mid : q;
}

}  // namespace

std::uint8_t ring_spoke_flags(const Mesh& m, VertexId v) {
  const Vec3 p = m.position(v);
  NormalSum sum;  // only its spoke lengths
  for_each_outgoing(m, v, [&](HalfedgeId s) {
    const Vec3 d = m.position(m.to(s)) - p;
    const double l = dot(d, d);
    sum.shortest = std::min(sum.shortest, l), sum.longest = std::max(sum.longest, l);
  });
  return sum.spoke_flags();
}

bool dominant_plane(const Mesh& m, VertexId v, Vec3& normal) {
  const Vec3 p = m.position(v);
  // The largest face first, then the shares against its plane.
  Vec3 largest;
  double largest2 = 0;
  for_each_outgoing(m, v, [&](HalfedgeId s) {
    const Vec3 n = cross(m.position(m.to(s)) - p, m.position(m.opposite(s)) - p);
    const double n2 = dot(n, n);
    if (n2 > largest2) largest2 = n2, largest = n;
  });
  if (!(largest2 > 0)) return false;
  double planar = 0, total = 0, largest_other = 0;
  int in_plane_faces = 0;
  for_each_outgoing(m, v, [&](HalfedgeId s) {
    const Vec3 q = m.position(m.to(s)), r = m.position(m.opposite(s));
    const Vec3 n = cross(q - p, r - p);
    const double area = norm(n);
    total += area;
    if (coplanar(largest, n) && in_plane(largest, p, q, r, n)) {
      planar += area;
      ++in_plane_faces;
    } else {
      largest_other = std::max(largest_other, area);
    }
  });
  if (in_plane_faces < 2 || !(planar >= kPlaneAreaShare * total) ||
      !(largest_other <= kPlaneDominance * std::sqrt(largest2)))
    return false;
  normal = normalized(largest);
  return true;
}

// Whether the edge of h is a sliver's long edge (kSliverAspect, as guarded_edge_point tells it).
bool sliver_edge(const Mesh& m, HalfedgeId h) {
  const HalfedgeId t = m.twin(h);
  if (!t.valid()) return false;
  const Vec3 a = m.position(m.from(h)), chord = m.position(m.to(h)) - a;
  const Vec3 t0 = cross(chord, m.position(m.opposite(h)) - a),
             t1 = cross(chord, m.position(m.opposite(t)) - a);
  const double length2 = dot(chord, chord);
  return length2 * length2 >= (kSliverAspect * kSliverAspect) * std::min(dot(t0, t0), dot(t1, t1));
}

// Whether the face of h is a sliver: its longest edge at least kSliverAspect times its height
// across that edge.
bool sliver_face(const Mesh& m, HalfedgeId h) {
  const Vec3 a = m.position(m.from(h)), b = m.position(m.to(h)), c = m.position(m.opposite(h));
  const double longest2 = std::max({dot(b - a, b - a), dot(c - b, c - b), dot(a - c, a - c)});
  const Vec3 n = cross(b - a, c - a);
  return longest2 * longest2 >= (kSliverAspect * kSliverAspect) * dot(n, n);
}

// relax_normals: the damping towards a vertex's own normal of the round before, per unit of
// ring weight (small: it only keeps an ill-posed ring, spokes along a line, from wandering).
constexpr double kRelaxDamping = 0.03;
// A component of relaxed vertices stops when no normal of it turns by kRelaxConverged rad in a
// round, and after kShortRelaxRounds rounds unless its largest turn has come down to
// kConverging of its first round's (a scan's uneven rings, where the equations do not hold,
// keep turning; a CAD part's fillets and corners converge, slowly: bunny lsf L2 CPU +5%
// against +30% when every component ran kRelaxRounds).
constexpr double kRelaxConverged = 1e-6;
constexpr int kShortRelaxRounds = 10;
constexpr double kConverging = 0.1;
// A relaxed vertex is trusted (GuardVertex::relaxed) when the RMS over its ring of
// n_v . u + n_w . u is at most kRelaxTrusted and its normal turned by at most 30 degrees (cosine
// kRelaxTurnCosine) from its face sum; otherwise the face sum comes back.
constexpr double kRelaxTrusted = 0.1, kRelaxTurnCosine = 0.866;
// relax_normals: a vertex whose ring's RMS of n_v . u + n_w . u stays above kCurvedResidual after
// the plain rounds gets the equations' third-order curvature terms.
constexpr double kCurvedResidual = 5e-3;

namespace {
// The normal curvature along the unit direction u of the fit q, against the unit normal `side`
// (the fit's normal taken on its side): n . s_dd / |s_d|^2 for the parameter direction d whose
// tangent s_d is u's projection onto the fit's tangent plane. Zero for a degenerate fit.
double fit_normal_curvature(const QuadricFit& q, const Vec3& side, const Vec3& u) {
  if (!q.valid) return 0;
  const Vec3 &su = q.c[0], &sv = q.c[1];
  Vec3 n = normalized(cross(su, sv));
  if (dot(n, side) < 0) n = -1.0 * n;
  const Vec3 t = u - dot(u, n) * n;
  const double e = dot(su, su), g = dot(sv, sv), fm = dot(su, sv), det = e * g - fm * fm;
  if (!(det > 1e-24 * (e * g))) return 0;
  const double a = dot(su, t), b = dot(sv, t);
  const double du = (g * a - fm * b) / det, dv = (e * b - fm * a) / det;
  const Vec3 sd = du * su + dv * sv;
  const double sd2 = dot(sd, sd);
  if (!(sd2 > 0)) return 0;
  return dot(n, du * du * q.c[2] + 2.0 * du * dv * q.c[3] + dv * dv * q.c[4]) / sd2;
}
}  // namespace

void relax_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard, int rounds,
                   bool curvature_terms) {
  const std::size_t nv = m.num_vertices();
  // Which smooth one-sector vertices move: those whose ring is not even (hulls, fillets, fans
  // and zippers) and their even neighbours (a corner's fan centre between fillets), unless
  // every face of their ring lies in one plane (then the face sum is the plane's normal,
  // exactly). Even rings away from those (a scan's) keep their normals bit for bit: on a scan
  // almost no vertex is listed.
  auto movable = [&](VertexId v) {
    return f.kind(v) == VertexKind::Smooth && guard[v.idx].one_sector && m.halfedge(v).valid() &&
           !guard[v.idx].two_curves;
  };
  std::vector<std::uint8_t> marked(nv, 0);
  for (std::uint32_t i = 0; i < nv; ++i) {
    const VertexId v(i);
    if (guard[i].spokes == 0 || !movable(v)) continue;
    marked[i] = 1;
    for_each_outgoing(m, v, [&](HalfedgeId s) { marked[m.to(s).idx] = 1; });
  }
  std::vector<std::uint32_t> relaxed;
  for (std::uint32_t i = 0; i < nv; ++i) {
    const VertexId v(i);
    if (!marked[i] || !movable(v)) continue;
    const Vec3 p = m.position(v);
    NormalSum sum;
    for_each_outgoing(m, v, [&](HalfedgeId s) {
      sum.add(m.position(m.to(s)) - p, m.position(m.opposite(s)) - p);
    });
    if (!sum.flat) relaxed.push_back(i);
  }
  if (relaxed.empty()) return;
  // The listed vertices joined by edges make components that relax independently (the vertices
  // around them keep their normals): each runs rounds until it converges, so the small ones (a
  // scan's few uneven rings) stop after a few rounds. `order` lists them by component.
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> slot(nv, kNone), parent(relaxed.size());
  for (std::uint32_t k = 0; k < relaxed.size(); ++k) slot[relaxed[k]] = k, parent[k] = k;
  auto root = [&](std::uint32_t k) {
    while (parent[k] != k) k = parent[k] = parent[parent[k]];
    return k;
  };
  for (std::uint32_t k = 0; k < relaxed.size(); ++k)
    for_each_outgoing(m, VertexId(relaxed[k]), [&](HalfedgeId s) {
      const std::uint32_t j = slot[m.to(s).idx];
      if (j != kNone) {
        const std::uint32_t a = root(k), b = root(j);
        parent[std::max(a, b)] = std::min(a, b);
      }
    });
  std::vector<std::uint32_t> order(relaxed.size());
  for (std::uint32_t k = 0; k < relaxed.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return root(a) < root(b); });
  struct Component {
    std::uint32_t begin, end;  // of `order`
    double first2;             // the square of its largest turn in the first round
  };
  std::vector<Component> active;
  for (std::uint32_t b = 0; b < order.size();) {
    std::uint32_t e = b + 1;
    while (e < order.size() && root(order[e]) == root(order[b])) ++e;
    active.push_back({b, e, 0.0});
    b = e;
  }
  const std::vector<Component> active_all = active;
  // Each round solves, per vertex, the normal equations of
  //   sum over spokes (n . u + n_w . u)^2 + damping |n - n_round_before|^2
  // (u the unit spoke): the matrix and the fixed neighbours' part of the right-hand side are the
  // same every round, so they are set up once; a round reads only the listed neighbours.
  struct Solve {
    double c00, c01, c02, c11, c12, c22;  // the damped matrix's cofactors over its determinant
    double damping;
    Vec3 fixed;  // - sum (n_w . u) u over the neighbours that keep their normals
    std::uint32_t begin = 0, end = 0;  // of `spokes`
  };
  struct Spoke {
    Vec3 u;
    std::uint32_t slot;  // the listed neighbour's
  };
  std::vector<Solve> solve(relaxed.size());
  std::vector<std::uint32_t> listed_spokes(relaxed.size() + 1, 0);
  for (std::uint32_t k = 0; k < relaxed.size(); ++k) {
    std::uint32_t n = 0;
    for_each_outgoing(m, VertexId(relaxed[k]),
                      [&](HalfedgeId s) { n += slot[m.to(s).idx] != kNone; });
    listed_spokes[k + 1] = listed_spokes[k] + n;
  }
  std::vector<Spoke> spokes(listed_spokes.back());
  parallel_for_each_index(relaxed.size(), [&](std::size_t k) {
    const VertexId v(relaxed[k]);
    const Vec3 p = m.position(v);
    Solve& q = solve[k];
    q.begin = q.end = listed_spokes[k];
    double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0, count = 0;
    for_each_outgoing(m, v, [&](HalfedgeId s) {
      const Vec3 c = m.position(m.to(s)) - p;
      const double l2 = dot(c, c);
      if (!(l2 > 0)) return;
      const Vec3 u = (1.0 / std::sqrt(l2)) * c;
      const VertexId w = m.to(s);
      a00 += u.x * u.x, a01 += u.x * u.y, a02 += u.x * u.z;
      a11 += u.y * u.y, a12 += u.y * u.z, a22 += u.z * u.z;
      count += 1;
      if (slot[w.idx] != kNone) {
        spokes[q.end++] = {u, slot[w.idx]};
      } else {
        const Vec3 nw =
            guard[w.idx].one_sector ? guard[w.idx].normal : sector_normal(m, f, m.twin(s));
        q.fixed += -dot(nw, u) * u;
      }
    });
    q.damping = kRelaxDamping * count;
    a00 += q.damping, a11 += q.damping, a22 += q.damping;
    // Symmetric 3x3 by cofactors (positive definite with the damping).
    const double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22,
                 c02 = a01 * a12 - a02 * a11, c11 = a00 * a22 - a02 * a02,
                 c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
    const double det = a00 * c00 + a01 * c01 + a02 * c02;
    if (!(count > 0) || !(det > 0)) {
      q.damping = 0;  // not solved: keeps its normal
      return;
    }
    const double r = 1.0 / det;
    q.c00 = c00 * r, q.c01 = c01 * r, q.c02 = c02 * r, q.c11 = c11 * r, q.c12 = c12 * r,
    q.c22 = c22 * r;
  });
  std::vector<Vec3> current(relaxed.size()), next(relaxed.size()), initial(relaxed.size());
  for (std::uint32_t k = 0; k < relaxed.size(); ++k) initial[k] = guard[relaxed[k]].normal;
  current = initial;
  // curvature[k]: the third-order terms' part of vertex k's right-hand side (below); empty in
  // the first pass.
  std::vector<Vec3> curvature;
  auto run_rounds = [&](std::vector<Component> active) {
    std::vector<std::uint32_t> work;
    for (int round = 0; round < rounds && !active.empty(); ++round) {
      work.clear();
      for (const Component& c : active)
        work.insert(work.end(), order.begin() + c.begin, order.begin() + c.end);
      parallel_for_each_index(work.size(), [&](std::size_t w) {
        const std::size_t k = work[w];
        const Solve& q = solve[k];
        const Vec3 own = current[k];
        next[k] = own;
        if (q.damping == 0) return;
        Vec3 b = q.fixed + q.damping * own;
        if (!curvature.empty()) b += curvature[k];
        for (std::uint32_t j = q.begin; j < q.end; ++j)
          b += -dot(current[spokes[j].slot], spokes[j].u) * spokes[j].u;
        const Vec3 n((q.c00 * b.x + q.c01 * b.y + q.c02 * b.z),
                     (q.c01 * b.x + q.c11 * b.y + q.c12 * b.z),
                     (q.c02 * b.x + q.c12 * b.y + q.c22 * b.z));
        if (dot(n, n) > 0) next[k] = normalized(n);
      });
      // A component whose largest turn this round is below kRelaxConverged rad is done.
      std::size_t kept = 0;
      for (Component& c : active) {
        double largest2 = 0;
        for (std::uint32_t o = c.begin; o < c.end; ++o) {
          const std::uint32_t k = order[o];
          const Vec3 d = next[k] - current[k];
          largest2 = std::max(largest2, dot(d, d));
          current[k] = next[k];
        }
        if (round == 0) c.first2 = largest2;
        // Past kShortRelaxRounds only while converging: its largest turn shrunk to a tenth of
        // the first round's (a scan's rings, where the equations do not hold, keep turning).
        const bool converging =
            round + 1 < kShortRelaxRounds || largest2 <= (kConverging * kConverging) * c.first2;
        if (largest2 >= kRelaxConverged * kRelaxConverged && converging) active[kept++] = c;
      }
      active.resize(kept);
    }
  };
  run_rounds(active);
  // The chord symmetry is exact where the normal curvature along the chord is the same at both
  // ends (circles, spheres, cylinders, planes: the rounded box's pieces, where the rounds above
  // converge to residuals of 1e-4); where it changes (a coarse torus: by 0.05 / mm between
  // neighbouring rings) n_v . u + n_w . u = -(L / 6) (k_w - k_v) to third order, k the normal
  // curvatures along the chord, and the plain equations leave residuals of 1e-2 that tilt the
  // normals by degrees. So a second pass adds that term, with the curvatures of the vertices'
  // LSF fits, along the edges between two vertices whose ring residual exceeds kCurvedResidual
  // and whose rings are not fans or zippers (kUneven: their fits, one-sided, are the least
  // reliable). Elsewhere the plain equations stay.
  // The sum of the squared residuals of n . u + n_w . u = term(s, u, l) over v's spokes s
  // (unit u, length l; n_w the normal at the spoke's far end), and the number of spokes.
  auto ring_residual = [&](VertexId v, const Vec3& n, auto&& far_normal, auto&& term) {
    const Vec3 p = m.position(v);
    double sum = 0, count = 0;
    for_each_outgoing(m, v, [&](HalfedgeId s) {
      const Vec3 c = m.position(m.to(s)) - p;
      const double l2 = dot(c, c);
      if (!(l2 > 0)) return;
      const double l = std::sqrt(l2);
      const double r = dot(n + far_normal(s), c) / l - term(s, (1.0 / l) * c, l);
      sum += r * r, count += 1;
    });
    return std::pair{sum, count};
  };
  auto no_term = [](HalfedgeId, const Vec3&, double) { return 0.0; };
  std::vector<QuadricFit> fits(relaxed.size());
  std::vector<std::uint8_t> curved(relaxed.size(), 0);
  parallel_for_each_index(relaxed.size(), [&](std::size_t k) {
    const VertexId v(relaxed[k]);
    if (!curvature_terms || (guard[v.idx].spokes & GuardVertex::kUneven) ||
        f.kind(v) > VertexKind::Dart)
      return;
    auto far_normal = [&](HalfedgeId s) {
      const VertexId w = m.to(s);
      const std::uint32_t j = slot[w.idx];
      return j != kNone                ? current[j]
             : guard[w.idx].one_sector ? guard[w.idx].normal
                                       : sector_normal(m, f, m.twin(s));
    };
    const auto [sum, count] = ring_residual(v, current[k], far_normal, no_term);
    if (!(count > 0) || sum <= (kCurvedResidual * kCurvedResidual) * count) return;
    fits[k] = vertex_fit(m, f, v);
    curved[k] = fits[k].valid;
  });
  // The right-hand side of n_v . u + n_w . u = term along spoke s of relaxed vertex k (unit u,
  // length l): zero unless both ends are curved.
  auto curvature_term = [&](std::uint32_t k, HalfedgeId s, const Vec3& u, double l) {
    const std::uint32_t j = slot[m.to(s).idx];
    if (!curved[k] || j == kNone || !curved[j]) return 0.0;
    const double kappa_v = fit_normal_curvature(fits[k], current[k], u);
    const double kappa_w = fit_normal_curvature(fits[j], current[j], u);
    return -(l / 6.0) * (kappa_w - kappa_v);
  };
  if (curvature_terms && std::find(curved.begin(), curved.end(), 1) != curved.end()) {
    curvature.assign(relaxed.size(), Vec3());
    parallel_for_each_index(relaxed.size(), [&](std::size_t k) {
      if (!curved[k]) return;
      const Vec3 p = m.position(VertexId(relaxed[k]));
      for_each_outgoing(m, VertexId(relaxed[k]), [&](HalfedgeId s) {
        const Vec3 c = m.position(m.to(s)) - p;
        const double l2 = dot(c, c);
        if (!(l2 > 0)) return;
        const double l = std::sqrt(l2);
        const Vec3 u = (1.0 / l) * c;
        curvature[k] += curvature_term(static_cast<std::uint32_t>(k), s, u, l) * u;
      });
    });
    run_rounds(active_all);
  }
  for (std::uint32_t k = 0; k < relaxed.size(); ++k) guard[relaxed[k]].normal = current[k];
  // Trusted where the equations now hold along the ring (kRelaxTrusted). Elsewhere (a scan's
  // folded or needle rings, where the rounds need not converge) the face sums come back.
  parallel_for_each_index(relaxed.size(), [&](std::size_t k) {
    const VertexId v(relaxed[k]);
    const Vec3 n = guard[v.idx].normal;
    auto far_normal = [&](HalfedgeId s) {
      const VertexId w = m.to(s);
      return guard[w.idx].one_sector ? guard[w.idx].normal : sector_normal(m, f, m.twin(s));
    };
    auto term = [&](HalfedgeId s, const Vec3& u, double l) {
      return curvature_term(static_cast<std::uint32_t>(k), s, u, l);
    };
    const auto [sum, count] = ring_residual(v, n, far_normal, term);
    if (count > 0 && sum <= (kRelaxTrusted * kRelaxTrusted) * count &&
        dot(n, initial[k]) >= kRelaxTurnCosine)
      next[k] = n;
    else
      next[k] = Vec3();
  });
  for (std::uint32_t k = 0; k < relaxed.size(); ++k) {
    GuardVertex& g = guard[relaxed[k]];
    g.relaxed = dot(next[k], next[k]) > 0;
    g.curved = curved[k];
    if (!g.relaxed) g.normal = initial[k];
  }
}

// The unit tangent at p of the circle through a, p and b (of their line when straight).
Vec3 middle_tangent(const Vec3& a, const Vec3& p, const Vec3& b) {
  const Vec3 u = a - p, w = b - p;
  return normalized(dot(u, u) * w - dot(w, w) * u);
}

bool two_curve_normal(const Mesh& m, VertexId v, const Vec3& face_sum, Vec3& normal) {
  const Vec3 p = m.position(v);
  constexpr int kMaxSpokes = 64;
  std::array<Vec3, kMaxSpokes> spoke;
  int n = 0;
  bool too_many = false;
  for_each_outgoing(m, v, [&](HalfedgeId h) {
    n < kMaxSpokes ? void(spoke[n++] = m.position(m.to(h)) - p) : void(too_many = true);
  });
  if (too_many || n < 4) return false;
  // The long spokes (at least half the longest): of their pairs nearly opposite (within 20
  // degrees), the one v is most nearly the midpoint of. A sliver's midpoint after a level has
  // the split edge's two ends, and beside them the ends' other neighbours' midpoints, as long
  // (the plate's end outlines at 152 mm): the circle through the split edge's ends is the one
  // whose tangent at v lies in the surface (on an extrusion, by symmetry), where a lopsided
  // pair's tilts along the strip (0.3 mrad RMS on the plate, over 152 mm edges).
  double longest2 = 0;
  for (int i = 0; i < n; ++i) longest2 = std::max(longest2, dot(spoke[i], spoke[i]));
  int l0 = -1, l1 = -1;
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) {
    const double li2 = dot(spoke[i], spoke[i]);
    if (4.0 * li2 < longest2) continue;
    for (int j = i + 1; j < n; ++j) {
      const double lj2 = dot(spoke[j], spoke[j]);
      if (4.0 * lj2 < longest2 || !(dot(spoke[i], spoke[j]) < -0.94 * std::sqrt(li2 * lj2)))
        continue;
      const Vec3 sum = spoke[i] + spoke[j];
      const double lopsided = dot(sum, sum) / (li2 + lj2);
      if (lopsided < best) best = lopsided, l0 = i, l1 = j;
    }
  }
  if (l1 < 0) return false;
  const double short2 = std::min(dot(spoke[l0], spoke[l0]), dot(spoke[l1], spoke[l1])) /
                        (kTwoCurvesRatio * kTwoCurvesRatio);
  const Vec3 along = middle_tangent(spoke[l0] + p, p, spoke[l1] + p);
  // On each side of the long spokes, the short spoke most across them.
  const Vec3 side = cross(face_sum, along);
  int w0 = -1, w1 = -1;
  double best0 = 2, best1 = 2;
  for (int i = 0; i < n; ++i) {
    if (i == l0 || i == l1 || dot(spoke[i], spoke[i]) > short2) continue;
    const double c = std::abs(dot(spoke[i], along)) / norm(spoke[i]);
    if (dot(spoke[i], side) > 0 ? c < best0 : c < best1)
      (dot(spoke[i], side) > 0 ? (best0 = c, w0 = i) : (best1 = c, w1 = i));
  }
  if (w0 < 0 || w1 < 0) return false;
  normal = normalized(cross(along, middle_tangent(spoke[w0] + p, p, spoke[w1] + p)));
  if (dot(normal, face_sum) < 0) normal = -normal;
  return dot(normal, face_sum) >= kRuledTurnCosine;
}

void fit_guard_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard) {
  const double min_cosine = std::cos(kFitNormalDegrees * std::numbers::pi / 180.0);
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    GuardVertex& g = guard[i];
    const VertexId v(static_cast<std::uint32_t>(i));
    if (!g.relaxed || !g.curved || g.two_curves || f.kind(v) != VertexKind::Smooth) return;
    const QuadricFit q = vertex_fit(m, f, v);
    if (!q.valid) return;
    Vec3 n = normalized(cross(q.c[0], q.c[1]));
    if (dot(n, g.normal) < 0) n = -1.0 * n;
    if (dot(n, g.normal) >= min_cosine) g.normal = n;
  });
}

void two_curve_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard) {
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    GuardVertex& g = guard[i];
    const VertexId v(static_cast<std::uint32_t>(i));
    Vec3 n;
    if (g.one_sector && (g.spokes & GuardVertex::kUneven) && f.kind(v) == VertexKind::Smooth &&
        two_curve_normal(m, v, g.normal, n))
      g.normal = n, g.two_curves = 1, g.relaxed = 1;
  });
}

// relax_sliver_normals: the sweeps at most, the change of a tilt (rad) below which a sweep
// ends them, and the fewest crease sectors joined by slivers' long edges whose tilts are kept.
constexpr std::size_t kSliverRunNodes = 8;
constexpr int kSliverSweeps = 200;
constexpr double kSliverConverged = 1e-12;
// How far (rad) a flat sector of slivers may break the chord symmetry with a trusted smooth
// neighbour's normal and still be taken as a plane.
constexpr double kFlatSliversBend = 1e-3;

void relax_sliver_normals(const Mesh& m, const Features& f, std::span<GuardVertex> guard,
                          SectorNormals& sectors) {
  // Both half-edges of every smooth sliver edge between two crease vertices (the only ones
  // that move), found from the crease vertices: a scan of the vertex kinds where there are none.
  // Besides, every short smooth spoke (not a sliver's long edge) from a crease vertex to a
  // smooth vertex whose guard normal is trusted (GuardVertex::relaxed: the two-curve normals
  // of the strips' midpoints after a level): `anchor_spokes`.
  std::vector<std::uint32_t> sliver_spokes, anchor_spokes;
  for (std::uint32_t i = 0; i < m.num_vertices(); ++i) {
    if (f.kind(VertexId(i)) != VertexKind::Crease) continue;
    for_each_outgoing(m, VertexId(i), [&](HalfedgeId h) {
      const VertexId w = m.to(h);
      if (f.is_sharp(m.edge(h))) return;
      if (f.kind(w) == VertexKind::Smooth && guard[w.idx].one_sector && guard[w.idx].relaxed) {
        if (!sliver_edge(m, h)) anchor_spokes.push_back(h.idx);
        return;
      }
      if (w.idx < i || f.kind(w) != VertexKind::Crease || !sliver_edge(m, h)) return;
      sliver_spokes.push_back(h.idx);
      sliver_spokes.push_back(m.twin(h).idx);
    });
  }
  if (sliver_spokes.empty()) return;
  // One node per crease sector with a sliver edge. Every outgoing half-edge of its sector maps
  // to it (spoke_node), so the node at an edge's far end is found from the spoke's twin.
  struct Node {
    Vec3 base, along;                   // the sector normal; the unit direction it may tilt in
    bool anchor = false;                // a flat sector, or one not all slivers
    bool flat_slivers = false;          // flat, and all slivers
    std::vector<std::uint32_t> spokes;  // its sliver spokes
  };
  std::vector<Node> nodes;
  std::unordered_map<std::uint32_t, std::uint32_t> spoke_node;  // half-edge -> node
  auto node_of = [&](HalfedgeId h) -> std::int64_t {
    const auto it = spoke_node.find(h.idx);
    return it != spoke_node.end() ? std::int64_t{it->second} : -1;
  };
  for (const std::uint32_t s : sliver_spokes) {
    const HalfedgeId h(s);
    const VertexId v = m.from(h);
    if (const std::int64_t k = node_of(h); k >= 0) {
      nodes[static_cast<std::size_t>(k)].spokes.push_back(s);
      continue;
    }
    Node node;
    node.base = sector_normal(m, f, h);
    if (!(norm(node.base) > 0)) continue;
    node.spokes.push_back(s);
    const auto index = static_cast<std::uint32_t>(nodes.size());
    {  // the sector's spokes, as sector_normal walks it
      // Only a sector of slivers (a strip's end) moves: a flat sector's normal is its plane's,
      // exact (a cap fanned into slivers), and a sector with a wider face holds another piece
      // of surface (a flat face beyond a shallow crease the angle did not mark).
      const Vec3 p = m.position(v);
      const Vec3 first = cross(m.position(m.to(h)) - p, m.position(m.opposite(h)) - p);
      bool flat = true, slivers = true;
      auto add = [&](HalfedgeId o) {
        spoke_node.emplace(o.idx, index);
        flat =
            flat && coplanar(first, cross(m.position(m.to(o)) - p, m.position(m.opposite(o)) - p));
        slivers = slivers && sliver_face(m, o);
      };
      HalfedgeId o = h;
      do {
        add(o);
        o = ccw_within_patch(m, f, o);
      } while (o.valid() && o != h);
      if (!o.valid())
        for (o = cw_within_patch(m, f, h); o.valid() && o != h; o = cw_within_patch(m, f, o))
          add(o);
      node.anchor = flat || !slivers;
      node.flat_slivers = flat && slivers;
    }
    nodes.push_back(std::move(node));
  }
  // A flat sector of slivers is a plane's unless a trusted smooth neighbour across a short edge
  // says the surface bends there (the plate's crease line after a level, whose three slivers
  // lie in the chord plane of the arc's first strip, 3-7 degrees off): then it moves.
  for (const std::uint32_t s : anchor_spokes) {
    const HalfedgeId h(s);
    const std::int64_t k = node_of(h);
    if (k < 0 || !nodes[static_cast<std::size_t>(k)].flat_slivers) continue;
    Node& node = nodes[static_cast<std::size_t>(k)];
    const Vec3 u = normalized(m.position(m.to(h)) - m.position(m.from(h)));
    if (std::abs(dot(node.base + guard[m.to(h).idx].normal, u)) > kFlatSliversBend)
      node.anchor = false;
  }
  // The direction each node tilts in: about the crease curve (so it stays across the curve).
  std::vector<std::uint8_t> fixed(nodes.size(), 0);
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    Node& node = nodes[k];
    const Vec3 along = cross(crease_tangent(m, f, m.from(HalfedgeId(node.spokes[0]))), node.base);
    if (node.anchor || !(dot(along, along) > 0.25))
      fixed[k] = 1;
    else
      node.along = normalized(along);
  }
  // One equation per sliver edge between two moving sector normals: c_a t_a + c_b t_b = rhs,
  // from (base_a + t_a along_a) . u + (base_b + t_b along_b) . u = 0 (u the unit chord). An
  // edge to anything else says nothing (a corner's, a smooth vertex's or a mixed sector's
  // normal is less sure than the strip's own).
  struct Equation {
    std::size_t a = 0, b = 0;
    double ca = 0, cb = 0, rhs = 0;
  };
  std::vector<Equation> equations;
  for (std::size_t k = 0; k < sliver_spokes.size(); k += 2) {
    const HalfedgeId h(sliver_spokes[k]), t(sliver_spokes[k + 1]);
    const std::int64_t a = node_of(h), b = node_of(t);
    if (a < 0 || b < 0 || fixed[static_cast<std::size_t>(a)] || fixed[static_cast<std::size_t>(b)])
      continue;
    const Vec3 u = normalized(m.position(m.to(h)) - m.position(m.from(h)));
    const Node &na = nodes[static_cast<std::size_t>(a)], &nb = nodes[static_cast<std::size_t>(b)];
    Equation eq{static_cast<std::size_t>(a), static_cast<std::size_t>(b), dot(na.along, u),
                dot(nb.along, u), -dot(na.base + nb.base, u)};
    if (eq.ca * eq.ca + eq.cb * eq.cb > 0) equations.push_back(eq);
  }
  // An edge to a trusted smooth normal holds the node's tilt itself (b = a, cb = 0): what the
  // equations between nodes leave free is then fixed, however short the run.
  std::vector<std::uint8_t> anchored(nodes.size(), 0);
  for (const std::uint32_t s : anchor_spokes) {
    const HalfedgeId h(s);
    const std::int64_t a = node_of(h);
    if (a < 0 || fixed[static_cast<std::size_t>(a)]) continue;
    const auto k = static_cast<std::size_t>(a);
    const Vec3 u = normalized(m.position(m.to(h)) - m.position(m.from(h)));
    const Equation eq{k, k, dot(nodes[k].along, u), 0.0,
                      -dot(nodes[k].base + guard[m.to(h).idx].normal, u)};
    if (eq.ca != 0) equations.push_back(eq), anchored[k] = 1;
  }
  // Kaczmarz sweeps from zero tilts: they converge to the least-norm tilts that meet the
  // equations, so what they leave undetermined (a lone strip's two ends tilting opposite ways)
  // keeps the face sums' normals. (Gauss-Seidel per node put the whole correction on the
  // first end it visited: the zipped cylinder's isolated slivers got worse.)
  std::vector<double> tilt(nodes.size(), 0.0);
  for (int sweep = 0; sweep < kSliverSweeps && !equations.empty(); ++sweep) {
    double change = 0;
    for (const Equation& eq : equations) {
      const double step =
          (eq.rhs - eq.ca * tilt[eq.a] - eq.cb * tilt[eq.b]) / (eq.ca * eq.ca + eq.cb * eq.cb);
      tilt[eq.a] += step * eq.ca;
      tilt[eq.b] += step * eq.cb;
      change = std::max(change, std::abs(step));
    }
    if (change < kSliverConverged) break;
  }
  // The Hermite midpoint of an edge reads the difference of its ends' tilts, and the
  // equations fix their sums: what they leave, the one free tilt per connected run of strips
  // (ends tilting alternately), is the mean of its face sums' errors, small only over many
  // strips (the plate's zipped sides). A short run keeps its face sums (the zipped cylinder's
  // few isolated slivers got worse).
  std::vector<std::size_t> parent(nodes.size()), size(nodes.size(), 1);
  for (std::size_t k = 0; k < nodes.size(); ++k) parent[k] = k;
  auto root = [&](std::size_t k) {
    while (parent[k] != k) k = parent[k] = parent[parent[k]];
    return k;
  };
  for (const Equation& eq : equations) {
    std::size_t ra = root(eq.a), rb = root(eq.b);
    if (ra == rb) continue;
    if (size[ra] < size[rb]) std::swap(ra, rb);
    parent[rb] = ra, size[ra] += size[rb];
  }
  std::vector<std::uint8_t> run_anchored(nodes.size(), 0);
  for (std::size_t k = 0; k < nodes.size(); ++k)
    if (anchored[k]) run_anchored[root(k)] = 1;
  std::vector<Vec3> current(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    if (size[root(k)] < kSliverRunNodes && !run_anchored[root(k)]) fixed[k] = 1;
    current[k] = fixed[k] ? nodes[k].base : normalized(nodes[k].base + tilt[k] * nodes[k].along);
  }
  for (std::size_t k = 0; k < nodes.size(); ++k)
    if (!fixed[k]) guard[m.from(HalfedgeId(nodes[k].spokes[0])).idx].sectors_relaxed = 1;
  for (const auto& [h, k] : spoke_node)
    if (!fixed[k]) sectors.by_halfedge.push_back({h, current[k]});
  std::sort(sectors.by_halfedge.begin(), sectors.by_halfedge.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
}

Vec3 guarded_edge_point(const GuardNormals& normal_of, EdgeId e, const Vec3& lower_estimate,
                        const Vec3& upper_estimate) {
  const Mesh& m = normal_of.mesh;
  const Features& f = normal_of.features;
  const GuardVertex* guard = normal_of.guard;
  const HalfedgeId h0 = m.halfedge(e), h1 = m.twin(h0);
  const Vec3 average = 0.5 * (lower_estimate + upper_estimate);
  if (!h1.valid()) return average;
  // ha runs a -> b; its estimate is a's fit.
  const HalfedgeId ha = h0.idx < h1.idx ? h0 : h1, hb = m.twin(ha);
  const Vec3 a = m.position(m.from(ha)), b = m.position(m.to(ha));
  const Vec3 mid = 0.5 * (a + b), chord = b - a;
  // Planar regions stay planar. Both faces in one plane, or a face of a planar patch
  // (coplanar with a neighbour across one of its other edges) at least twice as wide across
  // the edge as the face on the other side (a flat face ending at a fillet, tangent or at a
  // shallow crease: issue 17's rounded box and plate), "in one plane" meaning to the rounding
  // of the coordinates (in_plane), never by an angle: a smooth surface's tessellation, however
  // fine, has no two faces that flat. The plane then rules the edge when it is most of both
  // ends' neighbourhoods and the rest bends away for real (planar_end): the one-sided or mixed
  // fits there bow a straight edge. (A regular cylinder's split quads are exactly planar too,
  // but they are a small part of their corners' rings: they keep their fits. Near a flat net
  // nothing bends by more than kCoplanarSine, so the fits, linear there, decide: the spectral
  // analysis linearises the scheme about exactly such a net.)
  const Vec3 c0 = m.position(m.opposite(ha)), c1 = m.position(m.opposite(hb));
  const Vec3 t0 = triangle_normal(a, b, c0), t1 = triangle_normal(b, a, c1);
  // The squared widths across the edge, times its length. (Squares throughout: this runs for
  // every edge of every level, and the roots cost as much as the rest.)
  const double w0 = dot(t0, t0), w1 = dot(t1, t1);
  // When every face at a and at b is within kFlatSine of one face there (flat, known for
  // the batched smooth vertices), every face there is within kCoplanarSine of t0 and of t1:
  // nothing bends, so on_plane is false, and its walks are skipped (the flat regions of a
  // CAD part, most of its edges after a level).
  const bool no_bend = guard != nullptr && guard[m.from(ha).idx].flat && guard[m.from(hb).idx].flat;
  auto on_plane = [&](const Vec3& t) {  // (only asked for the few exactly planar candidates)
    if (no_bend) return false;
    bool bends = false;
    return planar_end(m, f, ha, t, bends) && planar_end(m, f, hb, t, bends) && bends;
  };
  constexpr double kRatio2 = kPatchWidthRatio * kPatchWidthRatio;
  const Vec3 na = normal_of(ha), nb = normal_of(hb);
  const double length2 = dot(chord, chord);
  const double length = std::sqrt(length2);
  const Vec3 hermite = hermite_midpoint_offset(chord, length, na, nb);
  // A ruled strip's edge between its two curves: the ruled midpoint, unless it strays from the
  // Hermite midpoint by more than kRuledSlack of its offset (then not a ruled wall).
  if (Vec3 ruled; ruled_midpoint(m, f, ha, ruled)) {
    const Vec3 off = ruled - mid - hermite;
    if (dot(off, off) <= kRuledSlack * kRuledSlack * dot(hermite, hermite)) return ruled;
  }
  // coplanar() first: no root, and false for almost every edge of a curved surface.
  if (((coplanar(t0, t1) && in_plane(t0, b, a, c1)) ||
       (w0 >= kRatio2 * w1 && in_planar_patch(m, ha, t0))) &&
      on_plane(t0))
    return mid;
  if (w1 >= kRatio2 * w0 && in_planar_patch(m, hb, t1) && on_plane(t1)) return mid;
  const Vec3 da = lower_estimate - mid - hermite, db = upper_estimate - mid - hermite;
  const double hermite_length = norm(hermite);
  // The allowance besides the Hermite offset: 1e-3 of the chord, or of the narrower face's
  // height across a sliver's long edge (kSliverAspect), whose chord says nothing of how far its
  // surface bends (the plate's 305 mm strips round a few millimetres of arc).
  const double narrow2 = std::min(w0, w1);
  const bool sliver = length2 * length2 >= (kSliverAspect * kSliverAspect) * narrow2;
  const double scale = sliver ? std::min(length, std::sqrt(narrow2 / length2)) : length;
  const double tolerance = kHermiteSlack * hermite_length + 1e-3 * scale;
  const double tolerance2 = tolerance * tolerance;
  bool a_ok = dot(da, da) <= tolerance2, b_ok = dot(db, db) <= tolerance2;
  // Next to a fan or zipper the fits are the least reliable (their samples mix far points on one
  // side with near ones, or two surface pieces): an estimate there must lie within
  // kUnevenHermiteSlack of the Hermite offset. Only asked when it can change the outcome.
  const double strict = kUnevenHermiteSlack * hermite_length + 1e-3 * scale;
  const double strict2 = strict * strict;
  // At a crease or corner end the fit is one-sided (its sector's angles scaled to pi, or the
  // natural angles): on a zipped wall it extrapolates the far rim's few points, while the
  // Hermite midpoint of normals held across the crease curves (sector_normal) is close to
  // the truth. There only the allowance beside the Hermite offset is left (kCreaseHermiteSlack).
  if (f.kind(m.from(ha)) >= VertexKind::Crease || f.kind(m.from(hb)) >= VertexKind::Crease) {
    const double crease = kCreaseHermiteSlack * hermite_length + 1e-3 * scale;
    a_ok = a_ok && dot(da, da) <= crease * crease;
    b_ok = b_ok && dot(db, db) <= crease * crease;
  }
  if (((a_ok && dot(da, da) > strict2) || (b_ok && dot(db, db) > strict2)) &&
      (normal_of.uneven(ha, sliver) || normal_of.uneven(hb, sliver))) {
    a_ok = a_ok && dot(da, da) <= strict2;
    b_ok = b_ok && dot(db, db) <= strict2;
  }
  // Both ends' normals relaxed to the chord symmetry (relax_normals): they agree with their
  // neighbours' along every edge, so the Hermite midpoint (exact on circles) is the surface's
  // point, where the fits bend towards their far, one-sided samples (the rounded box: 0.1-0.2
  // mm off at fillet ends and sphere corners, against 0.01 mm).
  const bool relaxed_ends =
      guard != nullptr && guard[m.from(ha).idx].relaxed && guard[m.from(hb).idx].relaxed;
  if (relaxed_ends) a_ok = b_ok = false;
  Vec3 point = a_ok && b_ok ? average
               : a_ok       ? lower_estimate
               : b_ok       ? upper_estimate
                            : mid + hermite;
  // The fold guard against the normals: the children of both faces at the edge. A point
  // within a tenth of the narrower face's height of the chord turns no child by more than
  // about 11 degrees from its parent: not checked (most points of a fine level).
  const Vec3 offset = point - mid;
  // Between relaxed ends only the face guard (guard_child_folds) checks the children: this one
  // puts the faces' other edge points on their chords, which on a strongly curved face (a
  // sphere corner's fan, sagitta a sixth of the chord) turns the children by 60 degrees
  // where the points are right, and pulled them 0.2 mm inside the sphere.
  if (relaxed_ends || dot(offset, offset) * length2 < 0.01 * std::min(w0, w1)) return point;
  const Vec3 n = normalized(na + nb);
  if (norm(n) == 0) return point;
  const std::array<Vec3, 2> opposite = {c0, c1};
  const std::array<Vec3, 2> normals = {n, -n};  // hb's face seen from a -> b is reversed
  return pull_back_folds(a, b, opposite, normals, 2, point);
}
namespace {

// Whether a 1-to-4 child of face `face`, with the edge points `points`, turns more than 60
// degrees from the face's sector normals (the sum over its three corners). Screened first
// against the face itself: a child within 45 degrees of its parent is not checked further.
bool child_folds(const GuardNormals& normal_of, std::span<const Vec3> points, FaceId face) {
  const Mesh& m = normal_of.mesh;
  const HalfedgeId h0 = Mesh::halfedge(face, 0), h1 = Mesh::halfedge(face, 1),
                   h2 = Mesh::halfedge(face, 2);
  const Vec3 a = m.position(m.from(h0)), b = m.position(m.from(h1)), c = m.position(m.from(h2));
  const Vec3 ab = points[m.edge(h0).idx], bc = points[m.edge(h1).idx], ca = points[m.edge(h2).idx];
  const std::array<std::array<Vec3, 3>, 4> children = {
      {{a, ab, ca}, {ab, b, bc}, {ca, bc, c}, {ab, bc, ca}}};
  const Vec3 parent = triangle_normal(a, b, c);
  const double parent2 = dot(parent, parent);
  bool suspect = false;
  for (const auto& t : children) {  // cos < kScreenCosine, without a root
    const Vec3 n = triangle_normal(t[0], t[1], t[2]);
    const double d = dot(n, parent);
    suspect = suspect || d < 0 || d * d < (kScreenCosine * kScreenCosine) * (dot(n, n) * parent2);
  }
  if (!suspect) return false;
  const Vec3 n = normalized(normal_of(h0) + normal_of(h1) + normal_of(h2));
  if (norm(n) == 0) return false;
  for (const auto& t : children)
    if (turns_over_60(t[0], t[1], t[2], n)) return true;
  return false;
}

}  // namespace

void guard_child_folds(const GuardNormals& normal_of, std::span<Vec3> points,
                       std::span<std::uint8_t> marks) {
  const Mesh& m = normal_of.mesh;
  const std::size_t nf = m.num_faces();
  auto midpoint = [&](EdgeId e) {
    const HalfedgeId h = m.halfedge(e);
    return 0.5 * (m.position(m.from(h)) + m.position(m.to(h)));
  };
  // Every face once (in parallel), then only the folding faces and their neighbours: the
  // faces whose edge points the last round moved.
  std::atomic<bool> any{false};
  parallel_for_each_index(nf, [&](std::size_t i) {
    marks[i] = child_folds(normal_of, points, FaceId(static_cast<std::uint32_t>(i)));
    if (marks[i]) any.store(true, std::memory_order_relaxed);
  });
  if (!any.load()) return;
  std::vector<std::uint32_t> folding;
  for (std::size_t i = 0; i < nf; ++i)
    if (marks[i]) folding.push_back(static_cast<std::uint32_t>(i));
  std::vector<std::uint32_t> candidates;
  for (int round = 0; round <= kFoldRounds && !folding.empty(); ++round) {
    // Halfway back towards the chord (the last round: onto it), each edge of each folding
    // face; an edge of two folding faces moves twice.
    candidates.clear();
    for (const std::uint32_t i : folding) {
      for (int k = 0; k < 3; ++k) {
        const HalfedgeId h = Mesh::halfedge(FaceId(i), k);
        const EdgeId e = m.edge(h);
        const Vec3 mid = midpoint(e);
        points[e.idx] = round == kFoldRounds ? mid : mid + 0.5 * (points[e.idx] - mid);
        candidates.push_back(i);
        if (m.twin(h).valid()) candidates.push_back(Mesh::face(m.twin(h)).idx);
      }
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    folding.clear();
    for (const std::uint32_t i : candidates)
      if (child_folds(normal_of, points, FaceId(i))) folding.push_back(i);
  }
}
}  // namespace lsf

Vec3 lsf_guarded_edge_point(const Mesh& m, const Features& f, EdgeId e, const Vec3& lower_estimate,
                            const Vec3& upper_estimate) {
  return lsf::guarded_edge_point(lsf::GuardNormals{m, f}, e, lower_estimate, upper_estimate);
}

Vec3 lsf_guarded_curve_point(const Mesh& m, const Features& f, EdgeId e, const Vec3& point) {
  const HalfedgeId h = m.halfedge(e), t = m.twin(h);
  const Vec3 a = m.position(m.from(h)), b = m.position(m.to(h));
  // As for smooth edges (guarded_edge_point): a point within a tenth of the narrower face's
  // height of the chord turns no child by more than about 11 degrees from its parent, and is
  // not checked (the sector normals are four walks round the ends).
  {
    const Vec3 chord = b - a, offset = point - 0.5 * (a + b);
    double narrowest = std::numeric_limits<double>::infinity();
    for (const HalfedgeId s : {h, t}) {
      if (!s.valid()) continue;
      const Vec3 w = cross(chord, m.position(m.opposite(s)) - a);
      narrowest = std::min(narrowest, dot(w, w));
    }
    if (dot(offset, offset) * dot(chord, chord) < 0.01 * narrowest) return point;
  }
  // Each side's children against that side's normals (sectors end at the sharp edge).
  std::array<Vec3, 2> opposite, normals;
  int sides = 0;
  for (const HalfedgeId s : {h, t}) {
    if (!s.valid()) continue;
    const Vec3 n =
        normalized(lsf::sector_normal(m, f, s) + lsf::sector_normal(m, f, Mesh::next(s)));
    if (norm(n) == 0) continue;
    // Seen from a -> b: the face of t runs b -> a, so its corners are swapped back below.
    opposite[sides] = m.position(m.opposite(s));
    normals[sides] = s == h ? n : -n;
    ++sides;
  }
  return lsf::pull_back_folds(a, b, opposite, normals, sides, point);
}
void lsf_guard_child_folds(const Mesh& m, const Features& f, std::span<Vec3> points,
                           std::span<std::uint8_t> marks) {
  lsf::guard_child_folds(lsf::GuardNormals{m, f}, points, marks);
}
}  // namespace stlrefine
