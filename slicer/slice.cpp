// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "slicer/slice.h"

#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/parallel.h"
#include "slicer/cgal_planes.h"
#include "slicer/loops.h"

namespace stlrefine::slicer {

namespace {

constexpr double kMaxAbsZ = 1e9;  // StlReadOptions' coordinate limit: nothing printable is larger
constexpr std::uint32_t kNone = 0xffffffffu;

std::string num(double x) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.17g", x);
  return text;
}

Error invalid(const char* field, const std::string& message) {
  return std::move(Error(ErrorCode::InvalidParameter, "out_of_range", message).with_field(field));
}

void require_finite(const char* field, double value, double lo, double hi, const char* unit) {
  if (!(value >= lo && value <= hi)) {
    throw invalid(field, std::string(field) + " = " + num(value) + " is outside [" + num(lo) +
                             ", " + num(hi) + "]" + unit);
  }
}

}  // namespace

const char* to_string(LoopKind kind) {
  return kind == LoopKind::Outer ? "outer" : "hole";
}

std::size_t Layer::num_points() const {
  std::size_t n = 0;
  for (const Loop& l : loops) n += l.points.size();
  for (const Polyline& p : open) n += p.points.size();
  return n;
}

void SliceParams::validate() const {
  if (heights.empty()) require_finite("layer_height", layer_height, 1e-4, 1e4, " mm");
  if (z_min) require_finite("z_min", *z_min, -kMaxAbsZ, kMaxAbsZ, " mm");
  if (z_max) require_finite("z_max", *z_max, -kMaxAbsZ, kMaxAbsZ, " mm");
  if (z_min && z_max && *z_min > *z_max)
    throw invalid("z_min", "z_min = " + num(*z_min) + " is above z_max = " + num(*z_max));
  if (!heights.empty() && (z_min || z_max))
    throw invalid("heights", "heights replace the uniform layers: give heights or z_min/z_max");
  for (double h : heights) require_finite("heights", h, -kMaxAbsZ, kMaxAbsZ, " mm");
  require_in_range<std::size_t>("max_layers", max_layers, 1, 1'000'000);
  require_in_range<std::uint64_t>("max_points", max_points, 1, std::uint64_t{1} << 40);
  require_in_range<std::uint64_t>("points_per_layer", points_per_layer, 0, std::uint64_t{1} << 20);
  require_in_range("threads", threads, 0, 256);
}

Bounds mesh_bounds(const Mesh& mesh) {
  Bounds b;
  for (const Vec3& p : mesh.positions()) {
    if (b.empty) {
      b.min = b.max = p;
      b.empty = false;
      continue;
    }
    b.min = {std::min(b.min.x, p.x), std::min(b.min.y, p.y), std::min(b.min.z, p.z)};
    b.max = {std::max(b.max.x, p.x), std::max(b.max.y, p.y), std::max(b.max.z, p.z)};
  }
  return b;
}

SlicePlan plan_layers(const Mesh& mesh, const SliceParams& params) {
  params.validate();
  SlicePlan plan;
  plan.bounds = mesh_bounds(mesh);
  const auto too_many = [&](const std::string& what) {
    return Error(ErrorCode::BudgetExceeded, "layer_budget",
                 what + "; the limit is max_layers = " + std::to_string(params.max_layers))
        .with_field("max_layers");
  };
  // Every layer is written, empty or not: n layers alone may be more output than allowed.
  const auto check_layer_cost = [&](std::size_t n, const char* lever) {
    if (params.points_per_layer == 0 || n * params.points_per_layer <= params.max_points) return;
    throw Error(ErrorCode::BudgetExceeded, "point_budget",
                std::to_string(n) + " layers cost " + std::to_string(n * params.points_per_layer) +
                    " points before any contour (an empty layer is written as " +
                    std::to_string(params.points_per_layer) +
                    " points' worth of output in this format); the limit is max_points = " +
                    std::to_string(params.max_points) + ": use " + lever)
        .with_field("max_points");
  };

  if (!params.heights.empty()) {
    if (params.heights.size() > params.max_layers)
      throw too_many(std::to_string(params.heights.size()) + " heights were given");
    check_layer_cost(params.heights.size(), "fewer heights");
    plan.heights = params.heights;
    std::sort(plan.heights.begin(), plan.heights.end());
    const auto dup = std::adjacent_find(plan.heights.begin(), plan.heights.end());
    if (dup != plan.heights.end())
      throw invalid("heights", "height " + num(*dup) + " is given twice");
    return plan;
  }

  const double h = params.layer_height;
  plan.layer_height = h;
  if (plan.bounds.empty && !(params.z_min && params.z_max)) return plan;  // nothing to cut
  const double lo = params.z_min.value_or(plan.bounds.min.z);
  const double hi = params.z_max.value_or(plan.bounds.max.z);
  if (lo > hi) {
    const char* field = params.z_min ? "z_min" : "z_max";
    throw invalid(field, "z_min = " + num(lo) + " is above z_max = " + num(hi) +
                             (params.z_min ? " (the mesh top)" : " (the mesh bottom)"));
  }
  const auto layer_z = [&](std::size_t k) { return lo + (double(k) + 0.5) * h; };
  const double span = (hi - lo) / h;
  const auto describe = [&](const std::string& count) {
    return "layer_height = " + num(h) + " mm over z in [" + num(lo) + ", " + num(hi) + "] makes " +
           count + " layers";
  };
  if (!(span <= double(params.max_layers) + 1)) throw too_many(describe("about " + num(span)));
  // Layers k with lo + (k + 1/2) h <= hi; the estimate is off by at most one either way.
  std::size_t n = static_cast<std::size_t>(std::floor(span + 0.5)) + 1;
  while (n > 0 && layer_z(n - 1) > hi) --n;
  while (layer_z(n) <= hi) ++n;
  if (n > params.max_layers) throw too_many(describe(std::to_string(n)));
  // No plane inside the part (it is less than half a layer tall, or the z range is): an
  // empty answer would read as success. Often a part in metres or inches read as mm.
  if (n == 0) {
    char height[32];
    const bool own_range = !params.z_min && !params.z_max;
    std::snprintf(height, sizeof height, "%.4g",
                  own_range ? plan.bounds.max.z - plan.bounds.min.z : hi - lo);
    throw Error(ErrorCode::NothingToMake, "no_layers",
                describe("no") + " (planes are at z_min + (k + 1/2) h; " +
                    (own_range ? "the part is " : "the z range is ") + height +
                    " mm tall): use a smaller layer_height, or units= if the part is not in mm")
        .with_field("layer_height");
  }
  check_layer_cost(n, "a larger layer_height or a narrower z range (z_min, z_max)");
  plan.heights.resize(n);
  for (std::size_t k = 0; k < n; ++k) plan.heights[k] = layer_z(k);
  return plan;
}

namespace {

using cgal::Kernel;

//! Number of planes at or below p, i.e. p is (on or) above plane k iff k < result. A plain
//! search proposes the index; the kernel predicate on the two neighbouring planes decides.
std::uint32_t planes_at_or_below(const Vec3& p, const std::vector<double>& heights) {
  const std::size_t n = heights.size();
  const auto above = [&](std::size_t k) {
    return cgal::on_or_above(cgal::layer_plane(heights[k]), p);
  };
  std::size_t i = std::upper_bound(heights.begin(), heights.end(), p.z) - heights.begin();
  if ((i == 0 || above(i - 1)) && (i == n || !above(i))) return std::uint32_t(i);
  // Never expected (the comparison above is the predicate's exact meaning for z = c
  // planes), but the predicate has the last word: search with it alone.
  std::size_t first = 0, count = n;
  while (count > 0) {
    const std::size_t step = count / 2;
    if (above(first + step)) {
      first += step + 1;
      count -= step + 1;
    } else {
      count = step;
    }
  }
  return std::uint32_t(first);
}

//! A face that crosses at least one plane, with the end of its range of planes.
struct Entry {
  std::uint32_t face;
  std::uint32_t end;  //!< one past the last plane it crosses
};

//! One layer travelling through the pipeline.
struct Work {
  std::size_t k = 0;
  std::vector<std::uint32_t> faces;  //!< every face crossing plane k, in (first plane, id) order
  Layer layer;
  std::string encoded;
};

//! Builds one layer's contours by walking across the faces it cuts.
class LayerBuilder {
 public:
  LayerBuilder(const Mesh& mesh, const std::vector<std::uint32_t>& below, std::size_t k, double z)
      : corner_(mesh.corner_vertices()),
        twin_(mesh.twins()),
        pos_(mesh.positions()),
        below_(below),
        k_(std::uint32_t(k)),
        z_(z) {}

  void build(const std::vector<std::uint32_t>& faces, std::vector<std::uint64_t>& visited,
             Layer& layer) {
    std::vector<std::vector<Point2>> closed;
    for (const std::uint32_t seed : faces) {
      if (is_visited(visited, seed)) continue;
      Chain chain;
      std::uint32_t f = seed;
      std::size_t steps = 0;
      bool open = false;
      do {
        mark(visited, f);
        const std::uint32_t up = cut(f).up;
        push(chain, crossing(up));
        const HalfedgeId t = twin_[up];
        if (!t.valid()) {
          open = true;
          break;
        }
        f = Mesh::face(t).idx;
        if (++steps > faces.size()) throw broken();
      } while (f != seed);

      if (!open) {
        if (chain.points.size() > 1 && same(chain, chain.first_vertex, chain.points.front()))
          chain.points.pop_back();
        closed.push_back(std::move(chain.points));
        continue;
      }
      // Open: go back to the boundary edge where this chain starts, then walk it forwards.
      std::uint32_t b = seed;
      steps = 0;
      for (HalfedgeId t = twin_[cut(b).down]; t.valid(); t = twin_[cut(b).down]) {
        b = Mesh::face(t).idx;
        mark(visited, b);
        if (++steps > faces.size()) throw broken();
      }
      Chain polyline;
      push(polyline, crossing(cut(b).down));
      for (f = b;;) {
        const std::uint32_t up = cut(f).up;
        push(polyline, crossing(up));
        const HalfedgeId t = twin_[up];
        if (!t.valid()) break;
        f = Mesh::face(t).idx;
      }
      layer.open.push_back(Polyline{std::move(polyline.points)});
    }
    for (const std::uint32_t f : faces) visited[f >> 6] = 0;  // reset for the next layer
    detail::assemble_loops(closed, layer);
  }

 private:
  struct Cut {
    std::uint32_t down = kNone, up = kNone;  //!< half-edges leaving / entering the upper side
  };
  struct Crossing {
    Point2 p;
    std::uint32_t vertex = kNone;  //!< the vertex it passes through, when exactly on the plane
  };
  struct Chain {
    std::vector<Point2> points;
    std::uint32_t first_vertex = kNone, last_vertex = kNone;
  };

  bool above(VertexId v) const { return k_ < below_[v.idx]; }

  //! A face crossing the plane has exactly one half-edge going down through it and one
  //! going up (half-edge 3f + i runs from corner i to corner i + 1). With outward normals,
  //! walking from the down to the up crossing runs counter-clockwise around material.
  Cut cut(std::uint32_t f) const {
    const std::uint32_t b = 3 * f;
    const bool a[3] = {above(corner_[b]), above(corner_[b + 1]), above(corner_[b + 2])};
    Cut c;
    for (std::uint32_t i = 0; i < 3; ++i) {
      const bool from = a[i], to = a[i == 2 ? 0 : i + 1];
      if (from && !to) c.down = b + i;
      if (!from && to) c.up = b + i;
    }
    if (c.down == kNone || c.up == kNone) throw broken();
    return c;
  }

  //! Where half-edge h's edge meets the plane. Computed from the lower end, so both faces of
  //! the edge would get the same bits; an upper end exactly on the plane is returned as is.
  Crossing crossing(std::uint32_t h) const {
    VertexId lo = corner_[h], hi = corner_[Mesh::next(HalfedgeId(h)).idx];
    if (above(lo)) std::swap(lo, hi);
    const Vec3& a = pos_[lo.idx];
    const Vec3& b = pos_[hi.idx];
    if (b.z == z_) return {{b.x, b.y}, hi.idx};  // exact: the plane is z = z_
    const double t = (z_ - a.z) / (b.z - a.z);
    return {{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)}, kNone};
  }

  static bool same(const Chain& c, std::uint32_t vertex, const Point2& p) {
    return (vertex != kNone && vertex == c.last_vertex) || p == c.points.back();
  }

  //! Appends a crossing; consecutive crossings through the same on-plane vertex (the edges
  //! of its fan) are one point, so a plane through a vertex gives no zero-length segment.
  static void push(Chain& c, const Crossing& x) {
    if (c.points.empty()) {
      c.first_vertex = x.vertex;
    } else if (same(c, x.vertex, x.p)) {
      c.last_vertex = x.vertex;
      return;
    }
    c.points.push_back(x.p);
    c.last_vertex = x.vertex;
  }

  static bool is_visited(const std::vector<std::uint64_t>& v, std::uint32_t f) {
    return (v[f >> 6] >> (f & 63)) & 1u;
  }
  static void mark(std::vector<std::uint64_t>& v, std::uint32_t f) {
    v[f >> 6] |= std::uint64_t{1} << (f & 63);
  }
  static Error broken() {
    return Error(ErrorCode::Internal, "broken_mesh",
                 "slicer: the mesh's half-edge structure is inconsistent");
  }

  std::span<const VertexId> corner_;
  std::span<const HalfedgeId> twin_;
  std::span<const Vec3> pos_;
  const std::vector<std::uint32_t>& below_;
  std::uint32_t k_;
  double z_;
};

}  // namespace

namespace detail {

SliceStats run(const Mesh& mesh, const SliceParams& params, const SlicePlan& plan,
               const StartFn& started, const PrepareFn& prepare, const DeliverFn& deliver,
               const ProgressFn& progress, const std::atomic<bool>* cancel) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<double>& heights = plan.heights;
  const std::size_t n_layers = heights.size();
  const std::size_t nv = mesh.num_vertices(), nf = mesh.num_faces();
  SliceStats stats;
  stats.layers = n_layers;
  const auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };

  tbb::task_arena arena(params.threads > 0 ? params.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    // 1. Each vertex: how many planes are at or below it (kernel predicates).
    std::vector<std::uint32_t> below(nv);
    const auto positions = mesh.positions();
    parallel_for_each_index(
        nv, [&](std::size_t v) { below[v] = planes_at_or_below(positions[v], heights); });

    // 2. Each face: the range of planes its corners straddle. One pass over the triangles;
    // the exact crossing count is the output budget's measure.
    const auto corners = mesh.corner_vertices();
    std::vector<std::uint32_t> first(nf), end(nf);
    tbb::combinable<std::uint64_t> crossings_part;
    parallel_for_each_index(nf, [&](std::size_t f) {
      const std::uint32_t a = below[corners[3 * f].idx], b = below[corners[3 * f + 1].idx],
                          c = below[corners[3 * f + 2].idx];
      first[f] = std::min({a, b, c});
      end[f] = std::max({a, b, c});
      crossings_part.local() += end[f] - first[f];
    });
    stats.crossings = crossings_part.combine(std::plus<>());
    const std::uint64_t layer_cost = std::uint64_t{n_layers} * params.points_per_layer;
    if (stats.crossings + layer_cost > params.max_points) {
      std::string what = std::to_string(n_layers) + " layers would give " +
                         std::to_string(stats.crossings) + " contour points";
      if (layer_cost > 0)
        what += " and cost " + std::to_string(layer_cost) + " more as layer records";
      throw Error(ErrorCode::BudgetExceeded, "point_budget",
                  what + "; the limit is max_points = " + std::to_string(params.max_points))
          .with_field("max_points");
    }
    if (started) started();

    // 3. Faces bucketed by their first plane (a stable counting sort), for the sweep.
    std::vector<std::uint32_t> offset(n_layers + 1, 0);
    for (std::size_t f = 0; f < nf; ++f)
      if (first[f] < end[f]) ++offset[first[f] + 1];
    for (std::size_t k = 0; k < n_layers; ++k) offset[k + 1] += offset[k];
    std::vector<Entry> starts(offset[n_layers]);
    {
      std::vector<std::uint32_t> fill(offset.begin(), offset.end() - 1);
      for (std::size_t f = 0; f < nf; ++f)
        if (first[f] < end[f]) starts[fill[first[f]]++] = {std::uint32_t(f), end[f]};
    }
    std::vector<std::uint32_t>().swap(first);
    std::vector<std::uint32_t>().swap(end);

    // 4. Sweep upwards. In order: the faces crossing layer k (active set); in parallel:
    // contours (and the writer's encoding); in order: delivery. Tokens bound the layers in
    // flight, hence the memory.
    tbb::enumerable_thread_specific<std::vector<std::uint64_t>> visited(
        [nf] { return std::vector<std::uint64_t>((nf + 63) / 64, 0); });
    std::vector<Entry> active;
    std::size_t next = 0;
    bool stopped = false;
    const std::size_t tokens = 4 * std::size_t(std::max(1, arena.max_concurrency()));
    using WorkPtr = std::shared_ptr<Work>;
    tbb::parallel_pipeline(
        tokens,
        tbb::make_filter<void, WorkPtr>(tbb::filter_mode::serial_in_order,
                                        [&](tbb::flow_control& fc) -> WorkPtr {
                                          if (next == n_layers || cancelled()) {
                                            stopped = next != n_layers;
                                            fc.stop();
                                            return nullptr;
                                          }
                                          const std::size_t k = next++;
                                          std::erase_if(active,
                                                        [k](const Entry& e) { return e.end <= k; });
                                          active.insert(active.end(), starts.begin() + offset[k],
                                                        starts.begin() + offset[k + 1]);
                                          auto w = std::make_shared<Work>();
                                          w->k = k;
                                          w->faces.reserve(active.size());
                                          for (const Entry& e : active) w->faces.push_back(e.face);
                                          return w;
                                        }) &
            tbb::make_filter<WorkPtr, WorkPtr>(
                tbb::filter_mode::parallel,
                [&](WorkPtr w) {
                  Layer& layer = w->layer;
                  layer.index = w->k;
                  layer.z = heights[w->k];
                  LayerBuilder(mesh, below, w->k, layer.z).build(w->faces, visited.local(), layer);
                  std::vector<std::uint32_t>().swap(w->faces);
                  if (prepare) prepare(layer, w->encoded);
                  return w;
                }) &
            tbb::make_filter<WorkPtr, void>(tbb::filter_mode::serial_in_order, [&](WorkPtr w) {
              const Layer& layer = w->layer;
              for (const Loop& l : layer.loops)
                ++(l.kind == LoopKind::Outer ? stats.outer_loops : stats.holes);
              stats.open_polylines += layer.open.size();
              stats.points += layer.num_points();
              stats.degenerate_loops += layer.degenerate_loops;
              stats.reversed_loops += layer.reversed_loops;
              const std::size_t k = w->k;
              deliver(std::move(w->layer), std::move(w->encoded));
              if (progress) progress(double(k + 1) / double(n_layers), "slice");
            }));
    if (stopped) throw Error(ErrorCode::Cancelled, "cancelled", "slicing cancelled");
  });
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace detail

SliceStats slice(const Mesh& mesh, const SliceParams& params, const LayerFn& on_layer,
                 const ProgressFn& progress, const std::atomic<bool>* cancel) {
  const SlicePlan plan = plan_layers(mesh, params);
  return detail::run(
      mesh, params, plan, {}, {}, [&](Layer&& layer, std::string&&) { on_layer(std::move(layer)); },
      progress, cancel);
}

std::vector<Layer> slice_all(const Mesh& mesh, const SliceParams& params, SliceStats* stats) {
  std::vector<Layer> layers;
  const SliceStats s =
      slice(mesh, params, [&](Layer&& layer) { layers.push_back(std::move(layer)); });
  if (stats) *stats = s;
  return layers;
}

}  // namespace stlrefine::slicer
