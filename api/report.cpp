// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/report.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>

#include "slicer/writers.h"

namespace stlrefine::api {

namespace {

using Json = nlohmann::ordered_json;

Json vec3_json(const Vec3& v) {
  return Json::array({v.x, v.y, v.z});
}

Json repair_json(const Ingested& in);
Json bodies_json(const MeshStats& s);

Json input_json(const Ingested& in) {
  Json j;
  j["format"] = to_string(in.format);
  j["file_format"] = to_string(in.file_format);
  if (in.file_format == MeshFormat::ThreeMf || in.parts.size() > 1) {
    // The first 10 only: the report may travel in a header (a 3MF can have 100k objects).
    constexpr std::size_t kListed = 10;
    Json objects = Json::array();
    for (std::size_t i = 0; i < in.parts.size() && i < kListed; ++i)
      objects.push_back({{"name", in.parts[i].name}, {"triangles", in.parts[i].triangle_count}});
    j["objects"] = std::move(objects);
    j["object_count"] = in.parts.size();
  }
  j["triangles"] = in.triangles;
  j["trailing_bytes"] = in.trailing_bytes;
  j["vertices_before_weld"] = 3 * in.triangles;
  j["vertices_after_weld"] = in.welded_vertices;
  j["weld_tolerance"] = in.weld_tolerance;
  const UnitsReport& u = in.units;
  j["units"] = {{"units", to_string(u.units)},
                {"assumed", u.assumed},
                {"scale", u.scale},
                {"factor_to_mm", u.factor},
                {"size_mm", vec3_json(u.size_mm)}};
  if (u.declared) j["units"]["declared"] = *u.declared;  // the file's own unit, applied
  j["repair"] = repair_json(in);
  j["bodies"] = in.stats.components;
  j["watertight"] = in.stats.watertight;
  j["largest_bodies"] = bodies_json(in.stats);
  return j;
}

// What a caller should look at before printing: one {code, message} per finding, about
// the mesh as it is worked on (after `repair`).
Json warnings_json(const Ingested& in) {
  Json list = Json::array();
  const auto warn = [&](const char* code, std::string message) {
    list.push_back({{"code", code}, {"message", std::move(message)}});
  };
  if (in.units.warning) warn("suspicious_units", *in.units.warning);
  const MeshStats& s = in.stats;
  if (s.boundary_loops > 0) {
    std::string message = std::to_string(s.boundary_loops) + " hole(s) (" +
                          std::to_string(s.boundary_edges) +
                          " open boundary edges): the part is not watertight and does not print "
                          "as a solid";
    if (in.repair_mode == repair::RepairMode::None)
      message += "; repair=fill_holes closes them";
    else if (in.repair.skipped)
      message +=
          "; repair=fill_holes could not run on this mesh: it has non-manifold edges "
          "cut apart at ingest";
    else if (in.repair.left_open > 0)
      message += "; " + std::to_string(in.repair.left_open) +
                 " were left open by repair=fill_holes (rim over 10000 edges, or no Delaunay "
                 "triangulation of it)";
    warn("open_boundaries", std::move(message));
  }
  const IngestReport& r = in.result.report;
  if (r.non_manifold_edges > 0)
    warn("non_manifold_edges_cut",
         std::to_string(r.non_manifold_edges) +
             " edge(s) shared by more than two facets were cut apart (each sheet keeps its own "
             "copy, a sharp boundary)");
  if (r.faces_reoriented > 0)
    warn("facets_reoriented", std::to_string(r.faces_reoriented) +
                                  " facet(s) wound against their neighbours were turned over");
  if (s.components > 1)
    warn("several_bodies", std::to_string(s.components) +
                               " separate bodies: each is refined on its own; see bodies[] for "
                               "the largest");
  if (in.repair_mode == repair::RepairMode::FillHoles && in.repair.fairing_failed > 0)
    warn("hole_fairing_failed", std::to_string(in.repair.fairing_failed) +
                                    " filled hole(s) could not be faired and were left flat");
  return list;
}

// The largest bodies (compute_stats lists at most 10: the report may travel in a header).
Json bodies_json(const MeshStats& s) {
  Json list = Json::array();
  for (const BodyStats& b : s.bodies)
    list.push_back({{"faces", b.faces},
                    {"vertices", b.vertices},
                    {"volume", b.volume},
                    {"area", b.area},
                    {"watertight", b.watertight},
                    {"genus", b.genus ? Json(*b.genus) : Json(nullptr)},
                    {"holes", b.boundary_loops},
                    {"bbox", {{"min", vec3_json(b.bbox_min)}, {"max", vec3_json(b.bbox_max)}}}});
  return list;
}

Json repair_json(const Ingested& in) {
  Json j;
  j["mode"] = repair::to_string(in.repair_mode);
  if (in.repair_mode == repair::RepairMode::None) return j;
  const repair::HoleFillReport& r = in.repair;
  j["holes"] = r.holes;
  j["filled"] = r.filled;
  if (r.skipped) j["skipped"] = "edges cut apart at ingest (non-manifold input): not repaired";
  j["fairing_failed"] = r.fairing_failed;
  j["flat"] = r.flat;
  j["left_open"] = r.left_open;
  j["largest_hole_edges"] = r.largest_hole_edges;
  j["faces_added"] = r.faces_added;
  j["vertices_added"] = r.vertices_added;
  j["seconds"] = r.seconds;
  return j;
}

Json distribution_json(const Distribution& d, bool any) {
  if (!any) return Json(nullptr);
  return Json{{"min", d.min}, {"p05", d.p05}, {"p50", d.p50}, {"p95", d.p95}, {"max", d.max}};
}

void append_number(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace

Json curvature_summary_json(const CurvatureSummary& s) {
  const bool any = s.valid > 0;
  Json j;
  j["valid"] = s.valid;
  j["invalid"] = s.invalid;
  j["gaussian"] = distribution_json(s.gaussian, any);
  j["mean"] = distribution_json(s.mean, any);
  j["k1"] = distribution_json(s.k1, any);
  j["k2"] = distribution_json(s.k2, any);
  j["abs_max"] = distribution_json(s.abs_max, any);
  return j;
}

std::string curvature_table_csv(const Mesh& mesh, const Features& features,
                                std::span<const VertexCurvature> curvatures) {
  std::string out = "vertex,x,y,z,kind,gaussian,mean,k1,k2,valid\n";
  out.reserve(out.size() + 120 * curvatures.size());
  const auto positions = mesh.positions();
  for (std::size_t i = 0; i < curvatures.size() && i < positions.size(); ++i) {
    const VertexCurvature& c = curvatures[i];
    const Vec3& p = positions[i];
    out += std::to_string(i);
    for (double v : {p.x, p.y, p.z}) {
      out += ',';
      append_number(out, v);
    }
    out += ',';
    out += to_string(features.kind(VertexId(static_cast<std::uint32_t>(i))));
    for (double v : {c.gaussian, c.mean, c.k1, c.k2}) {
      out += ',';
      append_number(out, v);
    }
    out += c.valid ? ",1\n" : ",0\n";
  }
  return out;
}

Json ingest_report_json(const IngestReport& r) {
  Json j;
  j["input_triangles"] = r.input_triangles;
  j["input_vertices"] = r.input_vertices;
  j["index_degenerate_removed"] = r.index_degenerate_removed;
  j["zero_area_faces"] = r.zero_area_faces;
  j["isolated_vertices_removed"] = r.isolated_vertices_removed;
  j["non_manifold_edges"] = r.non_manifold_edges;
  j["non_manifold_vertices"] = r.non_manifold_vertices;
  j["vertices_duplicated"] = r.vertices_duplicated;
  j["faces_reoriented"] = r.faces_reoriented;
  j["non_orientable_cuts"] = r.non_orientable_cuts;
  j["inconsistent_edges"] = r.inconsistent_edges;
  return j;
}

Json info_report(const Ingested& in, const MeshStats& s, const Features& features,
                 const InfoRequest& request) {
  Json mesh;
  mesh["vertices"] = s.vertices;
  mesh["edges"] = s.edges;
  mesh["faces"] = s.faces;
  mesh["boundary_edges"] = s.boundary_edges;
  mesh["boundary_loops"] = s.boundary_loops;
  mesh["components"] = s.components;
  mesh["zero_area_faces"] = s.zero_area_faces;
  mesh["euler_characteristic"] = s.euler_characteristic;
  mesh["watertight"] = s.watertight;
  mesh["genus"] = s.genus ? Json(*s.genus) : Json(nullptr);  // summed over the bodies
  mesh["bodies"] = bodies_json(s);
  mesh["bbox"] = {{"min", vec3_json(s.bbox_min)}, {"max", vec3_json(s.bbox_max)}};
  mesh["area"] = s.area;
  mesh["volume"] = s.volume;

  Json feat;
  feat["crease_mode"] = to_string(request.features.crease_mode);
  feat["crease_angle_deg"] = request.features.crease_angle_deg;  // used in angle mode only
  feat["sharp_edges"] = features.num_sharp_edges();
  feat["corners"] = features.count(VertexKind::Corner);
  feat["creases"] = features.count(VertexKind::Crease);
  feat["darts"] = features.count(VertexKind::Dart);

  Json j;
  j["input"] = input_json(in);
  j["warnings"] = warnings_json(in);
  j["ingest"] = ingest_report_json(in.result.report);
  j["mesh"] = std::move(mesh);
  j["features"] = std::move(feat);
  return j;
}

Json refine_report(const Ingested& in, const RefineReport& r, const RefineRequest& request,
                   std::size_t output_bytes, const RefineTimes& times) {
  Json input = input_json(in);
  input["vertices"] = r.input_vertices;
  input["faces"] = r.input_faces;

  Json j;
  j["scheme"] = r.scheme;
  j["levels"] = r.levels;
  j["crease_mode"] = to_string(request.refine.features.crease_mode);
  j["crease_angle_deg"] = request.refine.features.crease_angle_deg;  // used in angle mode only
  j["input"] = std::move(input);
  Json warnings = warnings_json(in);
  if (request.refine.adaptive() && r.output_faces == r.input_faces)
    warnings.push_back(
        {{"code", "adaptive_refined_nothing"},
         {"message", "the adaptive criteria (adaptive_tol " + std::to_string(r.adaptive_tol) +
                         " mm, adaptive_angle " + std::to_string(r.adaptive_angle) +
                         " deg) refined no face of this part: every chord is already within "
                         "them (is the part in mm? see input.units)"}});
  j["warnings"] = std::move(warnings);
  j["output"] = {{"format", to_string(request.output_format)},
                 {"vertices", r.output_vertices},
                 {"faces", r.output_faces},
                 {"bytes", output_bytes}};
  j["features"] = {{"sharp_edges_in", r.sharp_edges_in},
                   {"sharp_edges_out", r.sharp_edges_out},
                   {"corners", r.corners},
                   {"creases", r.creases},
                   {"darts", r.darts}};
  j["fold_fallbacks"] = r.fold_fallbacks;
  j["adaptive_tol"] = r.adaptive_tol;
  j["adaptive_angle"] = r.adaptive_angle;
  j["edges_over_tolerance"] = r.edges_over_tolerance;
  j["faces_over_criterion"] = r.faces_over_criterion;
  if (!r.stop_reason.empty()) {
    // Adaptive mode: why it stopped, and (at the cap) how far off and where.
    Json stop = {{"reason", r.stop_reason}};
    if (r.stop_reason == "max_level" && (r.edges_over_tolerance > 0 || r.max_over_tolerance > 0)) {
      stop["max_over_tolerance_mm"] = r.max_over_tolerance;
      stop["worst_at"] = vec3_json(r.worst_over_tolerance_at);
      if (r.edges_over_tolerance > 0) stop["edges_not_converging"] = r.edges_not_converging;
    }
    j["adaptive_stop"] = std::move(stop);
  }
  j["max_input_displacement"] = r.max_input_displacement;
  j["seconds"] = {{"ingest", times.ingest},
                  {"refine", times.refine},
                  {"write", times.write},
                  {"total", times.total}};
  j["ingest"] = ingest_report_json(in.result.report);
  return j;
}

Json primitives_report_json(const primitives::RegionMap* regions,
                            const primitives::PostPassReport& post,
                            const PrimitiveOptions& options) {
  Json j;
  j["mode"] = options.enabled ? "auto" : "off";
  j["tolerance"] = options.tolerance;
  if (!regions) return j;
  j["tolerance_mm"] = regions->tolerance;
  j["regions_found"] = regions->regions.size();
  std::size_t faces = 0;
  for (const primitives::Region& r : regions->regions) faces += r.faces;
  j["faces_in_regions"] = faces;
  std::vector<std::size_t> order(regions->regions.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return regions->regions[a].faces > regions->regions[b].faces;
  });
  // The report travels in a response header (X-Stlrefine-Report, at most 8 KiB a line in
  // cpp-httplib): the largest regions only.
  constexpr std::size_t kListed = 10;
  if (order.size() > kListed) order.resize(kListed);
  Json list = Json::array();
  for (std::size_t i : order) {
    const primitives::Region& r = regions->regions[i];
    const primitives::Primitive& p = r.primitive;
    Json e;
    e["type"] = primitives::to_string(p.type);
    e["point"] = vec3_json(p.point);
    if (p.type != primitives::PrimitiveType::Sphere) e["axis"] = vec3_json(p.axis);
    if (p.type == primitives::PrimitiveType::Sphere ||
        p.type == primitives::PrimitiveType::Cylinder || p.type == primitives::PrimitiveType::Torus)
      e["radius"] = p.radius;
    if (p.type == primitives::PrimitiveType::Torus) e["minor_radius"] = p.minor;
    if (p.type == primitives::PrimitiveType::Cone)
      e["half_angle_deg"] = p.angle * 180 / std::numbers::pi;
    e["faces"] = r.faces;
    e["vertices"] = r.vertices;
    e["max_residual"] = r.max_residual;
    e["grown"] = r.grown;
    list.push_back(std::move(e));
  }
  j["regions"] = std::move(list);
  j["snapped"] = post.snapped;
  j["snapped_to_curve"] = post.snapped_to_curve;
  j["snap_refused"] = post.snap_refused;
  j["snaps_reverted"] = post.snaps_reverted;
  j["max_snap_move"] = post.max_snap_move;
  return j;
}

Json deviation_report_json(const primitives::PostPassReport& post,
                           const PrimitiveOptions& options) {
  Json j;
  if (!options.max_deviation) {
    j["bound"] = "auto";
  } else if (*options.max_deviation > 0) {
    j["bound"] = *options.max_deviation;
  } else {
    j["bound"] = "off";
  }
  j["max_bound"] = post.max_bound;
  j["checked_vertices"] = post.vertices_checked;
  j["max_distance_from_input"] = post.max_distance;
  j["max_distance_before"] = post.max_distance_before;
  j["pulled_back"] = post.pulled_back;
  j["max_pull_back"] = post.max_pull_back;
  j["worst_normal_change_deg"] = post.worst_normal_change_deg;
  j["faces_turned_over_60_deg"] = post.faces_turned_over_60_deg;
  j["detect_seconds"] = post.detect_seconds;
  j["seconds"] = post.seconds;
  return j;
}

Json slice_stats_json(const slicer::SliceStats& stats, const SliceOptions& options,
                      std::size_t bytes) {
  const slicer::SliceParams& p = options.params;
  Json j;
  j["format"] = slicer::to_string(options.format);
  j["layer_height"] = p.heights.empty() ? Json(p.layer_height) : Json(nullptr);
  j["z_min"] = p.z_min ? Json(*p.z_min) : Json(nullptr);
  j["z_max"] = p.z_max ? Json(*p.z_max) : Json(nullptr);
  j["layers"] = stats.layers;
  j["outer_loops"] = stats.outer_loops;
  j["holes"] = stats.holes;
  j["open_polylines"] = stats.open_polylines;
  j["points"] = stats.points;
  j["degenerate_loops"] = stats.degenerate_loops;
  j["reversed_loops"] = stats.reversed_loops;
  j["bytes"] = bytes;
  j["seconds"] = stats.seconds;
  return j;
}

Json slice_report(const Ingested& in, const slicer::SliceStats& stats, const SliceRequest& request,
                  std::size_t bytes, double total_seconds) {
  Json input = input_json(in);
  input["vertices"] = in.result.mesh.num_vertices();
  input["faces"] = in.result.mesh.num_faces();
  Json j;
  j["input"] = std::move(input);
  j["warnings"] = warnings_json(in);
  j["slice"] = slice_stats_json(stats, request.slice, bytes);
  j["seconds"] = {{"ingest", in.seconds}, {"slice", stats.seconds}, {"total", total_seconds}};
  j["ingest"] = ingest_report_json(in.result.report);
  return j;
}

}  // namespace stlrefine::api
