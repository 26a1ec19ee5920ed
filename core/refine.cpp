// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/refine.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <unordered_set>

#include "core/error.h"
#include "core/parallel.h"
#include "core/schemes/adaptive_split4.h"
#include "core/schemes/adaptive_sqrt3.h"
#include "core/schemes/split4_host.h"
#include "core/schemes/sqrt3_host.h"

namespace stlrefine {

namespace {

// The ranges, and that the name is a scheme's (without making it).
void validate_fields(const RefineParams& p) {
  if (!find_scheme(p.scheme)) make_scheme(p.scheme);  // throws InvalidParameter naming "scheme"
  require_in_range("levels", p.levels, 0, 8);
  p.features.validate();
  require_in_range<std::uint64_t>("max_faces", p.max_faces, 1, (std::uint64_t{1} << 31) - 1);
  require_in_range("threads", p.threads, 0, 256);
  require_in_range("adaptive_tol", p.adaptive_tol, 0.0, 1e6);
  require_in_range("adaptive_angle", p.adaptive_angle, 0.0, 180.0);
  require_in_range("max_level", p.max_level, 1, 8);
  validate_scheme_options(p.scheme_options);
}

void require_adaptive_mode(const RefineParams& p, const Scheme& s) {
  if (p.adaptive() && !adaptive_scheme(s) && !adaptive_sqrt3_scheme(s))
    throw Error(ErrorCode::InvalidParameter, "adaptive_unsupported",
                "adaptive refinement needs a sqrt3 scheme or an interpolating 1-to-4 scheme "
                "(lsf, butterfly), not " +
                    std::string(s.name()))
        .with_field(p.adaptive_tol > 0 ? "adaptive_tol" : "adaptive_angle");
}

}  // namespace

void RefineParams::validate() const {
  validate_fields(*this);
  if (adaptive()) require_adaptive_mode(*this, *make_scheme(scheme));
}

void RefineParams::validate(const Scheme& s) const {
  validate_fields(*this);
  require_adaptive_mode(*this, s);
}

std::unique_ptr<Scheme> make_scheme(const RefineParams& params) {
  validate_fields(params);
  std::unique_ptr<Scheme> s = make_scheme(params.scheme, params.scheme_options);
  require_adaptive_mode(params, *s);
  return s;
}

const Split4Stencil* adaptive_scheme(const Scheme& scheme) {
  const auto* split4 = dynamic_cast<const HostScheme<Split4Stencil>*>(&scheme);
  return split4 && split4->interpolating() ? &split4->stencil() : nullptr;
}

const Sqrt3Stencil* adaptive_sqrt3_scheme(const Scheme& scheme) {
  const auto* sqrt3 = dynamic_cast<const HostScheme<Sqrt3Stencil>*>(&scheme);
  return sqrt3 ? &sqrt3->stencil() : nullptr;
}

std::uint64_t check_face_budget(std::size_t faces, const Scheme& scheme,
                                const RefineParams& params) {
  // Adaptive output size depends on the geometry: the uniform count at the level cap bounds
  // it, and the refinement stops as soon as its exact count would pass max_faces.
  if (params.adaptive()) return scheme.predict_faces(faces, params.max_level);
  const std::uint64_t predicted = scheme.predict_faces(faces, params.levels);
  if (predicted > params.max_faces) {
    throw Error(ErrorCode::BudgetExceeded, "face_budget",
                std::string(scheme.name()) + " with " + std::to_string(params.levels) +
                    " levels would make " + std::to_string(predicted) + " faces from " +
                    std::to_string(faces) +
                    "; the limit is max_faces = " + std::to_string(params.max_faces))
        .with_field("max_faces");
  }
  return predicted;
}

std::uint64_t check_face_budget(std::size_t faces, const RefineParams& params) {
  return check_face_budget(faces, *make_scheme(params.scheme), params);
}

std::uint64_t predict_faces(std::uint64_t faces, const Scheme& scheme, const RefineParams& params) {
  if (!params.adaptive()) return scheme.predict_faces(faces, params.levels);
  return std::min<std::uint64_t>(scheme.predict_faces(faces, params.max_level), params.max_faces);
}

void require_simple_mesh(const Mesh& m) {
  const auto refuse = [](const std::string& what) {
    return Error(ErrorCode::NotTriangleMesh, "adaptive_non_simple",
                 "adaptive refinement needs a simple mesh, but " + what +
                     "; refine with uniform levels instead");
  };
  std::unordered_set<std::uint64_t> pairs;
  pairs.reserve(m.num_edges());
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    const std::uint32_t a = std::min(m.from(h).idx, m.to(h).idx);
    const std::uint32_t b = std::max(m.from(h).idx, m.to(h).idx);
    if (!pairs.insert((std::uint64_t{a} << 32) | b).second)
      throw refuse("vertices " + std::to_string(a) + " and " + std::to_string(b) +
                   " are joined by two edges");
  }
  // With edges unique, faces on the same three vertices are twins across all three edges.
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    std::uint32_t across[3];
    for (int k = 0; k < 3; ++k) {
      const HalfedgeId t = m.twin(Mesh::halfedge(FaceId(f), k));
      across[k] = t.valid() ? Mesh::face(t).idx : f;
    }
    if (across[0] != f && across[0] == across[1] && across[1] == across[2])
      throw refuse("faces " + std::to_string(f) + " and " + std::to_string(across[0]) +
                   " have the same three vertices");
  }
}

namespace {

std::string mib(std::uint64_t bytes) {
  return std::to_string((bytes + (1 << 20) - 1) >> 20) + " MiB";
}

}  // namespace

MemoryBudgetError::MemoryBudgetError(std::string field, int level, std::uint64_t needed_bytes)
    : Error(ErrorCode::BudgetExceeded, "memory_budget",
            (field == "max_level" ? "adaptive level " : "level ") + std::to_string(level) +
                " would need " + std::to_string(needed_bytes) + " bytes (" + mib(needed_bytes) +
                ") of memory, more than the memory budget grants"),
      level_(level),
      needed_bytes_(needed_bytes) {
  with_field(std::move(field));
}

std::uint64_t mesh_bytes(const Mesh& m) {
  const std::size_t nv = m.num_vertices(), nh = m.num_halfedges(), ne = m.num_edges();
  // Mesh::memory_bytes counts capacities: whatever it has beyond the sizes is put on the
  // edge array, the one that can have more (Mesh::from_parts reserves it).
  const std::uint64_t sized = nv * (sizeof(Vec3) + sizeof(HalfedgeId)) + 3 * nh * 4 + ne * 4;
  const std::uint64_t spare = m.memory_bytes() > sized ? m.memory_bytes() - sized : 0;
  return big_vector_bytes<Vec3>(nv) + 3 * big_vector_bytes<HalfedgeId>(nh) +
         big_vector_bytes<HalfedgeId>(ne + spare / 4) + big_vector_bytes<HalfedgeId>(nv);
}

namespace {

std::uint64_t features_bytes(const Mesh& m) {
  return big_vector_bytes<std::uint8_t>(m.num_edges()) +
         big_vector_bytes<VertexKind>(m.num_vertices()) +
         big_vector_bytes<std::array<VertexId, 2>>(m.num_vertices());
}

}  // namespace

std::uint64_t level_bytes(const Level& level) {
  std::uint64_t bytes = mesh_bytes(level.mesh) + features_bytes(level.mesh) +
                        big_vector_bytes<double>(level.alpha.size()) +
                        big_vector_bytes<Vec3>(level.smooth_normals.size());
  if (level.irregular.list) bytes += level.irregular.list->capacity() * 8;
  return bytes;
}

namespace {

// Memory admission of one refinement: what it holds besides the host (the input, copies),
// the level in the making for the message, and the figure granted so far. Figures only rise.
class Meter {
 public:
  Meter(const MemoryGrowFn& grow, std::string field) : grow_(grow), field_(std::move(field)) {}

  bool on() const { return static_cast<bool>(grow_); }
  void set_level(int level) { level_ = level; }
  void set_outside(std::uint64_t bytes) { outside_ = bytes; }
  //! The host (or the step about to run) holds `bytes` besides what set_outside said.
  void need(std::uint64_t bytes) {
    if (!grow_) return;
    const std::uint64_t total = kRefineSlackBytes + outside_ + bytes;
    if (total <= granted_) return;
    if (!grow_(total)) throw MemoryBudgetError(field_, level_, total);
    granted_ = total;
  }
  //! For a host: its own bytes, through need().
  std::function<void(std::uint64_t)> host() {
    if (!grow_) return {};
    return [this](std::uint64_t bytes) { need(bytes); };
  }

 private:
  const MemoryGrowFn& grow_;
  std::string field_;
  int level_ = 0;
  std::uint64_t outside_ = 0, granted_ = 0;
};

void throw_if_cancelled(const std::atomic<bool>* cancel) {
  if (cancel && cancel->load(std::memory_order_relaxed))
    throw Error(ErrorCode::Cancelled, "cancelled", "refinement cancelled");
}

// The input mesh and what refine makes of it before a host runs: its features with a
// normal per face while they are detected, and the simple-mesh check's hash set (a node and
// a bucket per edge, with allocator headers).
std::uint64_t input_bytes(const Mesh& m) {
  return mesh_bytes(m) + features_bytes(m) + big_vector_bytes<Vec3>(m.num_faces()) +
         std::uint64_t(m.num_edges()) * 48;
}

RefineResult run_levels(Mesh mesh, const RefineParams& params, const Scheme& scheme,
                        const ProgressFn& progress, const std::atomic<bool>* cancel,
                        const MemoryGrowFn& grow, std::optional<Features> detected,
                        const BetweenLevelsFn& between_levels) {
  const CancelScope cancel_scope(cancel);  // parallel loops of this request stop early
  const auto start = std::chrono::steady_clock::now();
  RefineResult result;
  RefineReport& r = result.report;
  r.scheme = std::string(scheme.name());
  r.levels = params.levels;
  r.input_vertices = mesh.num_vertices();
  r.input_faces = mesh.num_faces();
  const std::size_t input_faces = mesh.num_faces();
  Meter meter(grow, params.adaptive() ? "max_level" : "levels");
  const std::uint64_t copied_positions = big_vector_bytes<Vec3>(mesh.num_vertices());
  if (meter.on()) {
    meter.set_outside(copied_positions);
    meter.need(input_bytes(mesh));
  }
  // Old vertices keep their ids at every level, so input vertex v is output vertex v.
  const BigVector<Vec3> input_positions(mesh.positions().begin(), mesh.positions().end());

  // The adaptive sqrt3 host knows edges by their vertex pairs (AdaptiveSplit4 does not).
  if (params.adaptive() && adaptive_sqrt3_scheme(scheme)) require_simple_mesh(mesh);
  Features features = detected ? std::move(*detected) : detect_features(mesh, params.features);
  Level level{std::move(mesh), std::move(features)};
  r.sharp_edges_in = level.features.num_sharp_edges();
  r.corners = level.features.count(VertexKind::Corner);
  r.creases = level.features.count(VertexKind::Crease);
  r.darts = level.features.count(VertexKind::Dart);

  StepStats stats;
  r.adaptive_tol = params.adaptive_tol;
  r.adaptive_angle = params.adaptive_angle;
  auto adaptive_progress = [&](int i) {
    if (progress)
      progress(double(i - 1) / params.max_level,
               "adaptive level " + std::to_string(i) + "/" + std::to_string(params.max_level));
  };
  if (params.adaptive() && adaptive_sqrt3_scheme(scheme)) {
    const Sqrt3AdaptiveCriteria criteria{params.adaptive_angle, params.adaptive_tol,
                                         params.max_level};
    meter.set_level(1);
    // The input level is held until the hierarchy has copied it.
    meter.set_outside(copied_positions + level_bytes(level));
    std::optional<AdaptiveSqrt3> adaptive;
    adaptive.emplace(level, *adaptive_sqrt3_scheme(scheme), criteria, meter.host());
    level = Level{};
    meter.set_outside(copied_positions);
    adaptive->run(params.max_faces, cancel, [&](int l) {
      meter.set_level(l + 1);
      adaptive_progress(l + 1);
    });
    throw_if_cancelled(cancel);
    level = adaptive->result();
    r.levels = adaptive->stats().levels;
    r.faces_over_criterion = adaptive->stats().over_criterion_at_cap;
    // Flips the fold guard did not make, face points it moved.
    stats.fold_fallbacks += adaptive->stats().flips_kept + adaptive->stats().face_points_pulled;
    r.max_over_tolerance = adaptive->stats().max_over_tolerance;
    r.worst_over_tolerance_at = adaptive->stats().worst_over_tolerance_at;
    r.stop_reason = r.faces_over_criterion > 0 ? "max_level" : "tolerance";
  } else if (params.adaptive()) {
    const Split4Stencil& stencil = *adaptive_scheme(scheme);
    meter.set_level(1);
    meter.set_outside(copied_positions + level_bytes(level));
    std::optional<AdaptiveSplit4> adaptive;
    adaptive.emplace(level, meter.host());
    level = Level{};
    meter.set_outside(copied_positions);
    int made = 0;
    for (int i = 1; i <= params.max_level; ++i) {
      throw_if_cancelled(cancel);
      adaptive_progress(i);
      meter.set_level(i);
      AdaptiveStepStats step;
      if (!adaptive->step(stencil, params.adaptive_tol, params.max_faces, stats, step,
                          params.adaptive_angle))
        break;
      made = i;
    }
    // At the cap some edges may still be over a criterion: say how many, how far, where
    // (measured as the steps measure them).
    if (made == params.max_level) {
      const EdgesOverTolerance over =
          adaptive->remaining(stencil, params.adaptive_tol, params.adaptive_angle);
      r.edges_over_tolerance = over.count;
      r.max_over_tolerance = over.max_distance;
      r.worst_over_tolerance_at = over.worst_at;
      r.edges_not_converging = over.not_shrinking;
    }
    level = adaptive->release();
    adaptive.reset();
    r.levels = made;
    r.stop_reason = r.edges_over_tolerance > 0 ? "max_level" : "tolerance";
  }
  // Work per level grows 4x (3x for sqrt3), so weight progress by output faces.
  std::uint64_t total = 0;
  const int uniform_levels = params.adaptive() ? 0 : params.levels;
  for (int i = 1; i <= uniform_levels; ++i) total += scheme.predict_faces(input_faces, i);
  std::uint64_t done = 0;
  for (int i = 1; i <= uniform_levels; ++i) {
    throw_if_cancelled(cancel);
    if (progress)
      progress(total ? double(done) / double(total) : 0.0,
               "level " + std::to_string(i) + "/" + std::to_string(params.levels));
    level.pass_smooth_normals = i < uniform_levels;  // the output needs none
    if (meter.on()) {
      // The coarse level next to everything the step makes (exact counts).
      meter.set_level(i);
      const auto* split4 = dynamic_cast<const HostScheme<Split4Stencil>*>(&scheme);
      meter.need(level_bytes(level) +
                 (split4 ? split4_step_bytes(level, split4->stencil()) : sqrt3_step_bytes(level)));
    }
    level = scheme.refine_once(level, stats);
    done += level.mesh.num_faces();
    if (between_levels && i < uniform_levels) {
      throw_if_cancelled(cancel);
      between_levels(level.mesh, level.features, i);
    }
  }
  throw_if_cancelled(cancel);

  for (std::size_t v = 0; v < input_positions.size(); ++v) {
    r.max_input_displacement = std::max(
        r.max_input_displacement,
        distance(input_positions[v], level.mesh.position(VertexId(static_cast<std::uint32_t>(v)))));
  }
  r.output_vertices = level.mesh.num_vertices();
  r.output_faces = level.mesh.num_faces();
  r.sharp_edges_out = level.features.num_sharp_edges();
  r.fold_fallbacks = stats.fold_fallbacks;
  result.mesh = std::move(level.mesh);
  result.features = std::move(level.features);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress) progress(1.0, "done");
  return result;
}

}  // namespace

RefineResult refine(Mesh mesh, const Scheme& scheme, const RefineParams& params,
                    const ProgressFn& progress, const std::atomic<bool>* cancel,
                    const MemoryGrowFn& grow, std::optional<Features> features,
                    const BetweenLevelsFn& between_levels) {
  params.validate(scheme);
  check_face_budget(mesh.num_faces(), scheme, params);
  if (params.threads == 0)
    return run_levels(std::move(mesh), params, scheme, progress, cancel, grow, std::move(features),
                      between_levels);
  // A dedicated arena caps this request's threads without touching the global pool.
  tbb::task_arena arena(params.threads);
  return arena.execute([&] {
    return run_levels(std::move(mesh), params, scheme, progress, cancel, grow, std::move(features),
                      between_levels);
  });
}

RefineResult refine(Mesh mesh, const RefineParams& params, const ProgressFn& progress,
                    const std::atomic<bool>* cancel, const MemoryGrowFn& grow) {
  const std::unique_ptr<Scheme> scheme = make_scheme(params);
  return refine(std::move(mesh), *scheme, params, progress, cancel, grow);
}

}  // namespace stlrefine
