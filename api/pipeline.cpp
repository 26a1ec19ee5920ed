// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/pipeline.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <utility>

#include "api/ingest.h"
#include "api/memory_model.h"
#include "api/problem.h"
#include "api/repair_step.h"
#include "api/report.h"
#include "core/error.h"
#include "core/features/features.h"
#include "core/io/mesh_formats.h"
#include "core/io/stl.h"
#include "core/mesh/mesh_stats.h"
#include "core/parallel.h"
#include "core/schemes/lsf_curvature.h"
#include "core/schemes/registry.h"
#include "core/schemes/scheme.h"
#include "primitives/post_pass.h"
#include "primitives/regions.h"
#include "slicer/writers.h"

namespace stlrefine::api {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

// The core's budget check, rethrown with its numbers for the 422 body.
void refuse_over_face_budget(std::uint64_t faces, const Scheme& scheme,
                             const RefineParams& params) {
  try {
    check_face_budget(faces, scheme, params);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::BudgetExceeded) throw;
    throw FaceBudgetError(e, scheme.predict_faces(faces, params.levels), params.max_faces);
  }
}

nlohmann::ordered_json run_info(std::span<const std::uint8_t> bytes, const InfoRequest& request) {
  return run_info(bytes, request, false).report;
}

nlohmann::ordered_json run_info(std::span<const std::uint8_t> bytes, const InfoPlan& plan) {
  return run_info(bytes, plan.request, false).report;
}

InfoOutcome run_info(std::span<const std::uint8_t> bytes, const InfoRequest& request,
                     bool curvature_csv) {
  request.features.validate();
  Ingested in = ingest_mesh(bytes, request.weld_tolerance, request.units);
  repair_ingested(in, request.repair);
  const Mesh& mesh = in.result.mesh;
  const Features features = detect_features(mesh, request.features);
  const std::vector<VertexCurvature> curvatures = vertex_curvatures(mesh, features);
  InfoOutcome out;
  out.report = info_report(in, in.stats, features, request);
  out.report["curvature"] = curvature_summary_json(summarize(curvatures));
  if (curvature_csv) out.curvature_csv = curvature_table_csv(mesh, features, curvatures);
  return out;
}

namespace {

// run_refine; with `keep` and binary output, the STL is not written: the refined mesh is
// moved to *keep and the report gives the STL's size (84 + 50 n) and no write time. `shape`:
// the body's, from the plan (null: sniffed here when the slice's prediction needs it).
// `input`: the file already read (then `part`, when set, is the one object refined), else
// the body is read here.
RefineOutcome refine_outcome(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                             const Scheme& scheme, const StlShape* shape,
                             const ProgressFn& progress, const std::atomic<bool>* cancel,
                             const MemoryGrowFn& grow, Mesh* keep, const MeshInput* input = nullptr,
                             std::optional<std::size_t> part = std::nullopt) {
  const auto start = Clock::now();
  RefineTimes times;

  if (request.slice) request.slice->params.validate();
  Ingested in = input ? ingest_input(*input, request.weld_tolerance, request.units, part)
                      : ingest_mesh(bytes, request.weld_tolerance, request.units);
  repair_ingested(in, request.repair, cancel);
  times.ingest = in.seconds + in.repair.seconds;
  refuse_over_face_budget(in.result.mesh.num_faces(), scheme, request.refine);
  // The layer budget on the input's bounds, before any refinement work. (Refinement moves
  // the bounds a little; the refined mesh is planned again by the slicer itself.)
  if (request.slice) {
    try {
      slicer::plan_layers(in.result.mesh, request.slice->params);
    } catch (Error& e) {
      // The name this request used.
      if (e.field() == "layer_height") e.with_field(std::string(request.slice->layer_height_name));
      throw;
    }
  }

  // The post-pass keeps what it needs of the input (its triangles in an AABB tree, the
  // recognised regions) before the mesh is moved into refine. Its memory is asked for first,
  // as refine asks before its arrays grow (whole-request figures: the body, the input mesh,
  // the surface and region detection's peak); refused: MemoryBudgetError on `primitives`.
  auto phase = Clock::now();
  const PrimitiveOptions& prim = request.primitives;
  std::optional<primitives::RegionMap> regions;
  std::unique_ptr<primitives::InputSurface> surface;
  std::uint64_t surface_bytes = 0;
  std::optional<Features> features;  // detected once: for the surface, then refine's
  if (prim.post_pass()) {
    surface_bytes = primitives::InputSurface::predict_bytes(
        in.result.mesh.num_vertices(), in.result.mesh.num_faces(), prim.enabled);
    // With primitives, a copy of the input is held for the refinement without them (below).
    if (prim.enabled) surface_bytes += mesh_bytes(in.result.mesh);
    const std::uint64_t need = bytes.size() + mesh_bytes(in.result.mesh) + surface_bytes;
    if (grow && !grow(need)) throw MemoryBudgetError("primitives", 0, need);
    features = detect_features(in.result.mesh, request.refine.features);
    if (prim.enabled)
      regions = primitives::detect_regions(in.result.mesh, *features, {prim.tolerance});
    surface = std::make_unique<primitives::InputSurface>(in.result.mesh, *features,
                                                         regions ? &*regions : nullptr);
  }
  const bool with_regions = regions && !regions->regions.empty();
  std::optional<Mesh> input_copy;
  if (with_regions) input_copy = in.result.mesh;
  const double detect_seconds = seconds_since(phase);

  phase = Clock::now();
  const std::size_t input_faces = in.result.mesh.num_faces();
  // One refinement of `mesh` and its post-pass against `surf` (null: none); with `snaps`,
  // the new vertices of the surface's recognised regions go onto their primitives. `held`: bytes
  // held beside it for the whole run (the body, the surface, a result kept for comparison).
  struct Refined {
    RefineResult result;
    std::optional<primitives::PostPassReport> post;
    // An approximating scheme moves the input vertices on purpose (loop, sqrt3 with
    // alpha < 1): the default post-pass would undo that, so it runs there only when
    // max_deviation is given; otherwise it only measures (no snap, no bound), for the
    // report's figures.
    bool measure_only = false;
  };
  auto refine_and_pass = [&](Mesh mesh, std::optional<Features> mesh_features,
                             primitives::InputSurface* surf, bool snaps,
                             std::uint64_t held) -> Refined {
    // refine's figures are its own: what is held is beside them for the whole request.
    MemoryGrowFn refine_grow;
    if (grow) refine_grow = [&](std::uint64_t refining) { return grow(held + refining); };
    // With recognised primitives, each level's new vertices go onto them before the next
    // level is made from it (snapping the last level only, its points are made from points
    // off the surfaces: the snaps then scatter neighbours of a sliver apart and turn it).
    // With snaps, the deviation bound is applied once, after the last level.
    // Snaps that turn a face more than 60 degrees are taken back as a whole, and the levels
    // after are left alone (as the last level's post-pass does, apply_guarded).
    // Without snaps, an interpolating sqrt3 scheme's steps are held to the deviation bound
    // before the next is made from them: pulled after the last step only, sqrt3's later
    // slivers, made off the bound, were turned 60-90 degrees around the fixed input vertices
    // (issue 17 item 2: fans of slivers within 0.05-0.6 mm of an input vertex, a move that
    // cannot be affine over them); made from the pulled surface, they need little or no
    // pull. The 1-to-4 schemes turn no face with one pass after the last level (CAD-like
    // families, round 8 and 9), and a pass per level made their long refinements much
    // slower (8 M faces of butterfly under ASan: 47 s -> past 150 s), so they keep the one
    // pass.
    BetweenLevelsFn between_levels;
    bool snap_levels =
        surf && snaps && with_regions && scheme.interpolating() && !request.refine.adaptive();
    const bool one_to_three = scheme.predict_faces(1, 1) == 3;  // a sqrt3 step
    const bool pull_levels = surf && !snap_levels && scheme.interpolating() && one_to_three &&
                             !request.refine.adaptive() && prim.max_deviation != 0.0;
    // refine's own figure for a level's pass, as refine_grow takes it (the catch below adds
    // the body and the surface to a refusal's figure once).
    auto level_need = [](const Mesh& level_mesh) {
      return mesh_bytes(level_mesh) + 3 * sizeof(Vec3) * std::uint64_t{level_mesh.num_vertices()} +
             primitives::InputSurface::predict_apply_bytes(level_mesh.num_vertices());
    };
    if (snap_levels)
      between_levels = [&](Mesh& level_mesh, const Features& level_features, int level) {
        if (!snap_levels) return;
        const std::uint64_t need = level_need(level_mesh);
        if (refine_grow && !refine_grow(need)) throw MemoryBudgetError("primitives", level, need);
        primitives::PostPassParams pp;
        pp.refined_features = &level_features;
        pp.max_deviation = 0;  // snaps only
        pp.snap_inside_regions_only = true;
        BigVector<Vec3> made = level_mesh.mutable_positions();
        if (surf->apply(level_mesh, pp).faces_turned_over_60_deg > 0) {
          level_mesh.mutable_positions() = std::move(made);
          snap_levels = false;
        }
      };
    else if (pull_levels)
      between_levels = [&](Mesh& level_mesh, const Features& level_features, int level) {
        const std::uint64_t need = level_need(level_mesh);
        if (refine_grow && !refine_grow(need)) throw MemoryBudgetError("primitives", level, need);
        const CancelScope cancel_scope(cancel);
        primitives::PostPassParams pp;
        pp.refined_features = &level_features;
        pp.snap = false;
        pp.max_deviation = prim.max_deviation;
        surf->apply(level_mesh, pp);
      };
    Refined made;
    made.result = [&] {
      try {
        return refine(std::move(mesh), scheme, request.refine, progress, cancel, refine_grow,
                      std::move(mesh_features), between_levels);
      } catch (const MemoryBudgetError& e) {
        throw MemoryBudgetError(e.field(), e.level(), held + e.needed_bytes());
      }
    }();
    const bool measure_only =
        made.result.report.max_input_displacement > 0 && !prim.max_deviation_given;
    made.measure_only = measure_only;
    if (surf) {
      const CancelScope cancel_scope(cancel);  // a disconnect or deadline stops the pass too
      primitives::PostPassParams pp;
      pp.refined_features = &made.result.features;
      pp.snap = snaps && !measure_only;
      pp.max_deviation = measure_only ? std::optional<double>(0.0) : prim.max_deviation;
      // With snapping, two copies of the positions: the refinement's and the snapped ones.
      const std::uint64_t positions_bytes =
          pp.snap ? 2 * sizeof(Vec3) * std::uint64_t{made.result.mesh.num_vertices()} : 0;
      const std::uint64_t need =
          held + mesh_bytes(made.result.mesh) + positions_bytes +
          primitives::InputSurface::predict_apply_bytes(made.result.mesh.num_vertices());
      if (grow && !grow(need))
        throw MemoryBudgetError("primitives", made.result.report.levels, need);
      made.post = surf->apply_guarded(made.result.mesh, pp);
      made.result.features = Features{};  // the rest needs only the mesh
    }
    return made;
  };
  // The input mesh is not needed afterwards (the report only uses counters): move it in.
  Refined refined = refine_and_pass(std::move(in.result.mesh), std::move(features), surface.get(),
                                    prim.enabled, bytes.size() + surface_bytes);
  surface.reset();
  // Recognised primitives must never cost a fold: when the refinement with them still turns
  // faces more than 60 degrees from the input's (snaps between levels that each looked
  // right, the tight bound of a region at its border), or when the last level's snaps were
  // taken back (its levels were still made from snapped ones: on the CAD-like cones that
  // left 1-5 faces folded against the truth that the input's normals do not show), the
  // part is refined again without them, as primitives=off would. The answer is the run
  // without them unless the one with them turned fewer faces and kept its snaps.
  std::size_t withdrawn_turned = 0;
  if (input_copy && refined.post && !refined.measure_only &&
      (refined.post->faces_turned_over_60_deg > 0 || refined.post->withdrawn_turned_faces > 0)) {
    const std::size_t turned = refined.post->faces_turned_over_60_deg;
    const bool snaps_kept = refined.post->withdrawn_turned_faces == 0;
    // Held: the body, the input copy, the result with primitives (for the comparison) and
    // the surface without them; a budget that cannot hold the result drops it (off wins).
    const std::uint64_t plain_surface_bytes = primitives::InputSurface::predict_bytes(
        input_copy->num_vertices(), input_copy->num_faces(), false);
    std::uint64_t held = bytes.size() + mesh_bytes(*input_copy) + plain_surface_bytes;
    bool keep_first = !grow || grow(held + mesh_bytes(refined.result.mesh));
    if (keep_first)
      held += mesh_bytes(refined.result.mesh);
    else
      refined.result.mesh = Mesh{};
    std::optional<Features> plain_features = detect_features(*input_copy, request.refine.features);
    auto plain_surface =
        std::make_unique<primitives::InputSurface>(*input_copy, *plain_features, nullptr);
    Refined plain = refine_and_pass(std::move(*input_copy), std::move(plain_features),
                                    plain_surface.get(), false, held);
    if (!keep_first || !snaps_kept || plain.post->faces_turned_over_60_deg < turned) {
      withdrawn_turned = std::max(turned, refined.post->withdrawn_turned_faces);
      plain.post->seconds += refined.post->seconds;
      refined = std::move(plain);
    }
  }
  input_copy.reset();
  std::optional<primitives::PostPassReport>& post = refined.post;
  const bool measure_only = refined.measure_only;
  if (post) post->detect_seconds = detect_seconds;
  PrimitiveOptions reported = prim;
  if (measure_only) reported.max_deviation = 0;
  times.refine = seconds_since(phase);
  if (grow) {
    // The hierarchy is gone; the mesh, its STL (and contours) are what the rest holds.
    const StlShape sniffed = shape || !request.slice ? StlShape{} : stl_shape(bytes);
    const std::uint64_t rest =
        refined_memory_bytes(bytes, shape ? *shape : sniffed, request, input_faces,
                             refined.result.mesh.num_faces(), mesh_bytes(refined.result.mesh));
    if (!grow(rest))
      throw MemoryBudgetError(request.refine.adaptive() ? "max_level" : "levels",
                              refined.result.report.levels, rest);
  }

  phase = Clock::now();
  RefineOutcome out;
  const bool stream = keep && request.output_format == StlFormat::Binary;
  if (!stream) out.stl = write_stl(refined.result.mesh, request.output_format);
  const std::size_t stl_size =
      stream ? binary_stl_size(refined.result.mesh.num_faces()) : out.stl.size();
  times.write = seconds_since(phase);
  slicer::SliceStats slice_stats;
  if (request.slice)
    out.contours =
        slice_to_string(refined.result.mesh, *request.slice, &slice_stats, progress, cancel);
  times.total = seconds_since(start);
  out.report = refine_report(in, refined.result.report, request, stl_size, times);
  if (post && !measure_only) {
    out.report["primitives"] =
        primitives_report_json(regions ? &*regions : nullptr, *post, request.primitives);
    if (withdrawn_turned > 0)
      out.report["primitives"]["withdrawn"] =
          "with the primitives the part turned " + std::to_string(withdrawn_turned) +
          " faces more than 60 degrees from the input's (thin faces along rims): it was "
          "refined again without them, as primitives=off, which turned " +
          std::to_string(post->faces_turned_over_60_deg) +
          "; the regions are listed, nothing was snapped";
    else if (post->withdrawn_turned_faces > 0)
      out.report["primitives"]["withdrawn"] =
          "the snaps turned " + std::to_string(post->withdrawn_turned_faces) +
          " faces more than 60 degrees (thin faces along rims): not applied; the regions are "
          "listed, the output has the deviation bound alone";
  } else {
    out.report["primitives"] = primitives_report_json(nullptr, {}, request.primitives);
    if (measure_only)
      out.report["primitives"]["skipped"] =
          "approximating scheme (input vertices moved): nothing snapped or pulled back, the "
          "deviation is only measured; give max_deviation to bound it";
  }
  if (post) out.report["deviation"] = deviation_report_json(*post, reported);
  if (request.slice)
    out.report["slice"] = slice_stats_json(slice_stats, *request.slice, out.contours->size());
  if (stream) *keep = std::move(refined.result.mesh);
  return out;
}

// mesh_format=3mf: each object of the file refined on its own through refine_outcome (the
// same budgets, post-pass and report as a one-part file; refining the merged mesh would
// need every face's object carried through every scheme), then one 3MF object each, in mm.
// The report is the first object's with the faces summed and `objects` listing each one's.
RefineOutcome refine_3mf(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const Scheme& scheme, const StlShape* shape, const ProgressFn& progress,
                         const std::atomic<bool>* cancel, const MemoryGrowFn& grow) {
  const auto start = Clock::now();
  const MeshInput input = read_mesh(bytes);
  RefineRequest one = request;
  one.output_format = StlFormat::Binary;  // the meshes are kept, never written as STL
  const std::size_t n = input.parts.size();
  const std::uint64_t input_bytes = sizeof(float) * std::uint64_t{input.soup.coords.capacity()};
  std::uint64_t done_bytes = 0;  // the objects refined so far, held until the 3MF is made
  std::vector<Mesh> meshes(n);
  std::vector<nlohmann::ordered_json> reports;
  for (std::size_t i = 0; i < n; ++i) {
    MemoryGrowFn part_grow;
    if (grow) part_grow = [&](std::uint64_t b) { return grow(b + input_bytes + done_bytes); };
    ProgressFn part_progress;
    if (progress)
      part_progress = [&, i](double f, std::string_view stage) {
        progress((static_cast<double>(i) + f) / static_cast<double>(n), stage);
      };
    RefineOutcome o =
        refine_outcome(bytes, one, scheme, shape, part_progress, cancel, part_grow, &meshes[i],
                       &input, n > 1 ? std::optional<std::size_t>(i) : std::nullopt);
    done_bytes += mesh_bytes(meshes[i]);
    reports.push_back(std::move(o.report));
  }
  std::vector<NamedMesh> named;
  for (std::size_t i = 0; i < n; ++i)
    named.push_back({input.parts[i].name.empty() ? "part" : input.parts[i].name, &meshes[i]});
  const auto write_start = Clock::now();
  RefineOutcome out;
  out.stl = write_3mf(named, "millimeter");
  const double write_seconds = seconds_since(write_start);
  out.report = reports.front();
  if (n > 1) {
    std::uint64_t in_faces = 0, out_faces = 0, out_vertices = 0;
    nlohmann::ordered_json objects = nlohmann::ordered_json::array();
    for (std::size_t i = 0; i < n; ++i) {
      in_faces += reports[i]["input"].value("faces", 0ull);
      out_faces += reports[i]["output"].value("faces", 0ull);
      out_vertices += reports[i]["output"].value("vertices", 0ull);
      // The first 10 objects only: the report may travel in a header.
      if (i >= 10) continue;
      objects.push_back({{"name", named[i].name},
                         {"input_faces", reports[i]["input"]["faces"]},
                         {"output_faces", reports[i]["output"]["faces"]},
                         {"report", std::move(reports[i])}});
    }
    out.report["input"]["faces"] = in_faces;
    out.report["output"]["vertices"] = out_vertices;
    out.report["output"]["faces"] = out_faces;
    out.report["objects"] = std::move(objects);
  }
  out.report["output"]["format"] = "3mf";
  out.report["output"]["unit"] = "millimeter";
  out.report["output"]["objects"] = n;
  out.report["output"]["bytes"] = out.stl.size();
  out.report["seconds"]["write"] = write_seconds;
  out.report["seconds"]["total"] = seconds_since(start);
  return out;
}

// Every run_refine variant: the mesh format decides (3MF: made whole, never streamed).
RefineOutcome refine_any(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const Scheme& scheme, const StlShape* shape, const ProgressFn& progress,
                         const std::atomic<bool>* cancel, const MemoryGrowFn& grow, Mesh* keep) {
  if (request.mesh_format == MeshFormat::ThreeMf)
    return refine_3mf(bytes, request, scheme, shape, progress, cancel, grow);
  return refine_outcome(bytes, request, scheme, shape, progress, cancel, grow, keep);
}

}  // namespace

RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const ProgressFn& progress, const std::atomic<bool>* cancel,
                         const MemoryGrowFn& grow) {
  // A bad parameter is reported before the file is read.
  const std::unique_ptr<Scheme> scheme = make_scheme(request.refine);
  return refine_any(bytes, request, *scheme, nullptr, progress, cancel, grow, nullptr);
}

RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefinePlan& plan,
                         const ProgressFn& progress, const std::atomic<bool>* cancel,
                         const MemoryGrowFn& grow) {
  return refine_any(bytes, plan.request, *plan.scheme, &plan.shape, progress, cancel, grow,
                    nullptr);
}

RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const Scheme& scheme, const ProgressFn& progress,
                         const std::atomic<bool>* cancel, const MemoryGrowFn& grow) {
  return refine_any(bytes, request, scheme, nullptr, progress, cancel, grow, nullptr);
}

RefinedMesh run_refine_to_mesh(std::span<const std::uint8_t> bytes, const RefinePlan& plan,
                               const ProgressFn& progress, const std::atomic<bool>* cancel,
                               const MemoryGrowFn& grow) {
  RefinedMesh out;
  out.outcome =
      refine_any(bytes, plan.request, *plan.scheme, &plan.shape, progress, cancel, grow, &out.mesh);
  return out;
}

RefinedMesh run_refine_to_mesh(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                               const ProgressFn& progress, const std::atomic<bool>* cancel,
                               const MemoryGrowFn& grow) {
  const std::unique_ptr<Scheme> scheme = make_scheme(request.refine);
  RefinedMesh out;
  out.outcome = refine_any(bytes, request, *scheme, nullptr, progress, cancel, grow, &out.mesh);
  return out;
}

std::string slice_to_string(const Mesh& mesh, const SliceOptions& options,
                            slicer::SliceStats* stats, const ProgressFn& progress,
                            const std::atomic<bool>* cancel) {
  const std::unique_ptr<slicer::LayerWriter> writer =
      slicer::make_writer(options.format, options.writer);
  std::string out;
  const slicer::SliceStats s = slicer::write_slices(
      mesh, options.params, *writer, [&out](std::string_view bytes) { out.append(bytes); },
      progress, cancel);
  if (stats) *stats = s;
  return out;
}

SliceOutcome run_slice(std::span<const std::uint8_t> bytes, const SlicePlan& plan,
                       const ProgressFn& progress, const std::atomic<bool>* cancel) {
  return run_slice(bytes, plan.request, progress, cancel);
}

SliceOutcome run_slice(std::span<const std::uint8_t> bytes, const SliceRequest& request,
                       const ProgressFn& progress, const std::atomic<bool>* cancel) {
  const auto start = Clock::now();
  request.slice.params.validate();  // a bad parameter is reported before the file is read
  request.slice.writer.validate();
  Ingested in = ingest_mesh(bytes, request.weld_tolerance, request.units);
  repair_ingested(in, request.repair, cancel);
  SliceOutcome out;
  slicer::SliceStats stats;
  out.contours = slice_to_string(in.result.mesh, request.slice, &stats, progress, cancel);
  out.report = slice_report(in, stats, request, out.contours.size(), seconds_since(start));
  return out;
}

}  // namespace stlrefine::api
