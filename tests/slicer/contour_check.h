// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// An independent check of a slicer run on a closed mesh: no open polylines; every loop has
// 3+ points and no zero-length edge; outer loops counter-clockwise and holes clockwise by a
// recomputed shoelace area; depth, kind and parent equal to a containment count done here
// (exact orientation predicates, every loop against every other); parents before children;
// loops of one layer never cross; every loop edge is one face's own segment, run in the
// face's direction (so the chain closed through real neighbours and the loop was not turned
// against the mesh); and each layer's area equals the Green sum of all its faces' segments.
// Each failure is a located Finding. On a self-intersecting surface some of these cannot
// hold near the intersections (loops cross, and the nesting of crossing loops has no single
// answer; a fold of the surface inside the part gives a loop whose winding disagrees with
// its nesting): self_intersection_boxes() and explained_by() tell those apart from slicer
// faults.
// Header-only and gtest-free: used by tests/slicer and by bench/slicer's
// stlrefine_contour_check (the large meshes). Needs CGAL.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <sstream>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "core/mesh/mesh.h"
#include "slicer/slice.h"

namespace stlrefine::test {

//! Where a check failed: the plane and the x-y box of what failed (a loop, or the two edges
//! that cross), so a caller can tell whether the input itself is at fault there.
struct Finding {
  enum Kind { Crossing, AgainstMesh, Other } kind = Other;
  double z = 0, x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::string what;
};

struct ContourCheck {
  std::size_t layers = 0, empty_layers = 0, loops = 0, outer = 0, holes = 0;
  std::uint64_t points = 0;
  std::size_t open = 0;               //!< open polylines (must be 0 on a closed mesh)
  std::size_t short_loops = 0;        //!< fewer than 3 points or a zero-length edge
  std::size_t wrong_sign = 0;         //!< outer not ccw or hole not cw (recomputed area)
  std::size_t wrong_nesting = 0;      //!< depth, kind or parent differ from the containment count
  std::size_t ambiguous_nesting = 0;  //!< the same, among loops that cross (no single answer)
  std::size_t unprobed = 0;           //!< loops whose every point lies on another loop
  std::size_t unmatched = 0;          //!< loop edges that are no face's segment (broken chaining)
  std::size_t against_mesh = 0;       //!< loops running against their faces' orientation
  std::size_t crossing_layers = 0;    //!< layers where edges of its loops cross
  std::size_t area_mismatch_layers = 0;      //!< layer area != Green sum of the mesh's segments
  std::size_t reversed = 0, degenerate = 0;  //!< the slicer's own counts, for the report
  std::vector<Finding> findings;             //!< every failure, located
  std::string first_problem;

  //! Closed, oriented, nested and non-crossing everywhere.
  bool ok() const { return findings.empty(); }
  //! Only findings of the two kinds a self-intersecting input causes (loops crossing, loops
  //! whose faces' orientation disagrees with their nesting), and nothing else.
  bool only_crossings_and_against_mesh() const {
    return open == 0 && short_loops == 0 && wrong_sign == 0 && wrong_nesting == 0 &&
           unprobed == 0 && unmatched == 0;
  }
};

class ContourChecker {
 public:
  //! `heights` are the run's planes in ascending order (slicer::plan_layers).
  ContourChecker(const Mesh& mesh, std::vector<double> heights)
      : corners_(mesh.corner_vertices()), pos_(mesh.positions()), heights_(std::move(heights)) {
    bucket_faces(mesh.num_faces());
  }

  //! Checks one layer; call for every layer of the run (any order, not concurrently).
  void add(const slicer::Layer& layer) {
    ++c_.layers;
    c_.open += layer.open.size();
    for (const auto& o : layer.open) {
      Box b = box_of(o.points);
      fail(layer, Finding::Other, b, "open polyline");
    }
    c_.reversed += layer.reversed_loops;
    c_.degenerate += layer.degenerate_loops;
    if (layer.loops.empty()) ++c_.empty_layers;
    const std::size_t n = layer.loops.size();
    c_.loops += n;
    std::vector<double> area(n);
    std::vector<Box> box(n);
    for (std::size_t i = 0; i < n; ++i) {
      const slicer::Loop& loop = layer.loops[i];
      c_.points += loop.points.size();
      ++(loop.kind == slicer::LoopKind::Outer ? c_.outer : c_.holes);
      area[i] = shoelace(loop.points);
      box[i] = box_of(loop.points);
      if (loop.points.size() < 3 || has_zero_edge(loop.points)) {
        ++c_.short_loops;
        fail(layer, Finding::Other, box[i],
             "loop " + std::to_string(i) + " has < 3 points or a zero-length edge");
      }
      if ((loop.kind == slicer::LoopKind::Outer) != (area[i] > 0)) {
        ++c_.wrong_sign;
        fail(layer, Finding::Other, box[i],
             "loop " + std::to_string(i) + " (" + slicer::to_string(loop.kind) +
                 ") has signed area " + num(area[i]));
      }
    }
    const std::vector<bool> crosses = check_crossings(layer);
    check_nesting(layer, area, box, crosses);
    check_against_mesh(layer, area, box);
  }

  const ContourCheck& result() const { return c_; }

 private:
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using P2 = K::Point_2;
  struct Box {
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    void add(const slicer::Point2& p) {
      x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x),
      y1 = std::max(y1, p.y);
    }
    bool has(const slicer::Point2& p) const {
      return x0 <= p.x && p.x <= x1 && y0 <= p.y && p.y <= y1;
    }
  };
  struct Segment {
    slicer::Point2 in, out;
  };

  static std::string num(double x) {
    std::ostringstream s;
    s.precision(17);
    s << x;
    return s.str();
  }

  static Box box_of(const std::vector<slicer::Point2>& points) {
    Box b;
    for (const auto& p : points) b.add(p);
    return b;
  }

  void fail(const slicer::Layer& layer, Finding::Kind kind, const Box& b, const std::string& what) {
    const std::string where =
        "layer " + std::to_string(layer.index) + " (z " + num(layer.z) + "): ";
    if (c_.first_problem.empty()) c_.first_problem = where + what;
    c_.findings.push_back({kind, layer.z, b.x0, b.y0, b.x1, b.y1, where + what});
  }

  static double shoelace(const std::vector<slicer::Point2>& p) {
    double twice = 0;
    for (std::size_t i = 0, n = p.size(); i < n; ++i) {
      const slicer::Point2& a = p[i];
      const slicer::Point2& b = p[(i + 1) % n];
      twice += (a.x - p[0].x) * (b.y - p[0].y) - (a.y - p[0].y) * (b.x - p[0].x);
    }
    return 0.5 * twice;
  }

  static bool has_zero_edge(const std::vector<slicer::Point2>& p) {
    for (std::size_t i = 0; i < p.size(); ++i)
      if (p[i] == p[(i + 1) % p.size()]) return true;
    return false;
  }

  //! Planes at or below z (a vertex on a plane counts as above it).
  std::uint32_t below(double z) const {
    return std::uint32_t(std::upper_bound(heights_.begin(), heights_.end(), z) - heights_.begin());
  }

  //! Faces listed under every plane they cross: one binary search per face corner.
  void bucket_faces(std::size_t nf) {
    std::vector<std::uint32_t> lo(nf), hi(nf);
    offset_.assign(heights_.size() + 1, 0);
    for (std::size_t f = 0; f < nf; ++f) {
      const double z[3] = {pos_[corners_[3 * f].idx].z, pos_[corners_[3 * f + 1].idx].z,
                           pos_[corners_[3 * f + 2].idx].z};
      lo[f] = below(std::min({z[0], z[1], z[2]}));
      hi[f] = below(std::max({z[0], z[1], z[2]}));
      for (std::uint32_t k = lo[f]; k < hi[f]; ++k) ++offset_[k + 1];
    }
    for (std::size_t k = 0; k < heights_.size(); ++k) offset_[k + 1] += offset_[k];
    faces_.resize(offset_.back());
    std::vector<std::uint64_t> fill(offset_.begin(), offset_.end() - 1);
    for (std::size_t f = 0; f < nf; ++f)
      for (std::uint32_t k = lo[f]; k < hi[f]; ++k) faces_[fill[k]++] = std::uint32_t(f);
  }

  //! Face f's piece of the contour at height z: from where the contour enters it (its edge
  //! going down through the plane) to where it leaves (its edge going up), each point
  //! computed from the edge's lower end as the slicer does, so the bits agree.
  Segment segment(std::uint32_t f, double z) const {
    Segment s;
    for (int i = 0; i < 3; ++i) {
      const Vec3& a = pos_[corners_[3 * f + i].idx];
      const Vec3& b = pos_[corners_[3 * f + (i + 1) % 3].idx];
      const bool a_up = a.z >= z, b_up = b.z >= z;
      if (a_up == b_up) continue;
      const Vec3& l = a_up ? b : a;  // the lower end
      const Vec3& u = a_up ? a : b;
      const double t = (z - l.z) / (u.z - l.z);
      const slicer::Point2 p = u.z == z
                                   ? slicer::Point2{u.x, u.y}
                                   : slicer::Point2{l.x + t * (u.x - l.x), l.y + t * (u.y - l.y)};
      (a_up ? s.in : s.out) = p;
    }
    return s;
  }

  //! Every loop edge must be one face's segment: in its direction when the loop runs with
  //! the mesh's orientation (always, on a closed outward-oriented mesh whose slices do not
  //! overlap), against it when the slicer turned the loop to fit its nesting. And the
  //! layer's area must equal the Green sum of all the faces' segments.
  void check_against_mesh(const slicer::Layer& layer, const std::vector<double>& area,
                          const std::vector<Box>& box) {
    const double z = layer.z;
    std::unordered_multiset<std::string> forward;
    double green = 0, scale = 0;
    for (std::uint64_t i = offset_[layer.index]; i < offset_[layer.index + 1]; ++i) {
      const Segment s = segment(faces_[i], z);
      const double cross = s.in.x * s.out.y - s.in.y * s.out.x;
      green += 0.5 * cross;
      scale += 0.5 * std::fabs(cross);
      if (!(s.in == s.out)) forward.insert(key(s.in, s.out));
    }
    double sum = 0, sum_abs = 0;
    for (const double a : area) sum += a, sum_abs += std::fabs(a);
    const double tolerance = 1e-9 * std::max(sum_abs, scale) + 1e-12;
    if (std::fabs(sum - green) > tolerance) {
      ++c_.area_mismatch_layers;
      Box all;
      for (const Box& b : box) all.add({b.x0, b.y0}), all.add({b.x1, b.y1});
      fail(layer, Finding::AgainstMesh, all,
           "area " + num(sum) + " but the mesh's segments give " + num(green));
    }
    for (std::size_t l = 0; l < layer.loops.size(); ++l) {
      const auto& p = layer.loops[l].points;
      std::size_t with = 0, against = 0, none = 0;
      for (std::size_t i = 0; i < p.size(); ++i) {
        const slicer::Point2& a = p[i];
        const slicer::Point2& b = p[(i + 1) % p.size()];
        if (forward.count(key(a, b)))
          ++with;
        else if (forward.count(key(b, a)))
          ++against;
        else
          ++none;
      }
      if (none > 0) {
        ++c_.unmatched;
        fail(layer, Finding::Other, box[l],
             "loop " + std::to_string(l) + ": " + std::to_string(none) +
                 " edges are no face's segment");
      }
      if (against > 0) {
        ++c_.against_mesh;
        fail(layer, Finding::AgainstMesh, box[l],
             "loop " + std::to_string(l) + " (area " + num(area[l]) +
                 "): " + std::to_string(against) + " of " + std::to_string(p.size()) +
                 " edges run against their faces");
      }
    }
  }

  static std::string key(const slicer::Point2& a, const slicer::Point2& b) {
    std::string k(4 * sizeof(double), '\0');
    const double v[4] = {a.x, a.y, b.x, b.y};
    std::memcpy(k.data(), v, sizeof(v));
    return k;
  }

  //! Even-odd containment of p in a loop by the winding-crossing rule with exact
  //! orientation; 0 = outside, 1 = inside, -1 = on the boundary.
  static int contains(const std::vector<slicer::Point2>& poly, const slicer::Point2& p) {
    int winding = 0;
    const P2 q(p.x, p.y);
    for (std::size_t i = 0, n = poly.size(); i < n; ++i) {
      const slicer::Point2& a = poly[i];
      const slicer::Point2& b = poly[(i + 1) % n];
      const CGAL::Orientation o = CGAL::orientation(P2(a.x, a.y), P2(b.x, b.y), q);
      if (o == CGAL::COLLINEAR && std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) &&
          std::min(a.y, b.y) <= p.y && p.y <= std::max(a.y, b.y))
        return -1;
      if (a.y <= p.y && b.y > p.y && o == CGAL::LEFT_TURN) ++winding;
      if (a.y > p.y && b.y <= p.y && o == CGAL::RIGHT_TURN) --winding;
    }
    return winding != 0 ? 1 : 0;
  }

  //! Depth, kind and parent against a containment count. Where loops cross (`crosses`: the
  //! loops with an edge crossing another loop's) containment has no single answer: a
  //! disagreement for a loop that crosses, or lies inside one that does, is reported as a
  //! Crossing finding, not as a nesting fault.
  void check_nesting(const slicer::Layer& layer, const std::vector<double>& area,
                     const std::vector<Box>& box, const std::vector<bool>& crosses) {
    const auto& loops = layer.loops;
    const std::size_t n = loops.size();
    for (std::size_t i = 0; i < n; ++i) {
      // Probe with the first point of loop i that lies on no other loop.
      std::vector<std::size_t> around;
      bool probed = false;
      for (const auto& p : loops[i].points) {
        around.clear();
        bool on_boundary = false;
        for (std::size_t j = 0; j < n && !on_boundary; ++j) {
          if (j == i || !box[j].has(p)) continue;
          const int c = contains(loops[j].points, p);
          if (c < 0) on_boundary = true;
          if (c > 0) around.push_back(j);
        }
        if (!on_boundary) {
          probed = true;
          break;
        }
      }
      if (!probed) {
        ++c_.unprobed;
        fail(layer, Finding::Other, box[i],
             "every point of loop " + std::to_string(i) + " lies on another loop");
        continue;
      }
      // The parent is the innermost loop around: the one with the smallest area.
      int parent = -1;
      for (const std::size_t j : around)
        if (parent < 0 || std::fabs(area[j]) < std::fabs(area[std::size_t(parent)]))
          parent = int(j);
      const int depth = int(around.size());
      const slicer::LoopKind kind =
          depth % 2 == 0 ? slicer::LoopKind::Outer : slicer::LoopKind::Hole;
      if (loops[i].depth != depth || loops[i].kind != kind || loops[i].parent != parent ||
          loops[i].parent >= int(i)) {
        bool ambiguous = crosses[i];
        for (const std::size_t j : around) ambiguous = ambiguous || crosses[j];
        for (int j = loops[i].parent; j >= 0 && j < int(i); j = loops[std::size_t(j)].parent)
          ambiguous = ambiguous || crosses[std::size_t(j)];
        if (ambiguous)
          ++c_.ambiguous_nesting;
        else
          ++c_.wrong_nesting;
        fail(layer, ambiguous ? Finding::Crossing : Finding::Other, box[i],
             "loop " + std::to_string(i) + " has depth " + std::to_string(loops[i].depth) +
                 ", parent " + std::to_string(loops[i].parent) + "; containment gives depth " +
                 std::to_string(depth) + ", parent " + std::to_string(parent));
      }
    }
  }

  //! Edges of the layer's loops that cross properly (each one's ends strictly on opposite
  //! sides of the other), found through a uniform grid of the edges' boxes; one finding per
  //! crossing pair, located by the two edges' box. Returns, per loop, whether one of its
  //! edges crosses another edge (of any loop, itself included).
  std::vector<bool> check_crossings(const slicer::Layer& layer) {
    struct Edge {
      slicer::Point2 a, b;
      std::uint32_t loop;
    };
    std::vector<Edge> edges;
    std::vector<bool> crosses(layer.loops.size(), false);
    Box all;
    for (std::uint32_t l = 0; l < layer.loops.size(); ++l) {
      const auto& loop = layer.loops[l];
      for (std::size_t i = 0, n = loop.points.size(); i < n; ++i) {
        edges.push_back({loop.points[i], loop.points[(i + 1) % n], l});
        all.add(loop.points[i]);
      }
    }
    if (edges.size() < 4) return crosses;
    const std::size_t g = std::max<std::size_t>(1, std::size_t(std::sqrt(double(edges.size()))));
    const double cw = std::max((all.x1 - all.x0) / double(g), 1e-300);
    const double ch = std::max((all.y1 - all.y0) / double(g), 1e-300);
    const auto cell = [&](double v, double v0, double size) {
      return std::min(g - 1, std::size_t(std::max(0.0, (v - v0) / size)));
    };
    std::vector<std::vector<std::uint32_t>> grid(g * g);
    for (std::uint32_t e = 0; e < edges.size(); ++e) {
      const Edge& s = edges[e];
      const std::size_t cx0 = cell(std::min(s.a.x, s.b.x), all.x0, cw);
      const std::size_t cx1 = cell(std::max(s.a.x, s.b.x), all.x0, cw);
      const std::size_t cy0 = cell(std::min(s.a.y, s.b.y), all.y0, ch);
      const std::size_t cy1 = cell(std::max(s.a.y, s.b.y), all.y0, ch);
      for (std::size_t cy = cy0; cy <= cy1; ++cy)
        for (std::size_t cx = cx0; cx <= cx1; ++cx) grid[cy * g + cx].push_back(e);
    }
    const auto orient = [](const slicer::Point2& p, const slicer::Point2& q,
                           const slicer::Point2& r) {
      return CGAL::orientation(P2(p.x, p.y), P2(q.x, q.y), P2(r.x, r.y));
    };
    std::vector<std::pair<std::uint32_t, std::uint32_t>> found;
    for (const auto& bucket : grid)
      for (std::size_t i = 0; i < bucket.size(); ++i)
        for (std::size_t j = i + 1; j < bucket.size(); ++j) {
          const Edge& s = edges[bucket[i]];
          const Edge& t = edges[bucket[j]];
          const CGAL::Orientation o1 = orient(s.a, s.b, t.a), o2 = orient(s.a, s.b, t.b);
          const CGAL::Orientation o3 = orient(t.a, t.b, s.a), o4 = orient(t.a, t.b, s.b);
          if (o1 != CGAL::COLLINEAR && o2 != CGAL::COLLINEAR && o3 != CGAL::COLLINEAR &&
              o4 != CGAL::COLLINEAR && o1 != o2 && o3 != o4)
            found.emplace_back(bucket[i], bucket[j]);
        }
    std::sort(found.begin(), found.end());
    found.erase(std::unique(found.begin(), found.end()), found.end());
    if (!found.empty()) ++c_.crossing_layers;
    for (const auto& [i, j] : found) {
      Box b;
      for (const Edge* e : {&edges[i], &edges[j]}) b.add(e->a), b.add(e->b);
      fail(layer, Finding::Crossing, b,
           "edges of loops " + std::to_string(edges[i].loop) + " and " +
               std::to_string(edges[j].loop) + " cross");
      crosses[edges[i].loop] = crosses[edges[j].loop] = true;
    }
    return crosses;
  }

  std::span<const VertexId> corners_;
  std::span<const Vec3> pos_;
  std::vector<double> heights_;
  std::vector<std::uint64_t> offset_;  //!< faces_[offset_[k], offset_[k + 1]) cross plane k
  std::vector<std::uint32_t> faces_;
  ContourCheck c_;
};

//! Slices `mesh` with `params` (streaming) and checks every layer.
inline ContourCheck check_contours(const Mesh& mesh, const slicer::SliceParams& params) {
  ContourChecker checker(mesh, slicer::plan_layers(mesh, params).heights);
  slicer::slice(mesh, params, [&](slicer::Layer&& layer) { checker.add(layer); });
  return checker.result();
}

//! Where the surface passes through itself: for every pair of faces that intersect (CGAL's
//! self_intersections; faces sharing a vertex or an edge count only when they overlap), the
//! common part of the two faces' bounding boxes.
struct Box3 {
  double x0, y0, z0, x1, y1, z1;
};
inline std::vector<Box3> self_intersection_boxes(const Mesh& mesh) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;
  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> v;
  v.reserve(mesh.num_vertices());
  for (const Vec3& p : mesh.positions()) v.push_back(sm.add_vertex(K::Point_3(p.x, p.y, p.z)));
  for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
    const auto c = mesh.face_vertices(FaceId(std::uint32_t(f)));
    sm.add_face(v[c[0].idx], v[c[1].idx], v[c[2].idx]);
  }
  std::vector<std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(sm, std::back_inserter(pairs));
  const auto box = [&](SurfaceMesh::Face_index f) {
    Box3 b{1e300, 1e300, 1e300, -1e300, -1e300, -1e300};
    for (const auto u : sm.vertices_around_face(sm.halfedge(f))) {
      const K::Point_3& p = sm.point(u);
      b = {std::min(b.x0, p.x()), std::min(b.y0, p.y()), std::min(b.z0, p.z()),
           std::max(b.x1, p.x()), std::max(b.y1, p.y()), std::max(b.z1, p.z())};
    }
    return b;
  };
  std::vector<Box3> boxes;
  for (const auto& [f, g] : pairs) {
    const Box3 a = box(f), b = box(g);
    boxes.push_back({std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::max(a.z0, b.z0),
                     std::min(a.x1, b.x1), std::min(a.y1, b.y1), std::min(a.z1, b.z1)});
  }
  return boxes;
}

//! How far (mm, the largest gap along one axis) a finding's plane and x-y box lie from the
//! nearest of `boxes`; 0 when they meet one, infinity when there is none.
inline double gap_to(const Finding& f, const std::vector<Box3>& boxes) {
  double best = std::numeric_limits<double>::infinity();
  for (const Box3& b : boxes)
    best = std::min(best, std::max({0.0, b.z0 - f.z, f.z - b.z1, b.x0 - f.x1, f.x0 - b.x1,
                                    b.y0 - f.y1, f.y0 - b.y1}));
  return best;
}

//! Whether a finding of the two kinds a self-intersection causes (crossing loops, a loop
//! against its faces) lies where the surface intersects itself: its plane and x-y box meet
//! one of `boxes`, grown by `margin` (mm). A fold is a thin tube between two intersections
//! and its slices close away from the intersecting faces: the dragon at 0.01 mm has such a
//! loop 0.0082 mm from the nearest box (bench/slicer/README.md).
inline bool explained_by(const Finding& f, const std::vector<Box3>& boxes, double margin) {
  return f.kind != Finding::Other && gap_to(f, boxes) <= margin;
}

//! The factor that brings a shared mesh (path relative to ../shared/meshes) to millimetres,
//! as bench/slicer does: the scans are in metres (bunny, dragon) or unit-sized boxes
//! (armadillo, spot, fandisk, the cycloidal gear, two unit cubes); the CAD and generated
//! parts are in millimetres already.
inline double shared_mesh_scale(const std::string& relative) {
  const std::pair<const char*, double> table[] = {{"organic/bunny.stl", 1000},
                                                  {"large/dragon_full.stl.gz", 1000},
                                                  {"organic/armadillo.stl", 100},
                                                  {"organic/spot.stl", 100},
                                                  {"cad/fandisk.stl", 10},
                                                  {"malformed/cycloidal_nonmanifold.stl", 100},
                                                  {"malformed/two_cubes_shared_edge.stl", 10}};
  for (const auto& [name, scale] : table)
    if (relative == name) return scale;
  return 1;
}

}  // namespace stlrefine::test
