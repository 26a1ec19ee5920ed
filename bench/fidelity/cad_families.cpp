// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/cad_families.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bench/fidelity/api_run.h"
#include "bench/fidelity/cad_metrics.h"
#include "bench/fidelity/openmesh_butterfly.h"
#include "bench/fidelity/runs.h"
#include "bench/fidelity/svg_plot.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "core/schemes/scheme.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"

namespace stlrefine::fidelity {
namespace {

using test::CadFamily;

//! One row kind: our scheme (with its request parameters) or an OpenMesh peer; sqrt3 kinds
//! make 2 steps per level.
struct Column {
  std::string label;
  Variant::Kind kind = Variant::Kind::Ours;
  std::string scheme;
  bool sqrt3 = false;
  api::RawParams params;  //!< ours: the request's parameters but `levels`
  std::string colour;
  std::string dash;  //!< the plot's stroke-dasharray ("" solid)
  int steps(int level) const { return sqrt3 ? 2 * level : level; }
};

struct Outcome {
  bool ok = false;
  std::string error;
  CadMetrics m;
  std::size_t fold_fallbacks = 0;
};

struct SeedResult {
  std::string description;
  double diag = 0;
  CadMetrics input;
  std::vector<CadMetrics> ideal;           //!< per level
  std::vector<std::vector<Outcome>> runs;  //!< [column][level]
};

using test::bbox_diagonal;

std::string sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2e", v);
  return buf;
}
std::string fixed(double v, int digits = 2) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string join_params(const api::RawParams& params) {
  std::string s;
  for (const auto& [name, value] : params) s += (s.empty() ? "" : ", ") + name + "=" + value;
  return s;
}

SeedResult run_seed(CadFamily family, std::uint64_t seed, const CadOptions& o,
                    const std::vector<Column>& columns) {
  SeedResult r;
  const test::CadShape shape = test::make_cad_shape(family, {seed, o.coarseness});
  // What every row starts from: the shape as a binary STL file (float positions), read
  // through the request path's ingest. Ours get the bytes, the peers the mesh.
  Mesh exact = build_mesh(shape.soup).mesh;
  const std::string stl = write_stl(exact, StlFormat::Binary);
  const Mesh input = o.direct ? std::move(exact) : ingest_request_stl(stl);
  r.description = shape.description;
  r.diag = bbox_diagonal(input);
  r.input = measure_cad(input, *shape.surface, o.samples);
  for (const int level : o.levels)
    r.ideal.push_back(measure_cad(ideal_refinement(shape, level), *shape.surface, o.samples));
  RunSettings settings;
  settings.threads = 1;
  settings.reps = 1;
  for (const Column& c : columns) {
    std::vector<Outcome>& row = r.runs.emplace_back();
    for (const int level : o.levels) {
      Outcome out;
      try {
        if (c.kind == Variant::Kind::Ours && o.direct) {
          const RefineParams params =
              check_refine_params(
                  merge_params(c.params, {{"levels", std::to_string(c.steps(level))}}))
                  .refine;
          RefineResult run = refine(Mesh(input), params);
          out.m = measure_cad(run.mesh, *shape.surface, o.samples);
          out.fold_fallbacks = run.report.fold_fallbacks;
        } else if (c.kind == Variant::Kind::Ours) {
          const ApiRun run = run_api_refine(
              stl, merge_params(c.params, {{"levels", std::to_string(c.steps(level))}}));
          out.m = measure_cad(run.mesh, *shape.surface, o.samples);
          out.fold_fallbacks = run.fold_fallbacks;
        } else {
          const RunOutput run = run_variant({c.kind, "", c.steps(level), 0}, input, settings);
          out.m = measure_cad(run.mesh, *shape.surface, o.samples);
        }
        out.ok = true;
      } catch (const std::exception& e) {
        out.error = e.what();
      }
      row.push_back(std::move(out));
    }
  }
  return r;
}

//! Over the seeds, for one column and level.
struct Aggregate {
  std::size_t ok = 0, failed = 0;
  double faces = 0, rms = 0, ratio = 0, worst_ratio = 0, vs_ideal = 0, worst_max = 0;
  std::size_t worse = 0, folded = 0, folded_seeds = 0, over_60 = 0, over_60_seeds = 0;
  std::size_t fold_fallbacks = 0;
  double worst_normal = 0;
  std::string first_error;
};

Aggregate aggregate(const std::vector<SeedResult>& seeds, std::size_t column, std::size_t level) {
  Aggregate a;
  for (const SeedResult& s : seeds) {
    const Outcome& out = s.runs[column][level];
    if (!out.ok) {
      ++a.failed;
      if (a.first_error.empty()) a.first_error = out.error;
      continue;
    }
    ++a.ok;
    const double ratio = out.m.rms / s.input.rms;
    a.faces += double(out.m.faces);
    a.rms += out.m.rms / s.diag;
    a.ratio += ratio;
    a.worst_ratio = std::max(a.worst_ratio, ratio);
    a.vs_ideal += out.m.rms / s.ideal[level].rms;
    a.worst_max = std::max(a.worst_max, out.m.max / s.diag);
    a.worse += ratio > 1;
    a.folded += out.m.folded;
    a.folded_seeds += out.m.folded > 0;
    a.over_60 += out.m.over_60;
    a.over_60_seeds += out.m.over_60 > 0;
    a.fold_fallbacks += out.fold_fallbacks;
    a.worst_normal = std::max(a.worst_normal, out.m.worst_normal_deg);
  }
  if (a.ok > 0) {
    const double n = double(a.ok);
    a.faces /= n, a.rms /= n, a.ratio /= n, a.vs_ideal /= n;
  }
  return a;
}

struct FamilyResult {
  CadFamily family;
  std::vector<SeedResult> seeds;
};

std::string seed_range(const CadOptions& o) {
  return std::to_string(o.seed_base) + "-" + std::to_string(o.seed_base + o.seeds - 1);
}

void print_family(std::ostream& md, const FamilyResult& fr, const CadOptions& o,
                  const std::vector<Column>& columns) {
  const auto& seeds = fr.seeds;
  std::size_t v_lo = std::numeric_limits<std::size_t>::max(), v_hi = 0, f_lo = v_lo, f_hi = 0;
  double in_rms = 0, in_lo = 1e300, in_hi = 0, in_max = 0, in_worst = 0;
  std::size_t in_over_60 = 0;
  for (const SeedResult& s : seeds) {
    in_worst = std::max(in_worst, s.input.worst_normal_deg);
    in_over_60 += s.input.over_60;
    v_lo = std::min(v_lo, s.input.vertices), v_hi = std::max(v_hi, s.input.vertices);
    f_lo = std::min(f_lo, s.input.faces), f_hi = std::max(f_hi, s.input.faces);
    const double r = s.input.rms / s.diag;
    in_rms += r / double(seeds.size());
    in_lo = std::min(in_lo, r), in_hi = std::max(in_hi, r);
    in_max = std::max(in_max, s.input.max / s.diag);
  }
  md << "\n### " << test::cad_family_name(fr.family) << "\n\n"
     << seeds.front().description << " (seed " << o.seed_base << "). " << seeds.size()
     << " seeds: " << v_lo << "-" << v_hi << " vertices, " << f_lo << "-" << f_hi
     << " faces.\n\nInput RMS / bbox diagonal " << sci(in_rms) << " (" << sci(in_lo) << " - "
     << sci(in_hi) << "), max " << sci(in_max) << "; worst face normal " << fixed(in_worst, 1)
     << "° from the truth, " << in_over_60 << " faces > 60°. Ideal (midpoints projected "
     << "onto the truth):";
  for (std::size_t l = 0; l < o.levels.size(); ++l) {
    double ideal = 0, ratio = 0;
    for (const SeedResult& s : seeds) {
      ideal += s.ideal[l].rms / s.diag / double(seeds.size());
      ratio += s.ideal[l].rms / s.input.rms / double(seeds.size());
    }
    md << (l ? "," : "") << " L" << o.levels[l] << " " << sci(ideal) << " (" << fixed(ratio)
       << "x input)";
  }
  md << ".\n\n| scheme | L | steps | faces | RMS / diag | RMS / input: mean | worst | "
        "seeds worse | RMS / ideal | max / diag | folded faces (seeds) | > 60° (seeds) | "
        "worst ° | fold guard |\n|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      const Aggregate a = aggregate(seeds, c, l);
      md << "| " << columns[c].label << " | " << o.levels[l] << " | "
         << columns[c].steps(o.levels[l]) << " | ";
      if (a.ok == 0) {
        md << "failed on every seed: " << a.first_error << " | | | | | | | | | | |\n";
        continue;
      }
      md << std::lround(a.faces) << " | " << sci(a.rms) << " | " << fixed(a.ratio) << " | "
         << fixed(a.worst_ratio) << " | " << a.worse << " | " << fixed(a.vs_ideal, 1) << " | "
         << sci(a.worst_max) << " | " << a.folded << " (" << a.folded_seeds << ") | " << a.over_60
         << " (" << a.over_60_seeds << ") | " << fixed(a.worst_normal, 0) << " | "
         << (columns[c].kind == Variant::Kind::Ours ? std::to_string(a.fold_fallbacks)
                                                    : std::string("–"))
         << (a.failed ? " (" + std::to_string(a.failed) + " failed: " + a.first_error + ")"
                      : std::string())
         << " |\n";
    }
}

//! RMS / diag against faces, means over the seeds: every row, the ideal and the input.
bool plot_family(const std::string& path, const FamilyResult& fr, const CadOptions& o,
                 const std::vector<Column>& columns) {
  const auto& seeds = fr.seeds;
  const double n = double(seeds.size());
  Panel panel;
  panel.title = std::string(test::cad_family_name(fr.family)) + ", seeds " + seed_range(o) +
                ": RMS distance to the true surface vs faces (means over the seeds; every line "
                "starts at the input)";
  panel.x_label = "faces (mean over the seeds)";
  panel.y_label = "RMS distance / bbox diagonal";
  panel.log_x = panel.log_y = true;
  // Every line starts at the input (level 0).
  double faces = 0, rms = 0;
  for (const SeedResult& s : seeds)
    faces += double(s.input.faces) / n, rms += s.input.rms / s.diag / n;
  const std::pair<double, double> level0{faces, rms};
  Series input{"input", "#000000", {level0}, false, "", true};
  Series ideal{"ideal (midpoints onto the truth)", "#000000", {level0}, false, "1,3", true};
  for (std::size_t l = 0; l < o.levels.size(); ++l) {
    faces = 0, rms = 0;
    for (const SeedResult& s : seeds)
      faces += double(s.ideal[l].faces) / n, rms += s.ideal[l].rms / s.diag / n;
    ideal.points.emplace_back(faces, rms);
  }
  panel.series.push_back(std::move(input));
  panel.series.push_back(std::move(ideal));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    Series s{columns[c].label, columns[c].colour, {level0}, false, columns[c].dash, true};
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      const Aggregate a = aggregate(seeds, c, l);
      if (a.ok > 0 && a.rms > 0) s.points.emplace_back(a.faces, a.rms);
    }
    if (s.points.size() == 1) s.label += " (failed on every seed)";
    panel.series.push_back(std::move(s));
  }
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = 0;
  for (const Series& s : panel.series)
    for (const auto& [x, y] : s.points) x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x);
  panel.x_min = x_lo / 1.3, panel.x_max = x_hi * 1.3;
  SvgLayout layout;
  layout.width = 1100;
  layout.legend_width = 300;
  layout.panel_height = std::max(420.0, 90 + 15.0 * double(panel.series.size()));
  return write_svg(path, "stlrefine_fidelity --cad-families", {panel}, layout);
}

void print_summary(std::ostream& md, const std::vector<FamilyResult>& results, const CadOptions& o,
                   const std::vector<Column>& columns) {
  md << "\n### Summary\n\nRMS distance to the truth / the input's RMS, mean over the "
        "seeds (worst seed in brackets), at each level; `ideal`: midpoints projected "
        "onto the truth.\n\n| scheme | L |";
  for (const FamilyResult& fr : results) md << " " << test::cad_family_name(fr.family) << " |";
  md << "\n|---|--:|";
  for (std::size_t i = 0; i < results.size(); ++i) md << "--:|";
  md << "\n";
  for (std::size_t l = 0; l < o.levels.size(); ++l) {
    md << "| ideal | " << o.levels[l] << " |";
    for (const FamilyResult& fr : results) {
      double ratio = 0, worst = 0;
      for (const SeedResult& s : fr.seeds) {
        ratio += s.ideal[l].rms / s.input.rms / double(fr.seeds.size());
        worst = std::max(worst, s.ideal[l].rms / s.input.rms);
      }
      md << " " << fixed(ratio) << " (" << fixed(worst) << ") |";
    }
    md << "\n";
  }
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      md << "| " << columns[c].label << " | " << o.levels[l] << " |";
      for (const FamilyResult& fr : results) {
        const Aggregate a = aggregate(fr.seeds, c, l);
        md << " " << (a.ok ? fixed(a.ratio) + " (" + fixed(a.worst_ratio) + ")" : "failed")
           << (a.worse ? " **" + std::to_string(a.worse) + " worse**" : "") << " |";
      }
      md << "\n";
    }

  md << "\nFaces folded (normal > 90° from the true normal at the best agreeing of the "
        "centroid's and the corners' closest points) / faces > 60°, totals over the seeds, at "
        "each level:\n\n| scheme | L |";
  for (const FamilyResult& fr : results) md << " " << test::cad_family_name(fr.family) << " |";
  md << "\n|---|--:|";
  for (std::size_t i = 0; i < results.size(); ++i) md << "--:|";
  md << "\n";
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      md << "| " << columns[c].label << " | " << o.levels[l] << " |";
      for (const FamilyResult& fr : results) {
        const Aggregate a = aggregate(fr.seeds, c, l);
        md << " " << a.folded << " / " << a.over_60 << " |";
      }
      md << "\n";
    }
}

std::string scheme_colour(const std::string& scheme) {
  static const std::vector<std::pair<std::string, std::string>> kColours{
      {"lsf", "#1f77b4"},           {"butterfly", "#d62728"},    {"sqrt3-interp", "#2ca02c"},
      {"sqrt3-unified", "#9467bd"}, {"butterfly-g1", "#ff7f0e"}, {"loop", "#8c564b"},
      {"loop-g2", "#e377c2"},       {"sqrt3", "#17becf"}};
  for (const auto& [name, colour] : kColours)
    if (name == scheme) return colour;
  return "#bcbd22";
}

std::string variant_dash(std::size_t index) {
  static const char* kDashes[] = {"", "6,3", "2,2", "8,3,2,3", "12,4"};
  return kDashes[index % std::size(kDashes)];
}

bool known_scheme(const std::string& scheme) {
  const auto names = scheme_names();
  return std::find(names.begin(), names.end(), scheme) != names.end();
}

//! Our rows (scheme x parameter set) and the peers'. Writes notes to `md`, errors to
//! stderr. \return false when a parameter is malformed or refused by the request parser.
bool build_columns(const CadOptions& o, std::ostream& md, std::vector<Column>& columns) {
  api::RawParams global;
  try {
    for (const std::string& p : o.params) global.push_back(split_param(p));
  } catch (const std::exception& e) {
    std::cerr << "--param: " << e.what() << "\n";
    return false;
  }
  for (const auto& [name, value] : global)
    if (name == "scheme" || name == "levels") {
      std::cerr << "--param " << name
                << ": use --schemes / --levels (or a --variant with scheme=)\n";
      return false;
    }
  auto base = [&](const std::string& scheme) {
    api::RawParams p{{"scheme", scheme}, {"threads", "1"}};
    if (o.crease_angle_deg) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%g", *o.crease_angle_deg);
      p.emplace_back("crease_angle", buf);
    }
    return merge_params(std::move(p), global);
  };

  struct Set {
    std::string name;
    api::RawParams params;
    std::string scheme;  //!< given: one row of this scheme
    std::size_t index = 0;
  };
  std::vector<Set> per_scheme, single;
  for (std::size_t i = 0; i < o.variants.size(); ++i) {
    const std::string& v = o.variants[i];
    const std::size_t colon = v.find(':');
    Set set;
    set.index = i;
    set.name = v.substr(0, colon);
    if (set.name.empty()) {
      std::cerr << "--variant '" << v << "': expected NAME:name=value,...\n";
      return false;
    }
    try {
      std::string rest = colon == std::string::npos ? "" : v.substr(colon + 1);
      std::stringstream list(rest);
      for (std::string item; std::getline(list, item, ',');)
        if (!item.empty()) set.params.push_back(split_param(item));
    } catch (const std::exception& e) {
      std::cerr << "--variant " << set.name << ": " << e.what() << "\n";
      return false;
    }
    for (const auto& [name, value] : set.params) {
      if (name == "levels") {
        std::cerr << "--variant " << set.name << ": levels are --levels\n";
        return false;
      }
      if (name == "scheme") set.scheme = value;
    }
    (set.scheme.empty() ? per_scheme : single).push_back(std::move(set));
  }

  for (const std::string& s : o.schemes) {
    if (!known_scheme(s)) {
      md << "> Note: scheme `" << s << "` does not exist in this build; skipped.\n";
      continue;
    }
    const bool sqrt3 = s.starts_with("sqrt3");
    if (per_scheme.empty())
      columns.push_back({s, Variant::Kind::Ours, s, sqrt3, base(s), scheme_colour(s), ""});
    for (const Set& set : per_scheme)
      columns.push_back({s + " [" + set.name + "]", Variant::Kind::Ours, s, sqrt3,
                         merge_params(base(s), set.params), scheme_colour(s),
                         variant_dash(set.index)});
  }
  for (const Set& set : single) {
    if (!known_scheme(set.scheme)) {
      md << "> Note: scheme `" << set.scheme << "` of variant " << set.name
         << " does not exist in this build; skipped.\n";
      continue;
    }
    columns.push_back({set.name, Variant::Kind::Ours, set.scheme, set.scheme.starts_with("sqrt3"),
                       merge_params(base(set.scheme), set.params), scheme_colour(set.scheme),
                       variant_dash(set.index + 1)});
  }
  // Every parameter set is checked once, as the request parser would, before any run.
  for (const Column& c : columns) {
    try {
      check_refine_params(merge_params(c.params, {{"levels", "1"}}));
    } catch (const std::exception& e) {
      std::cerr << "row " << c.label << " (" << join_params(c.params)
                << "): the request parser refuses it: " << e.what() << "\n";
      return false;
    }
  }
  if (o.openmesh && have_openmesh()) {
    columns.push_back({"OpenMesh ModifiedButterflyT",
                       Variant::Kind::OpenMeshButterfly,
                       "",
                       false,
                       {},
                       "#7f7f7f",
                       "6,2,1,2"});
    columns.push_back({"OpenMesh InterpolatingSqrt3LGT",
                       Variant::Kind::OpenMeshSqrt3LG,
                       "",
                       true,
                       {},
                       "#b8860b",
                       "6,2,1,2"});
  } else if (o.openmesh) {
    md << "> Note: built without OpenMesh; no OpenMesh rows.\n";
  }
  return true;
}

//! The run's preamble: what was run and how it was measured.
void print_header(std::ostream& md, const CadOptions& o, const std::vector<Column>& columns) {
  if (!o.command.empty()) md << "Command: `" << o.command << "`\n\n";
  md << "Seeds " << seed_range(o) << ", coarseness " << o.coarseness << ", ~" << o.samples
     << " distance samples per mesh. Levels are 1-to-4 levels; sqrt3 schemes (ours and "
        "OpenMesh's) make 2 steps per level. Distances are relative to each input's bbox "
        "diagonal; ratios are per seed, then averaged.\n\n"
     << (o.direct
             ? "**Diagnostic run (`--direct`)**: every row starts from the double-precision "
               "mesh; our rows call `stlrefine::refine` with the RefineParams the parameters "
               "below parse to (no STL rounding, no post-pass of the request pipeline).\n\n"
             : "Every row starts from the shape written as a binary STL (float positions, as a "
               "bureau's file) and read back through the request path's ingest. Our rows run "
               "as a request runs them: the parameters below through "
               "`api::parse_refine_params` (the CLI's limits) and `api::run_refine`, and what is "
               "measured is the STL it answers, read back (so any post-pass of the pipeline is "
               "included; output positions are floats). OpenMesh rows refine the ingested mesh "
               "directly.\n\n")
     << "| row | request parameters (`levels` from the L column) | crease angle in effect |\n"
        "|---|---|--:|\n";
  for (const Column& c : columns) {
    if (c.kind != Variant::Kind::Ours) continue;
    const api::RefineRequest r = check_refine_params(merge_params(c.params, {{"levels", "1"}}));
    md << "| " << c.label << " | `" << join_params(c.params) << "` | "
       << (r.refine.features.crease_mode == CreaseMode::Auto
               ? std::string("auto")
               : fixed(r.refine.features.crease_angle_deg, 1) + "°")
       << " |\n";
  }
}

bool write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  return static_cast<bool>(out);
}

}  // namespace

int run_cad_families(const CadOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<CadFamily> families;
  if (o.families.empty()) {
    families.assign(test::cad_families().begin(), test::cad_families().end());
  } else {
    for (const std::string& name : o.families) {
      const auto f = test::cad_family_from_name(name);
      if (!f) {
        std::cerr << "unknown family " << name << "\n";
        return 2;
      }
      families.push_back(*f);
    }
  }
  std::ostringstream head;
  std::vector<Column> columns;
  if (!build_columns(o, head, columns)) return 2;
  print_header(head, o, columns);
  std::cout << head.str() << std::flush;

  const std::filesystem::path out_dir = o.out_dir;
  if (!o.out_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(out_dir, ec);
    if (ec) {
      std::cerr << "--out " << o.out_dir << ": " << ec.message() << "\n";
      return 2;
    }
  }

  std::string all = "## CAD-like families, seeds " + seed_range(o) + "\n\n" + head.str();
  std::vector<FamilyResult> results;
  for (const CadFamily family : families) {
    const std::string name(test::cad_family_name(family));
    std::cerr << "[cad] " << name << "\n";
    FamilyResult fr{family, std::vector<SeedResult>(static_cast<std::size_t>(o.seeds))};
    std::atomic<int> next{0};
    std::mutex log;
    auto worker = [&] {
      for (int i = next++; i < o.seeds; i = next++) {
        fr.seeds[static_cast<std::size_t>(i)] =
            run_seed(family, o.seed_base + static_cast<std::uint64_t>(i), o, columns);
        const std::lock_guard lock(log);
        std::cerr << "[cad]   seed " << o.seed_base + static_cast<std::uint64_t>(i) << " done\n";
      }
    };
    std::vector<std::thread> pool;
    for (int j = 1; j < std::max(1, o.jobs); ++j) pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool) t.join();
    std::ostringstream section;
    print_family(section, fr, o, columns);
    if (!o.out_dir.empty()) {
      const std::string svg = name + ".svg";
      if (!plot_family((out_dir / svg).string(), fr, o, columns)) {
        std::cerr << "cannot write " << (out_dir / svg).string() << "\n";
        return 1;
      }
      section << "\n![" << name << ": RMS / diag vs faces](" << svg << ")\n";
      if (!write_text(out_dir / (name + ".md"), "## " + name + ", seeds " + seed_range(o) + "\n\n" +
                                                    head.str() + section.str())) {
        std::cerr << "cannot write " << (out_dir / (name + ".md")).string() << "\n";
        return 1;
      }
    }
    std::cout << section.str() << std::flush;
    all += section.str();
    results.push_back(std::move(fr));
  }
  std::ostringstream summary;
  print_summary(summary, results, o, columns);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summary << "\nWall time " << fixed(wall, 0) << " s (--jobs " << o.jobs << ").\n";
  std::cout << summary.str();
  all += summary.str();
  if (!o.out_dir.empty() && !write_text(out_dir / "all.md", all)) {
    std::cerr << "cannot write " << (out_dir / "all.md").string() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace stlrefine::fidelity
