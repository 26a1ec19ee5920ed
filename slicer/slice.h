// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The slicer: cuts a Mesh with horizontal planes and returns, per layer, closed contours
// classified outer / hole by nesting and oriented for a machine, plus the open polylines
// that open or cut meshes produce. CGAL is used inside (planes and predicates) but never
// appears in this header, so callers (api/, cli/, server/) need no CGAL flags.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/vec3.h"
#include "core/mesh/mesh.h"
#include "core/progress.h"

namespace stlrefine::slicer {

//! What a slice request asks for. Every field has its range next to it.
struct SliceParams {
  //! Uniform layer thickness h in mm, [1e-4, 1e4]. Planes are at z_min + (k + 1/2) h for
  //! every k >= 0 whose plane is <= z_max (the middle of each printed layer). Ignored when
  //! `heights` is given.
  double layer_height = 0.1;
  //! Range of the uniform layers; default the mesh's bounds. Finite, z_min <= z_max.
  std::optional<double> z_min, z_max;
  //! Explicit plane heights in mm (finite, distinct, any order; layers come out sorted).
  //! Non-empty replaces the uniform layers; z_min / z_max must then be unset.
  std::vector<double> heights;
  //! Refuse plans with more layers than this, before any work; [1, 1'000'000].
  std::size_t max_layers = 1'000'000;
  //! Refuse before the contour pass when the output would exceed this many points: one per
  //! triangle crossing a plane (counted exactly in a cheap pre-pass), plus
  //! `points_per_layer` for every layer, empty or not; [1, 2^40].
  std::uint64_t max_points = 200'000'000;
  //! What one layer costs against max_points whatever it holds: an empty layer's record in
  //! the output format, in that format's shortest points (slicer::empty_layer_points), so
  //! that planes through nothing are not free. 0 = layers are free (slice() into memory);
  //! write_slices charges at least its writer's cost. [0, 2^20].
  std::uint64_t points_per_layer = 0;
  //! Worker threads, [0, 256]; 0 = every core.
  int threads = 0;

  //! \throw Error(InvalidParameter) naming the field.
  void validate() const;
};

struct Point2 {
  double x = 0, y = 0;
  friend bool operator==(const Point2&, const Point2&) = default;
};

enum class LoopKind { Outer, Hole };
//! "outer" or "hole".
const char* to_string(LoopKind kind);

//! A closed contour. Points in order, the first one not repeated at the end.
struct Loop {
  //! Outer at even nesting depth (material inside), hole at odd depth.
  LoopKind kind = LoopKind::Outer;
  int depth = 0;    //!< number of loops around this one
  int parent = -1;  //!< index in Layer::loops of the loop directly around it; -1 at depth 0
  //! Signed (shoelace) area: > 0 for outer loops (counter-clockwise seen from +z), < 0 for
  //! holes (clockwise).
  double area = 0;
  std::vector<Point2> points;
};

//! A chain of crossings from one mesh boundary to another (open or non-manifold input).
//! Never closed and never dropped; its direction follows the mesh's face orientation.
struct Polyline {
  std::vector<Point2> points;
};

//! One cut plane's result.
struct Layer {
  std::size_t index = 0;  //!< 0-based, in ascending z
  double z = 0;
  //! Closed loops, parents before their children (pre-order of the nesting tree).
  std::vector<Loop> loops;
  std::vector<Polyline> open;
  //! Material area: sum of the loops' signed areas (outer minus holes).
  double area = 0;
  //! Loops that collapsed to fewer than 3 points or zero area: the plane only touches the
  //! part there (a vertex or a horizontal edge reached from one side).
  std::size_t degenerate_loops = 0;
  //! Loops whose mesh winding disagreed with their nesting and were reversed (inside-out
  //! shells). Zero on a consistently outward-oriented mesh.
  std::size_t reversed_loops = 0;

  std::size_t num_points() const;
};

//! Axis-aligned bounds of the mesh's vertices.
struct Bounds {
  Vec3 min, max;
  bool empty = true;
};
Bounds mesh_bounds(const Mesh& mesh);

//! The planes a request resolves to, known before any layer is computed (writers need the
//! layer count and the bounds for their headers).
struct SlicePlan {
  std::vector<double> heights;  //!< ascending
  double layer_height = 0;      //!< h for uniform layers; 0 for an explicit list
  Bounds bounds;                //!< the mesh's
};

//! Resolves params against the mesh. Validates params first.
//! \throw Error(InvalidParameter) naming the field;
//! Error(BudgetExceeded, field "max_layers") when the plan has more layers than allowed;
//! Error(BudgetExceeded, "point_budget", field "max_points") when its layers alone cost
//! more than max_points (layers x points_per_layer), before any height is stored.
SlicePlan plan_layers(const Mesh& mesh, const SliceParams& params);

//! Totals over a slice run.
struct SliceStats {
  std::size_t layers = 0;
  std::size_t outer_loops = 0, holes = 0, open_polylines = 0;
  std::uint64_t points = 0;
  //! Triangle-plane crossings found by the pre-pass (with layers x points_per_layer, the
  //! output point budget's measure).
  std::uint64_t crossings = 0;
  std::size_t degenerate_loops = 0, reversed_loops = 0;
  double seconds = 0;
};

//! Called once per layer, in ascending z, never concurrently. The layer may be moved from.
using LayerFn = std::function<void(Layer&& layer)>;

//! Cuts `mesh` with the planes of `params`. Every triangle is visited once to find the
//! range of planes its z-extent spans (kernel predicates on the plane, with the rule that a
//! vertex exactly on a plane counts as above it), then layers are swept upwards: each
//! layer's crossing triangles are chained through their shared edges into loops, in
//! parallel over layers. Layers reach `on_layer` in order while later ones are still being
//! computed; at most a few layers per thread are in memory at any time.
//! Progress is reported per layer; `cancel` is checked between layers.
//! \throw Error(InvalidParameter | BudgetExceeded | Cancelled); Error(Internal) when the
//! mesh breaks its own invariants.
SliceStats slice(const Mesh& mesh, const SliceParams& params, const LayerFn& on_layer,
                 const ProgressFn& progress = {}, const std::atomic<bool>* cancel = nullptr);

//! slice() into memory, for tests and small parts.
std::vector<Layer> slice_all(const Mesh& mesh, const SliceParams& params,
                             SliceStats* stats = nullptr);

// --- lower-level pieces, shared with the writers' streaming driver

namespace detail {
//! Called once the budgets are checked, before the first layer (writers write headers).
using StartFn = std::function<void()>;
//! Layer hook run on the worker thread right after a layer is built (writers encode there).
using PrepareFn = std::function<void(const Layer& layer, std::string& encoded)>;
//! Delivery of a layer and its encoding, in order.
using DeliverFn = std::function<void(Layer&& layer, std::string&& encoded)>;
SliceStats run(const Mesh& mesh, const SliceParams& params, const SlicePlan& plan,
               const StartFn& started, const PrepareFn& prepare, const DeliverFn& deliver,
               const ProgressFn& progress, const std::atomic<bool>* cancel);
}  // namespace detail

}  // namespace stlrefine::slicer
