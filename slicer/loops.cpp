// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "slicer/loops.h"

#include <CGAL/Polygon_2_algorithms.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numeric>
#include <optional>
#include <utility>

#include "slicer/cgal_planes.h"

namespace stlrefine::slicer::detail {

namespace {

using Point_2 = cgal::Kernel::Point_2;

struct Box {
  double x0, y0, x1, y1;
  bool contains(const Box& o) const { return x0 <= o.x0 && y0 <= o.y0 && o.x1 <= x1 && o.y1 <= y1; }
};

Box box_of(const std::vector<Point2>& pts) {
  Box b{pts[0].x, pts[0].y, pts[0].x, pts[0].y};
  for (const Point2& p : pts) {
    b.x0 = std::min(b.x0, p.x), b.y0 = std::min(b.y0, p.y);
    b.x1 = std::max(b.x1, p.x), b.y1 = std::max(b.y1, p.y);
  }
  return b;
}

struct Candidate {
  std::size_t chain;  //!< index in the input (discovery order)
  double area;
  Box box;
  std::vector<Point_2> polygon;  //!< filled on first use as a container
};

//! Whether loop `inner` lies inside `outer`. Loops of one slice never cross, but they may
//! touch at a vertex, so the first point of `inner` not on `outer`'s boundary decides
//! (exact predicates). A loop entirely on the other's boundary is a duplicate: not inside.
bool inside(Candidate& outer, const std::vector<Point2>& inner,
            const std::vector<std::vector<Point2>>& chains) {
  if (outer.polygon.empty()) {
    const auto& pts = chains[outer.chain];
    outer.polygon.reserve(pts.size());
    for (const Point2& p : pts) outer.polygon.emplace_back(p.x, p.y);
  }
  const auto side = [&](double x, double y) {
    return CGAL::bounded_side_2(outer.polygon.begin(), outer.polygon.end(), Point_2(x, y),
                                cgal::Kernel());
  };
  for (const Point2& p : inner) {
    const CGAL::Bounded_side s = side(p.x, p.y);
    if (s != CGAL::ON_BOUNDARY) return s == CGAL::ON_BOUNDED_SIDE;
  }
  for (std::size_t i = 0; i < inner.size(); ++i) {
    const Point2& a = inner[i];
    const Point2& b = inner[(i + 1) % inner.size()];
    const CGAL::Bounded_side s = side(0.5 * (a.x + b.x), 0.5 * (a.y + b.y));
    if (s != CGAL::ON_BOUNDARY) return s == CGAL::ON_BOUNDED_SIDE;
  }
  return false;
}

}  // namespace

double signed_area(std::span<const Point2> pts) {
  if (pts.size() < 3) return 0;
  // Relative to the first point: the terms stay small, far from the origin too.
  const Point2 o = pts[0];
  double twice = 0;
  for (std::size_t i = 1; i + 1 < pts.size(); ++i) {
    const double ax = pts[i].x - o.x, ay = pts[i].y - o.y;
    const double bx = pts[i + 1].x - o.x, by = pts[i + 1].y - o.y;
    twice += ax * by - ay * bx;
  }
  return 0.5 * twice;
}

void assemble_loops(std::vector<std::vector<Point2>>& chains, Layer& layer) {
  std::vector<Candidate> items;
  items.reserve(chains.size());
  for (std::size_t i = 0; i < chains.size(); ++i) {
    const double area = signed_area(chains[i]);
    if (chains[i].size() < 3 || area == 0) {
      ++layer.degenerate_loops;
      continue;
    }
    items.push_back({i, area, box_of(chains[i]), {}});
  }

  // Largest first: a loop's parent is then the last earlier loop that contains it.
  std::vector<std::size_t> order(items.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::fabs(items[a].area) > std::fabs(items[b].area);
  });
  std::vector<int> parent(items.size(), -1), depth(items.size(), 0);
  for (std::size_t i = 1; i < order.size(); ++i) {
    const Candidate& inner = items[order[i]];
    for (std::size_t j = i; j-- > 0;) {
      Candidate& outer = items[order[j]];
      if (!(std::fabs(outer.area) > std::fabs(inner.area)) || !outer.box.contains(inner.box))
        continue;
      if (inside(outer, chains[inner.chain], chains)) {
        parent[order[i]] = int(order[j]);
        depth[order[i]] = depth[order[j]] + 1;
        break;
      }
    }
  }

  // Pre-order of the nesting tree; items are already in chain (discovery) order.
  std::vector<std::vector<std::size_t>> children(items.size());
  std::vector<std::size_t> stack;
  for (std::size_t i = items.size(); i-- > 0;) {
    if (parent[i] < 0)
      stack.push_back(i);
    else
      children[std::size_t(parent[i])].push_back(i);
  }
  for (auto& c : children) std::reverse(c.begin(), c.end());
  std::vector<int> out_index(items.size(), -1);
  layer.loops.reserve(items.size());
  while (!stack.empty()) {
    const std::size_t i = stack.back();
    stack.pop_back();
    Candidate& item = items[i];
    Loop loop;
    loop.depth = depth[i];
    loop.kind = depth[i] % 2 == 0 ? LoopKind::Outer : LoopKind::Hole;
    loop.parent = parent[i] < 0 ? -1 : out_index[std::size_t(parent[i])];
    loop.points = std::move(chains[item.chain]);
    loop.area = item.area;
    if ((loop.kind == LoopKind::Outer) != (loop.area > 0)) {
      std::reverse(loop.points.begin() + 1, loop.points.end());  // keep the first point
      loop.area = -loop.area;
      ++layer.reversed_loops;
    }
    layer.area += loop.area;
    out_index[i] = int(layer.loops.size());
    layer.loops.push_back(std::move(loop));
    for (auto c = children[i].rbegin(); c != children[i].rend(); ++c) stack.push_back(*c);
  }
}

}  // namespace stlrefine::slicer::detail
