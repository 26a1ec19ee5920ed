// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// stlrefine_fidelity: how close LSF, our butterfly and OpenMesh's modified butterfly come
// to the true surface of coarse, irregularly triangulated known shapes (issue 4, item 6),
// and the paper's section-curve undulation test on the cylinder. With --cad-families: every
// scheme on the CAD-like families of tests/support/cad_like.h over many seeds (issue 17).
// Hand-run (bench/fidelity/README.md): Markdown tables to stdout, the plot to an SVG file.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "bench/fidelity/cad_families.h"
#include "bench/fidelity/metrics.h"
#include "bench/fidelity/openmesh_butterfly.h"
#include "bench/fidelity/runs.h"
#include "bench/fidelity/section.h"
#include "bench/fidelity/shapes.h"
#include "bench/fidelity/svg_plot.h"
#include "core/features/features.h"
#include "core/mesh/build_mesh.h"
#include "core/schemes/registry.h"

namespace fid = stlrefine::fidelity;
using stlrefine::Mesh;
using stlrefine::VertexId;

namespace {

struct Options {
  std::vector<std::string> schemes{"lsf", "butterfly", "sqrt3-interp"};
  std::vector<int> levels{1, 2, 3};
  std::vector<double> adaptive_tols;
  int max_level = 3;
  bool openmesh = true;
  std::vector<std::string> shapes{"cylinder", "sphere", "torus", "tube"};
  fid::RunSettings run;
  std::size_t samples = 200'000;
  double window = 2.0;
  int plot_level = 3;
  bool plot_openmesh = false;
  std::string svg = "undulation.svg";
};

struct Row {
  fid::Variant variant;
  int level = 0;  //!< 0 for the input row
  fid::Metrics m;
  double seconds = 0;
  std::size_t fold_fallbacks = 0;
  bool ours = false;
  std::string note;
  std::optional<fid::SectionStats> section;
};

std::string num(double v, int digits = 3) {
  if (v < 0) return "–";
  char buf[48];
  if (v != 0 && (std::abs(v) < 1e-3 || std::abs(v) >= 1e5))
    std::snprintf(buf, sizeof buf, "%.2e", v);
  else
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

//! A cap or rim deviation; "none left" when the shape has caps (rims) but the refined mesh
//! has no vertex that is recognisably on one (the crease was rounded away).
std::string cap_or_rim(double value, std::size_t count, int digits) {
  if (value >= 0 && count == 0) return "none left";
  return num(value, digits);
}

//! "valence 3: 2, 4: 16, ..." over the input mesh.
std::string valence_summary(const Mesh& mesh) {
  std::map<int, int> hist;
  for (std::uint32_t v = 0; v < mesh.num_vertices(); ++v) ++hist[mesh.valence(VertexId(v))];
  std::string s;
  for (const auto& [val, count] : hist)
    s += (s.empty() ? "" : ", ") + std::to_string(val) + ": " + std::to_string(count);
  return s;
}

void print_table(const std::vector<Row>& rows) {
  std::cout << "| scheme | level | faces | RMS mm | RMS / input | max mm | normal RMS ° | normal "
               "max ° | cap dev mm | rim dev mm | sharp edges | folds | fold fallbacks | time ms "
               "|\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  const double input_rms = rows.front().m.rms;
  for (const Row& r : rows) {
    if (!r.note.empty()) {
      std::cout << "| " << r.variant.label() << " | " << r.level << " | | | | | | | | | | | | "
                << r.note << " |\n";
      continue;
    }
    std::cout << "| " << (r.level == 0 ? std::string("input") : r.variant.label()) << " | "
              << r.level << " | " << r.m.faces << " | " << num(r.m.rms, 4) << " | "
              << num(r.m.rms / input_rms, 3) << " | " << num(r.m.max, 4) << " | "
              << num(r.m.normal_rms_deg, 2) << " | " << num(r.m.normal_max_deg, 2) << " | "
              << cap_or_rim(r.m.cap_max, r.m.cap_vertices, 3) << " | "
              << cap_or_rim(r.m.rim_max, r.m.rim_vertices, 4) << " | " << r.m.sharp_edges << " | "
              << r.m.folds << " | "
              << (r.ours ? std::to_string(r.fold_fallbacks) : std::string("–")) << " | "
              << (r.level == 0 ? std::string("–") : num(r.seconds * 1e3, 2)) << " |\n";
  }
}

void print_section_table(const fid::Shape& shape, const std::vector<Row>& rows, double window) {
  std::cout
      << "\nSection z = " << shape.section_z.value_or(0) << " mm (a circle of radius "
      << shape.section_radius << "), curvature window " << window
      << " mm:\n\n| scheme | level | loops | points | tangent dev RMS ° | tangent dev max ° "
         "| tangent dev max, "
      << window
      << " mm average ° | κr−1 RMS | κr−1 max | κr total variation | Σ|turn| / 2π | radius dev mm "
         "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Row& r : rows) {
    if (!r.section) continue;
    const fid::SectionStats& s = *r.section;
    std::cout << "| " << (r.level == 0 ? std::string("input") : r.variant.label()) << " | "
              << r.level << " | " << s.curves << " | " << s.points << " | "
              << num(s.tangent_rms_deg, 3) << " | " << num(s.tangent_max_deg, 3) << " | "
              << num(s.tangent_smoothed_max_deg, 3) << " | " << num(s.curvature_rms, 4) << " | "
              << num(s.curvature_max, 4) << " | " << num(s.curvature_variation, 3) << " | "
              << num(s.absolute_turning, 4) << " | " << num(s.radius_max_dev, 4) << " |\n";
  }
}

//! The targets after 2 levels, in words.
void print_verdict(const std::vector<Row>& rows, double crease_sharp_in) {
  const Row* input = &rows.front();
  const Row* bf2 = nullptr;
  for (const Row& r : rows)
    if (r.note.empty() && r.variant.kind == fid::Variant::Kind::Ours &&
        r.variant.scheme == "butterfly" && r.level == 2)
      bf2 = &r;
  std::cout << "\nTargets after 2 levels (RMS <= input/2 = " << num(input->m.rms / 2, 4)
            << " mm and <= our butterfly's; 0 folds; caps planar; rims on their circles):\n\n";
  for (const Row& r : rows) {
    if (!r.note.empty() || r.level != 2 || r.variant.kind == fid::Variant::Kind::OpenMeshButterfly)
      continue;
    std::vector<std::string> missed;
    if (r.m.rms > input->m.rms / 2)
      missed.push_back("RMS " + num(r.m.rms / input->m.rms, 3) + "x input");
    if (bf2 && r.m.rms > bf2->m.rms * (1 + 1e-9))
      missed.push_back("RMS " + num(r.m.rms / bf2->m.rms, 3) + "x butterfly's");
    if (r.m.folds > 0) missed.push_back(std::to_string(r.m.folds) + " folds");
    if (r.m.cap_max > 1e-9) missed.push_back("cap off its plane by " + num(r.m.cap_max) + " mm");
    // Two steps cut each rim edge into 4 (1-to-4: 16x the faces) or 3 (sqrt3: 9x the faces,
    // sharp edges trisected every second step); other growths are not judged.
    const double growth = double(r.m.faces) / double(input->m.faces);
    const double pieces = growth == 16 ? 4 : growth == 9 ? 3 : 0;
    if (crease_sharp_in > 0 && double(r.m.sharp_edges) < crease_sharp_in * pieces)
      missed.push_back("rim edges lost sharpness (" + std::to_string(r.m.sharp_edges) + " sharp)");
    std::cout << "- " << r.variant.label() << ": "
              << (missed.empty() ? std::string("all met") : "missed: ");
    for (std::size_t i = 0; i < missed.size(); ++i) std::cout << (i ? "; " : "") << missed[i];
    if (r.m.rim_max >= 0)
      std::cout << " (rim vertices up to " << num(r.m.rim_max, 4) << " mm off their circle)";
    std::cout << "\n";
  }
}

//! Where the largest error of each level-2 row is, against the input vertex nearest to it.
void print_worst(const Mesh& input, const std::vector<Row>& rows) {
  std::cout << "\nLargest distance after 2 levels, and the nearest input vertex (valence):\n\n";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    if (!r.note.empty() || r.level != 2) continue;
    const stlrefine::Vec3 p = r.m.worst_point;
    std::uint32_t best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::uint32_t v = 0; v < input.num_vertices(); ++v) {
      const double d = stlrefine::distance(input.position(VertexId(v)), p);
      if (d < best_d) best_d = d, best = v;
    }
    const auto q = input.position(VertexId(best));
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "- %s: %.4f mm at (%.2f, %.2f, %.2f), azimuth %.1f°, rho %.3f; %.2f mm from "
                  "input vertex %u (%.2f, %.2f, %.2f), valence %d",
                  r.variant.label().c_str(), r.m.max, p.x, p.y, p.z,
                  std::fmod(std::atan2(p.y, p.x) * 180 / std::numbers::pi + 360, 360),
                  std::hypot(p.x, p.y), best_d, best, q.x, q.y, q.z, input.valence(VertexId(best)));
    std::cout << buf << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stlrefine_fidelity: refined meshes of known shapes against the true surface"};
  Options o;
  app.add_option("--schemes", o.schemes, "our schemes to run (unknown ones are skipped)");
  app.add_option("--levels", o.levels, "uniform levels")->check(CLI::Range(1, 6));
  app.add_option("--adaptive-tol", o.adaptive_tols,
                 "adaptive rows for lsf and butterfly at these tolerances (mm)");
  app.add_option("--max-level", o.max_level, "level cap of the adaptive rows")
      ->check(CLI::Range(1, 6));
  app.add_option("--openmesh", o.openmesh, "add OpenMesh ModifiedButterflyT rows");
  app.add_option("--shapes", o.shapes, "cylinder, sphere, torus, tube");
  app.add_option("--crease-angle", o.run.crease_angle_deg, "degrees");
  app.add_option("--threads", o.run.threads, "threads for our schemes (OpenMesh uses 1)");
  app.add_option("--reps", o.run.reps, "time = median of this many runs")->check(CLI::Range(1, 50));
  app.add_option("--samples", o.samples, "about this many distance samples per mesh");
  app.add_option("--window", o.window, "curvature window along the section (mm)");
  app.add_option("--plot-level", o.plot_level, "level plotted in the SVG");
  app.add_option("--plot-openmesh", o.plot_openmesh,
                 "also plot OpenMesh (no crease rules: its rounded rims dominate the scale)");
  app.add_option("--svg", o.svg, "where to write the undulation plot");
  fid::CadOptions cad;
  bool cad_mode = false;
  app.add_flag("--cad-families", cad_mode,
               "instead: every scheme on the CAD-like families over many seeds (issue 17)");
  app.add_option("--families", cad.families,
                 "CAD-like families (default all): cylinder cone torus tube sphere ellipsoid "
                 "blob rounded-box plate");
  app.add_option("--seeds", cad.seeds, "CAD-like families: seeds per family")
      ->check(CLI::Range(1, 1000));
  app.add_option("--seed-base", cad.seed_base, "CAD-like families: the first seed");
  app.add_option("--coarseness", cad.coarseness, "CAD-like families: [0.25, 4]")
      ->check(CLI::Range(0.25, 4.0));
  app.add_option("--jobs", cad.jobs, "CAD-like families: seeds run in parallel")
      ->check(CLI::Range(1, 64));
  app.add_option("--param", cad.params,
                 "CAD-like families: name=value request parameter for every run of ours "
                 "(repeatable; e.g. primitives=auto, crease_angle=60)");
  app.add_option("--variant", cad.variants,
                 "CAD-like families: NAME:name=value,... a parameter set (repeatable). Without "
                 "scheme=, every scheme runs once per variant (rows 'scheme [NAME]', replacing "
                 "the plain rows); with scheme=X, one more row NAME");
  app.add_flag("--direct", cad.direct,
               "CAD-like families, diagnostic: our rows call refine() on the double-precision "
               "mesh (no STL rounding, no pipeline post-pass)");
  app.add_option("--out", cad.out_dir,
                 "CAD-like families: also write <family>.md, <family>.svg (error vs faces) and "
                 "all.md into this directory");
  CLI11_PARSE(app, argc, argv);

  if (cad_mode) {
    // The shared options keep their own defaults for this mode unless given.
    if (app.count("--schemes")) cad.schemes = o.schemes;
    if (app.count("--levels")) cad.levels = o.levels;
    if (app.count("--samples")) cad.samples = o.samples;
    cad.openmesh = o.openmesh;
    // Only when given: otherwise our rows run at the request default, as a user's would.
    if (app.count("--crease-angle")) cad.crease_angle_deg = o.run.crease_angle_deg;
    for (int i = 0; i < argc; ++i) cad.command += (i ? " " : "") + std::string(argv[i]);
    return fid::run_cad_families(cad);
  }

  // Our schemes that exist; the rest are noted and skipped.
  std::vector<std::string> schemes;
  for (const std::string& s : o.schemes) {
    const auto names = stlrefine::scheme_names();
    if (std::find(names.begin(), names.end(), s) != names.end())
      schemes.push_back(s);
    else
      std::cout << "> Note: scheme `" << s << "` does not exist in this build; skipped.\n";
  }
  if (o.openmesh && !fid::have_openmesh()) {
    std::cout << "> Note: built without OpenMesh; no ModifiedButterflyT rows.\n";
    o.openmesh = false;
  }

  std::vector<fid::Variant> variants;
  for (const std::string& s : schemes)
    for (int l : o.levels) variants.push_back({fid::Variant::Kind::Ours, s, l, 0});
  if (o.openmesh)
    for (int l : o.levels) variants.push_back({fid::Variant::Kind::OpenMeshButterfly, "", l, 0});
  for (double tol : o.adaptive_tols)
    for (const char* s : {"lsf", "butterfly"})
      variants.push_back({fid::Variant::Kind::OursAdaptive, s, o.max_level, tol});

  std::vector<fid::Panel> panels;
  for (const fid::Shape& shape : fid::all_shapes()) {
    if (std::find(o.shapes.begin(), o.shapes.end(), shape.name) == o.shapes.end()) continue;
    std::cerr << "[fidelity] " << shape.name << "\n";
    const Mesh input = stlrefine::build_mesh(shape.soup).mesh;
    const auto features = stlrefine::detect_features(input, {o.run.crease_angle_deg});
    std::cout << "\n### " << shape.name << "\n\n"
              << shape.description << ". Input: " << input.num_vertices() << " vertices, "
              << input.num_faces() << " faces; valences " << valence_summary(input) << "; "
              << features.num_sharp_edges() << " sharp edges at " << o.run.crease_angle_deg << "° ("
              << features.count(stlrefine::VertexKind::Corner) << " corners, "
              << features.count(stlrefine::VertexKind::Crease) << " crease, "
              << features.count(stlrefine::VertexKind::Dart) << " dart vertices).\n\n";

    std::vector<Row> rows;
    auto add_row = [&](Row row, const Mesh& mesh) {
      if (row.note.empty()) {
        row.m = fid::measure(mesh, shape.surface, o.run.crease_angle_deg, o.samples);
        if (shape.section_z)
          row.section = fid::analyse_section(fid::cut_horizontal(mesh, *shape.section_z),
                                             shape.section_radius, o.window);
      }
      rows.push_back(std::move(row));
    };
    add_row(Row{}, input);
    for (const fid::Variant& v : variants) {
      std::cerr << "[fidelity]   " << v.label() << " L" << v.level << "\n";
      fid::RunOutput out = fid::run_variant(v, input, o.run);
      Row row;
      row.variant = v;
      row.level = v.level;
      row.seconds = out.seconds;
      row.fold_fallbacks = out.fold_fallbacks;
      row.ours = v.kind != fid::Variant::Kind::OpenMeshButterfly;
      add_row(std::move(row), out.mesh);
    }
    print_table(rows);
    if (shape.section_z) print_section_table(shape, rows, o.window);
    print_verdict(rows, shape.name == "cylinder" ? double(features.num_sharp_edges()) : 0.0);
    print_worst(input, rows);

    // The plot: the cylinder's section, curvature and tangent deviation, at plot_level.
    if (shape.name != "cylinder") continue;
    fid::Panel curvature{"Curvature of the section z = " + num(*shape.section_z, 3) +
                             " mm of the irregular cylinder after " + std::to_string(o.plot_level) +
                             " levels (window " + num(o.window, 1) + " mm)",
                         "azimuth (degrees)",
                         "κ r (1 = the true circle)",
                         {},
                         1.0,
                         std::make_pair(0.0, 2.0),
                         0,
                         360};
    fid::Panel tangent{
        "Tangent deviation from the true circle (chord-length derivative, paper eq. 4), " +
            num(o.window, 1) + " mm average",
        "azimuth (degrees)",
        "degrees",
        {},
        0.0,
        {},
        0,
        360};
    const std::map<std::string, std::string> colours{{"lsf", "#1f77b4"},
                                                     {"butterfly", "#d62728"},
                                                     {"OpenMesh ModifiedButterflyT", "#2ca02c"},
                                                     {"sqrt3-interp", "#9467bd"}};
    for (const Row& r : rows) {
      if (!r.section || r.level != o.plot_level ||
          r.variant.kind == fid::Variant::Kind::OursAdaptive ||
          (r.variant.kind == fid::Variant::Kind::OpenMeshButterfly && !o.plot_openmesh))
        continue;
      const std::string label = r.variant.label();
      const std::string colour = colours.count(label) ? colours.at(label) : "#7f7f7f";
      fid::Series kc{label, colour, {}, label.starts_with("OpenMesh"), "", false};
      for (const auto& s : r.section->curvature) kc.points.emplace_back(s.polar_deg, s.value);
      fid::Series tc{label, colour, {}, label.starts_with("OpenMesh"), "", false};
      for (const auto& s : r.section->tangent_smoothed)
        tc.points.emplace_back(s.polar_deg, s.value);
      curvature.series.push_back(std::move(kc));
      tangent.series.push_back(std::move(tc));
    }
    panels.push_back(std::move(curvature));
    panels.push_back(std::move(tangent));
  }
  if (!panels.empty()) {
    if (!fid::write_svg(o.svg, "stlrefine fidelity: section-curve undulation test", panels)) {
      std::cerr << "cannot write " << o.svg << "\n";
      return 1;
    }
    std::cerr << "[fidelity] wrote " << o.svg << "\n";
  }
  return 0;
}
