// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/post_pass.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <mutex>
#include <numbers>

#include "core/geometry/point_triangle.h"
#include "core/parallel.h"
#include "primitives/chordal.h"
#include "primitives/smooth_pull.h"

namespace stlrefine::primitives {

namespace {

using K = CGAL::Simple_cartesian<double>;
using Triangles = std::vector<K::Triangle_3>;
using AabbPrimitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
using AabbTraits = CGAL::AABB_traits<K, AabbPrimitive>;
using Tree = CGAL::AABB_tree<AabbTraits>;
using TreeNode = CGAL::AABB_node<AabbTraits>;

K::Point_3 point3(const Vec3& p) {
  return {p.x, p.y, p.z};
}

// A snap onto a crease curve that moves a vertex more than this fraction of the way towards
// one of its neighbours and ends nearer it than this fraction of their edge is taken back if
// it turns a face over.
constexpr double kCurveSnapLand = 0.5;

// What one output vertex ends as.
struct Outcome {
  Vec3 position;
  double distance_before = 0, distance_after = 0, snap_move = 0, pull_back = 0, bound = 0,
         allowance = 0;
  std::uint32_t face = 0;  // the closest input face at the end
  // Where the vertex goes without its snap (pulled back within the default bound only), for a
  // snap that turns a face over: its closest face and distance there.
  Vec3 original, fallback;
  std::uint32_t fallback_face = 0;
  double fallback_distance = 0, fallback_bound = 0;
  std::uint8_t reverted = 0;
  // A curve snap that moved it more than kCurveSnapLand of the way towards a neighbour and
  // ended nearer it than kCurveSnapLand of their edge.
  std::uint8_t curve_land = 0;
  std::uint8_t is_new = 0, snapped = 0, to_curve = 0, refused = 0, pulled = 0;
  // The regions it was snapped onto: one, or the two whose curve it is on; -1 for none.
  std::array<std::int32_t, 2> region{-1, -1};
};

}  // namespace

struct InputSurface::Impl {
  std::vector<Vec3> positions;
  std::vector<std::array<std::uint32_t, 3>> faces;
  std::vector<Vec3> normals;  // unit (zero for a degenerate face)
  // Per face: the default deviation bound, the input's chordal error there (chordal_bounds).
  std::vector<double> bound;
  std::vector<std::int32_t> face_region;  // empty without regions
  // Per face and edge k (corner k to k + 1): the face across when the edge is sharp, else -1.
  std::vector<std::array<std::int32_t, 3>> across_crease;
  std::vector<Region> regions;
  double diagonal = 0, tolerance = 0;
  Triangles triangles;
  Tree tree;
  // The recognised regions' faces alone (their input face ids in region_faces), when they
  // are under half of the input: a scan has a few flat facets at most, and a new vertex with
  // none of them within reach cannot snap; this small tree says so without a search of the
  // whole input. Empty otherwise (every vertex is searched).
  Triangles region_triangles;
  std::vector<std::uint32_t> region_faces;
  Tree region_tree;

  std::size_t face_of(const Tree::Primitive_id& id) const {
    return static_cast<std::size_t>(id - triangles.begin());
  }
  Vec3 closest_on(std::size_t f, const Vec3& p) const {
    const auto& t = faces[f];
    return closest_point_on_triangle(p, positions[t[0]], positions[t[1]], positions[t[2]]);
  }

  // The tree's boxes, our triangles: CGAL's own queries test a triangle against a box or
  // project with its general constructions, several times slower than these traversals.
  //! The closest point of the input to p and its face, searched nearer boxes first; `hint`
  //! (a face near p: a neighbour's) bounds the search from the start.
  Vec3 closest(const Vec3& p, std::size_t& face, std::size_t hint) const;
  //! False when region_tree is built and no face of it is within r of p.
  bool region_face_within(const Vec3& p, double r) const;
  //! fn(face, distance) for every face within r of p, in the tree's order.
  template <class Fn>
  void for_each_face_within(const Vec3& p, double r, Fn&& fn) const;

  //! How well output face `face` agrees with the input: the best cosine between its normal
  //! and its corners' closest input faces' normals (closest(v)) or, when none agrees within
  //! kFoldDegrees, of the input faces within the face's longest edge of its centroid; -2 for
  //! a face without a normal. at(v): the corner positions to measure.
  template <class At, class Closest>
  double agreement(const Mesh& refined, FaceId face, const At& at, const Closest& closest) const;

  //! The largest normal change over the output's faces (degrees) and how many are over
  //! kFoldDegrees (PostPassReport::worst_normal_change_deg).
  struct Turn {
    double worst = 0;
    std::size_t over = 0;
  };
  template <class Closest>
  Turn measure_turn(const Mesh& refined, const Closest& closest) const;

  //! apply() without snapping: each new vertex pulled back within its bound in place, one
  //! closest face per vertex kept (for the normal change), the figures summed per chunk.
  PostPassReport apply_bound(Mesh& refined, const PostPassParams& params) const;
};

namespace {

double squared_distance_to_box(const Vec3& p, const CGAL::Bbox_3& box) {
  auto gap = [](double c, double lo, double hi) { return c < lo ? lo - c : c > hi ? c - hi : 0.0; };
  const double x = gap(p.x, box.xmin(), box.xmax()), y = gap(p.y, box.ymin(), box.ymax()),
               z = gap(p.z, box.zmin(), box.zmax());
  return x * x + y * y + z * z;
}

}  // namespace

Vec3 InputSurface::Impl::closest(const Vec3& p, std::size_t& face, std::size_t hint) const {
  struct Nearest {
    using Priority [[maybe_unused]] = double;  // read by CGAL's traversal_with_priority
    const Impl& m;
    Vec3 p, best;
    double best2 = INFINITY;
    std::size_t face = 0;
    bool go_further() const { return true; }
    void intersection(const K::Point_3&, const AabbPrimitive& primitive) {
      const std::size_t f = m.face_of(primitive.id());
      const Vec3 q = m.closest_on(f, p);
      const Vec3 d = q - p;
      if (const double d2 = dot(d, d); d2 < best2) {
        best2 = d2;
        best = q;
        face = f;
      }
    }
    bool do_intersect(const K::Point_3&, const TreeNode& node) const {
      return squared_distance_to_box(p, node.bbox()) < best2;
    }
    std::pair<bool, double> do_intersect_with_priority(const K::Point_3&,
                                                       const TreeNode& node) const {
      const double d2 = squared_distance_to_box(p, node.bbox());
      return {d2 < best2, -d2};
    }
  };
  Nearest search{*this, p, p};
  if (hint < faces.size()) {
    search.best = closest_on(hint, p);
    search.best2 = dot(search.best - p, search.best - p);
    search.face = hint;
  }
  if (search.best2 > 0) tree.traversal_with_priority(point3(p), search);
  face = search.face;
  return search.best;
}

template <class Fn>
void InputSurface::Impl::for_each_face_within(const Vec3& p, double r, Fn&& fn) const {
  struct Within {
    const Impl& m;
    Vec3 p;
    double r;
    Fn& fn;
    bool go_further() const { return true; }
    void intersection(const K::Point_3&, const AabbPrimitive& primitive) {
      const std::size_t f = m.face_of(primitive.id());
      const double d = distance(p, m.closest_on(f, p));
      if (d <= r) fn(f, d);
    }
    bool do_intersect(const K::Point_3&, const TreeNode& node) const {
      return squared_distance_to_box(p, node.bbox()) <= r * r;
    }
  };
  Within within{*this, p, r, fn};
  tree.traversal(point3(p), within);
}

bool InputSurface::Impl::region_face_within(const Vec3& p, double r) const {
  if (region_faces.empty()) return true;
  struct Any {
    const Impl& m;
    Vec3 p;
    double r;
    bool found = false;
    bool go_further() const { return !found; }
    void intersection(const K::Point_3&, const AabbPrimitive& primitive) {
      const auto& t =
          m.faces[m.region_faces[std::size_t(primitive.id() - m.region_triangles.begin())]];
      const Vec3 q =
          closest_point_on_triangle(p, m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]);
      found = found || distance(p, q) <= r;
    }
    bool do_intersect(const K::Point_3&, const TreeNode& node) const {
      return squared_distance_to_box(p, node.bbox()) <= r * r;
    }
  };
  Any any{*this, p, r};
  region_tree.traversal(point3(p), any);
  return any.found;
}

const double kCosTurn = std::cos(kFoldDegrees * std::numbers::pi / 180);

template <class At, class Closest>
double InputSurface::Impl::agreement(const Mesh& refined, FaceId face, const At& at,
                                     const Closest& closest_face) const {
  const auto vs = refined.face_vertices(face);
  const Vec3 a = at(vs[0]), b = at(vs[1]), c = at(vs[2]);
  const Vec3 n = cross(b - a, c - a);
  const double len = norm(n);
  double best = -2;
  if (!(len > 0)) return best;
  for (VertexId v : vs) {
    const Vec3& in = normals[closest_face(v)];
    if (in != Vec3{}) best = std::max(best, dot(n, in) / len);
  }
  if (best >= kCosTurn) return best;
  // Its corners' closest faces disagree (corners on a crease, or just past it once snapped,
  // are closest to the other side's chords): any input face within the face's own size of
  // its centroid that it agrees with will do; a fold agrees with none.
  const Vec3 centre = (a + b + c) * (1.0 / 3);
  std::size_t near_face = 0;
  const double r = distance(centre, closest(centre, near_face, closest_face(vs[0]))) +
                   std::max({distance(a, b), distance(b, c), distance(c, a)});
  for_each_face_within(centre, r, [&](std::size_t f, double) {
    if (normals[f] != Vec3{}) best = std::max(best, dot(n, normals[f]) / len);
  });
  return best;
}

template <class Closest>
InputSurface::Impl::Turn InputSurface::Impl::measure_turn(const Mesh& refined,
                                                          const Closest& closest_face) const {
  const auto& positions = refined.positions();
  auto at = [&](VertexId v) { return positions[v.idx]; };
  Turn turn;
  std::mutex turn_mutex;
  parallel_for_each_range(refined.num_faces(), [&](std::size_t begin, std::size_t end) {
    Turn acc;
    for (std::size_t g = begin; g != end; ++g) {
      double best = agreement(refined, FaceId(static_cast<std::uint32_t>(g)), at, closest_face);
      if (best < -1.5) continue;  // degenerate, or no corner's closest face has a normal
      best = std::clamp(best, -1.0, 1.0);
      acc.worst = std::max(acc.worst, std::acos(best) * 180 / std::numbers::pi);
      acc.over += best < kCosTurn;
    }
    const std::lock_guard lock(turn_mutex);
    turn.worst = std::max(turn.worst, acc.worst);
    turn.over += acc.over;
  });
  return turn;
}

namespace {

// Adds the counts and keeps the largest figures of `part` (a chunk's, or one vertex's).
void add_figures(PostPassReport& total, const PostPassReport& part) {
  total.vertices_checked += part.vertices_checked;
  total.snapped += part.snapped;
  total.snapped_to_curve += part.snapped_to_curve;
  total.snap_refused += part.snap_refused;
  total.snaps_reverted += part.snaps_reverted;
  total.pulled_back += part.pulled_back;
  total.past_bound += part.past_bound;
  total.max_snap_move = std::max(total.max_snap_move, part.max_snap_move);
  total.max_pull_back = std::max(total.max_pull_back, part.max_pull_back);
  total.max_distance_before = std::max(total.max_distance_before, part.max_distance_before);
  total.max_distance = std::max(total.max_distance, part.max_distance);
  total.max_bound = std::max(total.max_bound, part.max_bound);
}

// The report's last figures: the normal change, the bound, the time.
PostPassReport finish_report(PostPassReport report, double worst_normal_change_deg,
                             std::size_t faces_turned, const PostPassParams& params,
                             std::chrono::steady_clock::time_point start) {
  const bool user_bound = params.max_deviation && *params.max_deviation > 0;
  report.worst_normal_change_deg = worst_normal_change_deg;
  report.faces_turned_over_60_deg = faces_turned;
  report.default_bound = !params.max_deviation;
  if (user_bound) report.max_bound = *params.max_deviation;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace

PostPassReport InputSurface::Impl::apply_bound(Mesh& refined, const PostPassParams& params) const {
  const auto start = std::chrono::steady_clock::now();
  PostPassReport report;
  const std::size_t nv = refined.num_vertices();
  const bool user_bound = params.max_deviation && *params.max_deviation > 0;
  const bool bound_on = !params.max_deviation || *params.max_deviation > 0;
  const auto out_positions = refined.positions();
  std::vector<Nearest> nearest(nv);
  std::vector<std::uint8_t> is_new(nv, 0);
  auto locate = [&](const Vec3& p, std::uint32_t hint) {
    std::size_t face = 0;
    const Vec3 q = closest(p, face, hint);
    return Nearest{q, static_cast<std::uint32_t>(face), distance(p, q)};
  };
  parallel_for_each_range(nv, [&](std::size_t begin, std::size_t end) {
    // Vertices near in index are near in space (a level's new vertices follow its edges).
    std::uint32_t hint = UINT32_MAX;
    for (std::size_t i = begin; i != end; ++i) {
      const Vec3& p = out_positions[i];
      nearest[i] = locate(p, hint);
      hint = nearest[i].face;
      const auto& t = faces[hint];
      is_new[i] = !(p == positions[t[0]] || p == positions[t[1]] || p == positions[t[2]]);
    }
  });
  for (std::size_t i = 0; i < nv; ++i) {
    if (!is_new[i]) continue;
    ++report.vertices_checked;
    report.max_distance_before = std::max(report.max_distance_before, nearest[i].distance);
  }
  auto bound_of = [&](const Nearest& n) {
    return user_bound ? *params.max_deviation : bound[n.face];
  };
  if (bound_on) {
    const SmoothPullReport pull =
        smooth_pull(refined, is_new, nearest, bound_of, locate, diagonal, params.pull);
    report.pulled_back = pull.moved;
    report.max_pull_back = pull.max_move;
    report.past_bound = pull.violators;
    report.pulled_alone = pull.pulled_alone;
  }
  for (std::size_t i = 0; i < nv; ++i) {
    if (!is_new[i]) continue;
    report.max_distance = std::max(report.max_distance, nearest[i].distance);
    if (bound_on) report.max_bound = std::max(report.max_bound, bound_of(nearest[i]));
  }
  const Turn turn = measure_turn(refined, [&](VertexId v) { return nearest[v.idx].face; });
  return finish_report(report, turn.worst, turn.over, params, start);
}

InputSurface::InputSurface(const Mesh& mesh, const Features& features, const RegionMap* regions)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.positions.assign(mesh.positions().begin(), mesh.positions().end());
  const std::size_t nf = mesh.num_faces();
  m.faces.resize(nf);
  m.across_crease.assign(nf, {-1, -1, -1});
  m.normals.resize(nf);
  m.triangles.reserve(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    const auto vs = mesh.face_vertices(FaceId(static_cast<std::uint32_t>(f)));
    m.faces[f] = {vs[0].idx, vs[1].idx, vs[2].idx};
    const Vec3 &a = mesh.position(vs[0]), &b = mesh.position(vs[1]), &c = mesh.position(vs[2]);
    m.triangles.emplace_back(point3(a), point3(b), point3(c));
    const Vec3 n = cross(b - a, c - a);
    m.normals[f] = norm(n) > 0 ? normalized(n) : Vec3{};
    for (int k = 0; k < 3; ++k) {
      const HalfedgeId h = Mesh::halfedge(FaceId(static_cast<std::uint32_t>(f)), k);
      if (!mesh.is_boundary(h) && features.is_sharp(mesh.edge(h)))
        m.across_crease[f][std::size_t(k)] =
            static_cast<std::int32_t>(Mesh::face(mesh.twin(h)).idx);
    }
  }
  Vec3 lo, hi;
  if (!m.positions.empty()) lo = hi = m.positions[0];
  for (const Vec3& p : m.positions) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  m.diagonal = distance(lo, hi);
  m.tolerance = regions ? regions->tolerance : 1e-6 * m.diagonal;
  if (regions) {
    m.face_region = regions->face_region;
    m.regions = regions->regions;
  }
  // The default bound: the input's own chordal error (at least 1e-12 of the diagonal, for
  // rounding: a flat face's vertices are pulled onto it). On a recognised region the primitive
  // is the surface the face was cut from: the bound is the farthest the primitive is from the
  // face (sampled at the centroid, the edge midpoints and quarter points) plus its region's
  // largest vertex residual (an exact plane's faces: 1e-12 of the diagonal, so a vertex
  // pulled back onto one is on its plane). detect_regions only recognises a
  // primitive within twice the chordal estimate of every face's chords.
  m.bound = chordal_bounds(mesh, features, 1e-12 * m.diagonal);
  for (std::size_t f = 0; f < nf && !m.face_region.empty(); ++f) {
    if (m.face_region[f] < 0) continue;
    const Primitive& prim = m.regions[std::size_t(m.face_region[f])].primitive;
    const auto& t = m.faces[f];
    const Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    double gap = prim.distance((a + b + c) * (1.0 / 3));
    for (const auto& [u, w] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}})
      for (double s : {0.25, 0.5, 0.75}) gap = std::max(gap, prim.distance(u + (w - u) * s));
    m.bound[f] = gap + m.regions[std::size_t(m.face_region[f])].max_residual + 1e-12 * m.diagonal;
  }
  m.tree.insert(m.triangles.begin(), m.triangles.end());
  m.tree.build();
  const auto in_regions = static_cast<std::size_t>(std::count_if(
      m.face_region.begin(), m.face_region.end(), [](std::int32_t r) { return r >= 0; }));
  if (in_regions > 0 && 2 * in_regions < nf) {
    m.region_faces.reserve(in_regions);
    m.region_triangles.reserve(in_regions);
    for (std::size_t f = 0; f < nf; ++f)
      if (m.face_region[f] >= 0) {
        m.region_faces.push_back(static_cast<std::uint32_t>(f));
        m.region_triangles.push_back(m.triangles[f]);
      }
    m.region_tree.insert(m.region_triangles.begin(), m.region_triangles.end());
    m.region_tree.build();
  }
}

InputSurface::~InputSurface() = default;

std::uint64_t InputSurface::predict_bytes(std::uint64_t input_vertices, std::uint64_t input_faces,
                                          bool regions) {
  // Per vertex: positions (24). Per face: corner indices (12), normal (24), bound (8), region
  // (4), crease links (12), the CGAL triangle (72), the tree's primitive (8) and node (64 per
  // face: n - 1 nodes of a box and two pointers; no search tree: the queries are our own
  // traversals); vectors grown by doubling may hold up to twice their size.
  const std::uint64_t held = 2 * (24 * input_vertices) +
                             2 * (12 + 24 + 8 + 4 + 12 + 72) * input_faces + (8 + 64) * input_faces;
  // detect_regions, before the surface exists: components, patches (a copy of every vertex per
  // face it touches, normals and centroids), stamps, bounds and face flags.
  const std::uint64_t detect =
      regions ? (3 * 24 + 2 * 24 + 8 + 4 + 4 + 16 + 16) * 2 * input_faces + 8 * input_vertices : 0;
  // The regions' own tree, when they hold under half of the faces: their triangles and face
  // ids (reserved to size), the tree's primitives and nodes.
  const std::uint64_t region_tree = regions ? (72 + 4 + 8 + 64) * input_faces / 2 : 0;
  return held + detect + region_tree + (std::uint64_t{1} << 14);
}

std::uint64_t InputSurface::predict_apply_bytes(std::uint64_t output_vertices) {
  // One outcome per vertex; the list of snaps to take back (at most three corners of every
  // face, about two faces per vertex, in a vector that may double); where each vertex is and
  // whether smooth_pull may move it, and smooth_pull's own.
  return (sizeof(Outcome) + 2 * 3 * 2 * sizeof(std::uint32_t) + sizeof(Nearest) + 1) *
             output_vertices +
         smooth_pull_bytes(output_vertices) + (std::uint64_t{1} << 20);
}

double InputSurface::default_bound(std::size_t face) const {
  return impl_->bound[face];
}

PostPassReport InputSurface::apply(Mesh& refined, const PostPassParams& params) const {
  const auto start = std::chrono::steady_clock::now();
  const Impl& m = *impl_;
  PostPassReport report;
  const std::size_t nv = refined.num_vertices();
  if (m.faces.empty() || nv == 0) return report;
  if (!params.snap || m.regions.empty()) return m.apply_bound(refined, params);
  const bool user_bound = params.max_deviation && *params.max_deviation > 0;
  const bool bound_on = !params.max_deviation || *params.max_deviation > 0;
  const double curve_tol = 1e-12 * m.diagonal;
  std::vector<Outcome> out(nv);

  auto closest = [&](const Vec3& p, std::size_t& face, std::size_t hint = SIZE_MAX) {
    return m.closest(p, face, hint);
  };

  // The longest edge of the output bounds every vertex's search radius below: with it a
  // vertex far from every region is refused before its own edges are walked.
  double longest_edge = 0;
  if (!m.region_faces.empty())
    for (std::uint32_t e = 0; e < refined.num_edges(); ++e) {
      const HalfedgeId h = refined.halfedge(EdgeId(e));
      longest_edge = std::max(longest_edge, distance(refined.position(refined.from(h)),
                                                     refined.position(refined.to(h))));
    }

  auto snap_target = [&](VertexId v, const Vec3& p, double d, Outcome& o) -> std::optional<Vec3> {
    if (!m.region_face_within(p, d + 0.25 * longest_edge + 1e-9 * m.diagonal)) return std::nullopt;
    // Input faces near p (a quarter of its longest edge farther than the nearest: a vertex
    // of a crease may lie on one side's face, inside the other side's chord), each incident
    // refined face voting for the one whose normal it agrees with best.
    double longest = 0;
    const Vec3 self = refined.position(v);
    for_each_outgoing(refined, v, [&](HalfedgeId h) {
      longest = std::max(longest, distance(self, refined.position(refined.to(h))));
    });
    const double r = d + 0.25 * longest + 1e-9 * m.diagonal;
    if (!m.region_face_within(p, r)) return std::nullopt;  // no region to vote for
    std::vector<std::size_t> near;
    std::vector<double> near_distance;
    m.for_each_face_within(p, r, [&](std::size_t f, double dist) {
      near.push_back(f);
      near_distance.push_back(dist);
    });
    if (near.empty()) return std::nullopt;
    std::array<std::int32_t, 8> region{};
    std::array<int, 8> votes{};
    int kinds = 0;
    for_each_outgoing(refined, v, [&](HalfedgeId h) {
      const Vec3 n = refined.face_normal(Mesh::face(h));
      const double len = norm(n);
      if (!(len > 0)) return;
      // The best agreeing normal; among faces that agree as well (parallel planes, an
      // embossed letter's top), the nearest.
      double best = -2;
      for (std::size_t f : near) best = std::max(best, dot(n, m.normals[f]) / len);
      std::size_t pick = near[0];
      double nearest = INFINITY;
      for (std::size_t j = 0; j < near.size(); ++j) {
        const std::size_t f = near[j];
        if (dot(n, m.normals[f]) / len < best - 1e-6) continue;
        if (near_distance[j] < nearest) {
          nearest = near_distance[j];
          pick = f;
        }
      }
      const std::int32_t id = m.face_region[pick];
      for (int i = 0; i < kinds; ++i)
        if (region[std::size_t(i)] == id) {
          ++votes[std::size_t(i)];
          return;
        }
      if (kinds < 8) {
        region[std::size_t(kinds)] = id;
        votes[std::size_t(kinds)] = 1;
        ++kinds;
      }
    });
    if (params.snap_inside_regions_only)
      for (int i = 0; i < kinds; ++i)
        if (region[std::size_t(i)] < 0) return std::nullopt;
    // Recognised regions among the votes, most votes first.
    std::vector<std::pair<int, std::int32_t>> found;
    for (int i = 0; i < kinds; ++i)
      if (region[std::size_t(i)] >= 0)
        found.emplace_back(-votes[std::size_t(i)], region[std::size_t(i)]);
    if (found.empty()) return std::nullopt;
    std::sort(found.begin(), found.end());
    // The bound of the voted regions' faces nearby (a rim vertex is nearest to the cap, whose
    // bound is flat, but lies on the side's circle, within the side's chordal error).
    for (std::size_t f : near)
      for (const auto& e : found)
        if (m.face_region[f] == e.second) o.allowance = std::max(o.allowance, m.bound[f]);
    const double reach = 0.5 * longest;
    auto accept = [&](const std::optional<Vec3>& t) {
      return t && is_finite(*t) && distance(*t, p) <= reach;
    };
    // A vertex of a crease lies on it up to the scheme's chordal error; a vertex beside the
    // crease (a thin strip along a chamfer or a letter's wall, whose faces' longest edges run
    // along the crease) may be within 15% of its longest edge of it too, and on the curve it
    // lands on its neighbour there (xyz cube: two vertices at the same point, their faces
    // degenerate). Such a snap is marked: if a face of it ends turned over, it is taken back.
    auto accept_curve = [&](const std::optional<Vec3>& t) {
      if (!accept(t)) return false;
      const Vec3 move = *t - self;
      const double len = norm(move);
      o.curve_land = 0;
      for_each_outgoing(refined, v, [&](HalfedgeId h) {
        const Vec3& u = refined.position(refined.to(h));
        const double ahead = len > 0 ? dot(u - self, move) / len : 0;
        if (ahead > 0 && len > kCurveSnapLand * ahead &&
            distance(*t, u) < kCurveSnapLand * distance(self, u))
          o.curve_land = 1;
      });
      return true;
    };
    // Only a crease vertex of the refined mesh goes onto a curve (when its features are
    // known): a vertex off the creases stays on its own region's surface.
    const bool on_crease =
        !params.refined_features || params.refined_features->kind(v) >= VertexKind::Crease;
    // A vertex within 15% of its longest edge of an input crease between two recognised
    // regions: a crease vertex is a vertex of that crease, whatever its faces say (a folded
    // face may vote for the wrong side); a vertex off the creases goes onto it only when it
    // lies beyond the other side's surface (a cap vertex of a fan sliver just outside the
    // rim: on its plane it would still be outside the part, and its sliver, between two rim
    // vertices, would turn over once they are on the rim).
    double crease_gap = 0.15 * longest;
    std::int32_t crease_a = -1, crease_b = -1;
    std::size_t crease_face_a = 0, crease_face_b = 0;
    double crease_allowance = 0;
    for (std::size_t f : near)
      for (int k = 0; k < 3; ++k) {
        const std::int32_t g = m.across_crease[f][std::size_t(k)];
        if (g < 0) continue;
        const std::int32_t ra = m.face_region[f], rb = m.face_region[std::size_t(g)];
        if (ra < 0 || rb < 0 || ra == rb) continue;
        const Vec3& e0 = m.positions[m.faces[f][std::size_t(k)]];
        const Vec3& e1 = m.positions[m.faces[f][std::size_t((k + 1) % 3)]];
        const double gap = point_triangle_distance(p, e0, e1, e1);
        if (gap < crease_gap) {
          crease_gap = gap;
          crease_a = ra;
          crease_b = rb;
          crease_face_a = f;
          crease_face_b = std::size_t(g);
          crease_allowance = std::max(m.bound[f], m.bound[std::size_t(g)]);
        }
      }
    auto beyond = [&](std::int32_t region, std::size_t face) {
      const std::optional<Vec3> t = m.regions[std::size_t(region)].primitive.project(p);
      return t && dot(p - *t, m.normals[face]) > 0;
    };
    if (crease_a >= 0 && !on_crease) {
      // Beyond the side it did not vote for.
      const bool own_a = found.front().second == crease_a, own_b = found.front().second == crease_b;
      if (!((own_a && beyond(crease_b, crease_face_b)) ||
            (own_b && beyond(crease_a, crease_face_a))))
        crease_a = -1;
    }
    if (crease_a >= 0) {
      const std::optional<Vec3> t =
          project_to_intersection(m.regions[std::size_t(crease_a)].primitive,
                                  m.regions[std::size_t(crease_b)].primitive, p, curve_tol);
      if (accept_curve(t)) {
        o.to_curve = 1;
        o.allowance = std::max(o.allowance, crease_allowance);
        o.region = {crease_a, crease_b};
        return t;
      }
    }
    std::vector<std::pair<std::optional<Vec3>, std::int32_t>> tries;
    if (found.size() == 2) {
      const Primitive& a = m.regions[std::size_t(found[0].second)].primitive;
      const Primitive& b = m.regions[std::size_t(found[1].second)].primitive;
      if (on_crease) {
        const std::optional<Vec3> t = project_to_intersection(a, b, p, curve_tol);
        if (accept_curve(t)) {
          o.to_curve = 1;
          o.region = {found[0].second, found[1].second};
          return t;
        }
      }
      // Off a crease, or the curve is out of reach: keep planes planar; else the region
      // most of its faces voted for (a tangent join).
      if (a.type == PrimitiveType::Plane) tries.emplace_back(a.project(p), found[0].second);
      if (b.type == PrimitiveType::Plane) tries.emplace_back(b.project(p), found[1].second);
      if (!on_crease && tries.empty()) tries.emplace_back(a.project(p), found[0].second);
    } else if (found.size() == 1) {
      tries.emplace_back(m.regions[std::size_t(found[0].second)].primitive.project(p),
                         found[0].second);
    }
    for (const auto& [t, id] : tries)
      if (accept(t)) {
        o.region = {id, -1};
        return t;
      }
    o.refused = 1;
    return std::nullopt;
  };

  parallel_for_each_range(nv, [&](std::size_t begin, std::size_t end) {
    // Vertices near in index are near in space (a level's new vertices follow its edges).
    std::size_t previous_face = SIZE_MAX;
    for (std::size_t i = begin; i != end; ++i) {
      Outcome& o = out[i];
      const VertexId v(static_cast<std::uint32_t>(i));
      Vec3 p = refined.position(v);
      o.position = p;
      std::size_t face = 0;
      Vec3 q = closest(p, face, previous_face);
      previous_face = face;
      const auto& t = m.faces[face];
      o.face = static_cast<std::uint32_t>(face);
      if (p == m.positions[t[0]] || p == m.positions[t[1]] || p == m.positions[t[2]]) continue;
      o.is_new = 1;
      double d = distance(p, q);
      o.distance_before = d;
      o.original = o.fallback = p;
      o.fallback_face = static_cast<std::uint32_t>(face);
      o.fallback_distance = d;
      if (bound_on) {
        const double bound = user_bound ? *params.max_deviation : m.bound[face];
        o.fallback_bound = bound;
        if (d > bound) {
          std::size_t back_face = face;
          // Just inside the bound (by 1e-14 of the diagonal, far above the coordinates'
          // rounding): a snap taken back lands here and must still meet it.
          const double inside = just_inside(bound, m.diagonal);
          o.fallback = q + (p - q) * (inside / d);
          o.fallback_distance = distance(o.fallback, closest(o.fallback, back_face, face));
          o.fallback_face = static_cast<std::uint32_t>(back_face);
        }
      }
      {
        std::optional<Vec3> target = snap_target(v, p, d, o);
        if (!target && o.refused && d > 0) {
          // The scheme put the vertex far off (lsf on a zipped side: 2 mm): its region is
          // decided, and it is projected, from its closest point on the input instead.
          Outcome retry = o;
          retry.refused = 0;
          retry.allowance = 0;
          retry.to_curve = 0;
          target = snap_target(v, q, 0, retry);
          if (target) o = retry;
        }
        if (target) {
          // A snap that takes the vertex farther from the input than the input's chordal
          // error there is a wrong region: refused (a snapped vertex is never pulled back,
          // so the bound it is held to is the one it must already meet).
          std::size_t to_face = 0;
          const Vec3 to_q = closest(*target, to_face, face);
          const double to_d = distance(*target, to_q);
          if (to_d <= std::max(m.bound[to_face], o.allowance)) {
            o.snapped = 1;
            o.snap_move = distance(*target, p);
            p = *target;
            q = to_q;
            d = to_d;
            face = to_face;
          } else {
            o.refused = 1;
          }
        }
      }
      if (bound_on) {
        const double bound = user_bound  ? *params.max_deviation
                             : o.snapped ? std::max(m.bound[face], o.allowance)
                                         : m.bound[face];
        o.bound = bound;
        if (d > bound) {
          const Vec3 back = q + (p - q) * (just_inside(bound, m.diagonal) / d);
          o.pulled = 1;
          o.pull_back = distance(back, p);
          p = back;
          d = distance(p, closest(p, face, face));
        }
      }
      o.distance_after = d;
      o.position = p;
      o.face = static_cast<std::uint32_t>(face);
    }
  });

  BigVector<Vec3>& positions = refined.mutable_positions();
  for (std::size_t i = 0; i < nv; ++i)
    if (out[i].is_new) positions[i] = out[i].position;

  // A snap must not turn a face over: where a face ends more than kFoldDegrees from the input
  // (as measured below) and was not before the pass, its corners snapped onto one primitive
  // go back to their fallback (pulled back within the default bound only). Up to three rounds.
  auto closest_of = [&](VertexId v) { return out[v.idx].face; };
  auto agreement = [&](FaceId face, bool before) {
    auto at = [&](VertexId v) {
      const Outcome& o = out[v.idx];
      return before && o.is_new ? o.original : positions[v.idx];
    };
    return m.agreement(refined, face, at, closest_of);
  };
  // Above float32 rounding of the coordinates (an STL stores them so): 1e-6 of the diagonal.
  const double collapse = 1e-6 * m.diagonal;
  auto shortest_edge = [&](FaceId face, bool before) {
    const auto vs = refined.face_vertices(face);
    auto at = [&](VertexId v) {
      const Outcome& o = out[v.idx];
      return before && o.is_new ? o.original : positions[v.idx];
    };
    const Vec3 a = at(vs[0]), b = at(vs[1]), c = at(vs[2]);
    return std::min({distance(a, b), distance(b, c), distance(c, a)});
  };
  // The primitives' own normals, oriented like the input faces of their regions (a
  // primitive's normal_at points away from its axis; a bore's faces point towards it).
  std::vector<double> orientation(m.regions.size(), 0.0);
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const std::int32_t r = m.face_region[f];
    if (r < 0) continue;
    const auto& t = m.faces[f];
    const Vec3 c = (m.positions[t[0]] + m.positions[t[1]] + m.positions[t[2]]) * (1.0 / 3);
    orientation[std::size_t(r)] +=
        dot(m.normals[f], m.regions[std::size_t(r)].primitive.normal_at(c));
  }
  // Whether a face is more than kFoldDegrees from every normal of its own surface: the
  // regions its snapped corners share (a cap sliver's rim corner is on the cap and the side,
  // its others on the cap alone: the cap), all of theirs when they share none. Measured
  // against the input's faces instead (agreement), a cap sliver tilted 68 degrees next to a
  // frustum's rim agrees with the side wall and was kept. (The region of the input face
  // nearest to the face's centroid was tried instead: more faces turned, more withdrawals.)
  auto turned_from_own = [&](FaceId face, bool before) {
    const auto vs = refined.face_vertices(face);
    std::array<std::int32_t, 6> own{};
    std::size_t n_own = 0;
    bool first = true;
    for (VertexId v : vs) {
      const Outcome& o = out[v.idx];
      if (!o.snapped) continue;
      if (first) {
        for (std::int32_t r : o.region)
          if (r >= 0) own[n_own++] = r;
        first = false;
        continue;
      }
      std::size_t kept = 0;
      for (std::size_t i = 0; i < n_own; ++i)
        if (own[i] == o.region[0] || own[i] == o.region[1]) own[kept++] = own[i];
      if (kept > 0) {
        n_own = kept;
      } else {
        // No shared region: every region of the corners.
        for (std::int32_t r : o.region)
          if (r >= 0 && n_own < own.size()) own[n_own++] = r;
      }
    }
    if (n_own == 0) return false;
    auto at = [&](VertexId v) {
      const Outcome& o = out[v.idx];
      return before && o.is_new ? o.original : positions[v.idx];
    };
    const Vec3 a = at(vs[0]), b = at(vs[1]), c = at(vs[2]);
    const Vec3 n = normalized(cross(b - a, c - a));
    if (n == Vec3{}) return false;  // collapsed: see below
    const Vec3 centre = (a + b + c) * (1.0 / 3);
    for (std::size_t i = 0; i < n_own; ++i) {
      const std::size_t r = std::size_t(own[i]);
      const Vec3 g = m.regions[r].primitive.normal_at(centre);
      if (g == Vec3{} || orientation[r] == 0) return false;  // no normal here: cannot tell
      if (dot(n, g) * (orientation[r] > 0 ? 1 : -1) >= kCosTurn) return false;
    }
    return true;
  };
  for (int round = 0; round < 3; ++round) {
    std::vector<std::uint32_t> revert;
    for (std::size_t g = 0; g < refined.num_faces(); ++g) {
      const FaceId face(static_cast<std::uint32_t>(g));
      // Only snapped corners are taken back: a face without one is left as it is.
      bool any_snapped = false;
      for (VertexId v : refined.face_vertices(face))
        any_snapped = any_snapped || out[v.idx].snapped;
      if (!any_snapped) continue;
      // A face the pass collapsed (two corners at one point: no normal, so agreement() and
      // the report do not see it) is treated as turned.
      const bool collapsed =
          shortest_edge(face, false) < collapse && shortest_edge(face, true) >= collapse;
      // Turned from its own primitive's normal by the snaps (the scheme's face was within
      // kFoldDegrees of its surface): its snapped corners go back, a curve's too when it is
      // the face's only corner on the curve (a cap sliver reversed by its rim corner's snap).
      // With two or more on the curve the face runs along it: only its corners off the curve
      // go back (the rim stays on its circle); with all three on it, see below.
      std::size_t on_curve = 0;
      for (VertexId v : refined.face_vertices(face))
        on_curve += !out[v.idx].is_new || out[v.idx].to_curve;
      if (!collapsed && on_curve < 3 && turned_from_own(face, false) &&
          !turned_from_own(face, true)) {
        std::size_t curve_snaps = 0;
        for (VertexId v : refined.face_vertices(face)) curve_snaps += out[v.idx].to_curve;
        for (VertexId v : refined.face_vertices(face))
          if (out[v.idx].snapped && (curve_snaps < 2 || !out[v.idx].to_curve))
            revert.push_back(v.idx);
        continue;
      }
      const double after = agreement(face, false);
      if (!collapsed) {
        if (after < -1.5 || after >= kCosTurn) continue;
        if (agreement(face, true) < kCosTurn) continue;  // the scheme's, not the pass's
      }
      // A vertex snapped onto a crease curve stays: a face with its three corners on the
      // curve (butterfly makes them along zipped rims) lies across the curve's chord, and no
      // position of them both on the curve and unfolded exists.
      // Unless it landed on its neighbour (see kCurveSnapLand): it was beside the crease.
      for (VertexId v : refined.face_vertices(face))
        if (out[v.idx].snapped && (!out[v.idx].to_curve || out[v.idx].curve_land || collapsed))
          revert.push_back(v.idx);
    }
    if (revert.empty()) break;
    for (std::uint32_t i : revert) {
      Outcome& o = out[i];
      if (!o.snapped) continue;
      o.snapped = o.to_curve = 0;
      o.region = {-1, -1};
      o.reverted = 1;
      o.position = positions[i] = o.fallback;
      o.face = o.fallback_face;
      o.distance_after = o.fallback_distance;
      o.bound = o.fallback_bound;
      o.pulled = o.fallback != o.original;
      o.pull_back = distance(o.fallback, o.original);
      o.snap_move = 0;
    }
  }

  for (std::size_t i = 0; i < nv; ++i) {
    const Outcome& o = out[i];
    if (!o.is_new) continue;
    PostPassReport one;
    one.vertices_checked = 1;
    one.snapped = o.snapped && !o.to_curve;
    one.snapped_to_curve = o.to_curve;
    one.snap_refused = o.refused;
    one.snaps_reverted = o.reverted;
    one.pulled_back = o.pulled;
    one.max_snap_move = o.snap_move;
    one.max_pull_back = o.pull_back;
    one.max_distance_before = o.distance_before;
    one.max_distance = o.distance_after;
    one.max_bound = o.bound;
    add_figures(report, one);
  }
  const Impl::Turn turn = m.measure_turn(refined, closest_of);
  return finish_report(report, turn.worst, turn.over, params, start);
}

PostPassReport InputSurface::apply_guarded(Mesh& refined, const PostPassParams& params) const {
  if (!params.snap) return apply(refined, params);
  BigVector<Vec3> refined_positions = refined.mutable_positions();
  PostPassReport snapped = apply(refined, params);
  if (snapped.faces_turned_over_60_deg == 0) return snapped;
  BigVector<Vec3> snapped_positions = refined.mutable_positions();
  refined.mutable_positions() = std::move(refined_positions);
  PostPassParams bound_only_params = params;
  bound_only_params.snap = false;
  PostPassReport bound_only = apply(refined, bound_only_params);
  if (bound_only.faces_turned_over_60_deg < snapped.faces_turned_over_60_deg) {
    bound_only.withdrawn_turned_faces = snapped.faces_turned_over_60_deg;
    bound_only.seconds += snapped.seconds;
    return bound_only;
  }
  refined.mutable_positions() = std::move(snapped_positions);
  snapped.seconds += bound_only.seconds;
  return snapped;
}

}  // namespace stlrefine::primitives
