// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/cad_families.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>
#include <iostream>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bench/fidelity/cad_metrics.h"
#include "bench/fidelity/openmesh_butterfly.h"
#include "bench/fidelity/runs.h"
#include "core/mesh/build_mesh.h"
#include "core/schemes/scheme.h"
#include "tests/support/cad_like.h"

namespace stlrefine::fidelity {
namespace {

using test::CadFamily;

//! One row kind: our scheme or an OpenMesh peer; sqrt3 kinds make 2 steps per level.
struct Column {
  std::string label;
  Variant::Kind kind = Variant::Kind::Ours;
  std::string scheme;
  bool sqrt3 = false;
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

double bbox_diagonal(const Mesh& mesh) {
  Vec3 lo = mesh.position(VertexId(0)), hi = lo;
  for (const Vec3& p : mesh.positions()) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  return distance(lo, hi);
}

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

SeedResult run_seed(CadFamily family, std::uint64_t seed, const CadOptions& o,
                    const std::vector<Column>& columns) {
  SeedResult r;
  const test::CadShape shape = test::make_cad_shape(family, {seed, o.coarseness});
  const Mesh input = build_mesh(shape.soup).mesh;
  r.description = shape.description;
  r.diag = bbox_diagonal(input);
  r.input = measure_cad(input, *shape.surface, o.samples);
  for (const int level : o.levels)
    r.ideal.push_back(measure_cad(ideal_refinement(shape, level), *shape.surface, o.samples));
  RunSettings settings;
  settings.crease_angle_deg = o.crease_angle_deg;
  settings.threads = 1;
  settings.reps = 1;
  for (const Column& c : columns) {
    std::vector<Outcome>& row = r.runs.emplace_back();
    for (const int level : o.levels) {
      Outcome out;
      try {
        const RunOutput run = run_variant({c.kind, c.scheme, c.steps(level), 0}, input, settings);
        out.m = measure_cad(run.mesh, *shape.surface, o.samples);
        out.fold_fallbacks = run.fold_fallbacks;
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

void print_family(const FamilyResult& fr, const CadOptions& o, const std::vector<Column>& columns) {
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
  std::cout << "\n### " << test::cad_family_name(fr.family) << "\n\n"
            << seeds.front().description << " (seed " << o.seed_base << "). " << seeds.size()
            << " seeds: " << v_lo << "-" << v_hi << " vertices, " << f_lo << "-" << f_hi
            << " faces.\n\nInput RMS / bbox diagonal " << sci(in_rms) << " (" << sci(in_lo) << " - "
            << sci(in_hi) << "), max " << sci(in_max) << "; worst face normal "
            << fixed(in_worst, 1) << "° from the truth, " << in_over_60
            << " faces > 60°. Ideal (midpoints projected "
            << "onto the truth):";
  for (std::size_t l = 0; l < o.levels.size(); ++l) {
    double ideal = 0, ratio = 0;
    for (const SeedResult& s : seeds) {
      ideal += s.ideal[l].rms / s.diag / double(seeds.size());
      ratio += s.ideal[l].rms / s.input.rms / double(seeds.size());
    }
    std::cout << (l ? "," : "") << " L" << o.levels[l] << " " << sci(ideal) << " (" << fixed(ratio)
              << "x input)";
  }
  std::cout
      << ".\n\n| scheme | L | steps | faces | RMS / diag | RMS / input: mean | worst | "
         "seeds worse | RMS / ideal | max / diag | folded faces (seeds) | > 60° (seeds) | "
         "worst ° | fold guard |\n|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      const Aggregate a = aggregate(seeds, c, l);
      std::cout << "| " << columns[c].label << " | " << o.levels[l] << " | "
                << columns[c].steps(o.levels[l]) << " | ";
      if (a.ok == 0) {
        std::cout << "failed on every seed: " << a.first_error << " | | | | | | | | | | |\n";
        continue;
      }
      std::cout << std::lround(a.faces) << " | " << sci(a.rms) << " | " << fixed(a.ratio) << " | "
                << fixed(a.worst_ratio) << " | " << a.worse << " | " << fixed(a.vs_ideal, 1)
                << " | " << sci(a.worst_max) << " | " << a.folded << " (" << a.folded_seeds
                << ") | " << a.over_60 << " (" << a.over_60_seeds << ") | "
                << fixed(a.worst_normal, 0) << " | "
                << (columns[c].kind == Variant::Kind::Ours ? std::to_string(a.fold_fallbacks)
                                                           : std::string("–"))
                << (a.failed ? " (" + std::to_string(a.failed) + " failed: " + a.first_error + ")"
                             : std::string())
                << " |\n";
    }
}

void print_summary(const std::vector<FamilyResult>& results, const CadOptions& o,
                   const std::vector<Column>& columns) {
  std::cout << "\n### Summary\n\nRMS distance to the truth / the input's RMS, mean over the "
               "seeds (worst seed in brackets), at each level; `ideal`: midpoints projected "
               "onto the truth.\n\n| scheme | L |";
  for (const FamilyResult& fr : results)
    std::cout << " " << test::cad_family_name(fr.family) << " |";
  std::cout << "\n|---|--:|";
  for (std::size_t i = 0; i < results.size(); ++i) std::cout << "--:|";
  std::cout << "\n";
  for (std::size_t l = 0; l < o.levels.size(); ++l) {
    std::cout << "| ideal | " << o.levels[l] << " |";
    for (const FamilyResult& fr : results) {
      double ratio = 0, worst = 0;
      for (const SeedResult& s : fr.seeds) {
        ratio += s.ideal[l].rms / s.input.rms / double(fr.seeds.size());
        worst = std::max(worst, s.ideal[l].rms / s.input.rms);
      }
      std::cout << " " << fixed(ratio) << " (" << fixed(worst) << ") |";
    }
    std::cout << "\n";
  }
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      std::cout << "| " << columns[c].label << " | " << o.levels[l] << " |";
      for (const FamilyResult& fr : results) {
        const Aggregate a = aggregate(fr.seeds, c, l);
        std::cout << " " << (a.ok ? fixed(a.ratio) + " (" + fixed(a.worst_ratio) + ")" : "failed")
                  << (a.worse ? " **" + std::to_string(a.worse) + " worse**" : "") << " |";
      }
      std::cout << "\n";
    }

  std::cout << "\nFaces folded (normal > 90° from the true normal at the centroid's closest "
               "point) / faces > 60°, totals over the seeds, at each level:\n\n| scheme | L |";
  for (const FamilyResult& fr : results)
    std::cout << " " << test::cad_family_name(fr.family) << " |";
  std::cout << "\n|---|--:|";
  for (std::size_t i = 0; i < results.size(); ++i) std::cout << "--:|";
  std::cout << "\n";
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (std::size_t l = 0; l < o.levels.size(); ++l) {
      std::cout << "| " << columns[c].label << " | " << o.levels[l] << " |";
      for (const FamilyResult& fr : results) {
        const Aggregate a = aggregate(fr.seeds, c, l);
        std::cout << " " << a.folded << " / " << a.over_60 << " |";
      }
      std::cout << "\n";
    }
}

}  // namespace

int run_cad_families(const CadOptions& o) {
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
  std::vector<Column> columns;
  const auto names = scheme_names();
  for (const std::string& s : o.schemes) {
    if (std::find(names.begin(), names.end(), s) == names.end()) {
      std::cout << "> Note: scheme `" << s << "` does not exist in this build; skipped.\n";
      continue;
    }
    columns.push_back({s, Variant::Kind::Ours, s, s.starts_with("sqrt3")});
  }
  if (o.openmesh && have_openmesh()) {
    columns.push_back({"OpenMesh ModifiedButterflyT", Variant::Kind::OpenMeshButterfly, "", false});
    columns.push_back({"OpenMesh InterpolatingSqrt3LGT", Variant::Kind::OpenMeshSqrt3LG, "", true});
  } else if (o.openmesh) {
    std::cout << "> Note: built without OpenMesh; no OpenMesh rows.\n";
  }

  std::cout << "Seeds " << o.seed_base << "-" << o.seed_base + o.seeds - 1 << ", coarseness "
            << o.coarseness << ", crease angle " << o.crease_angle_deg << "°, ~" << o.samples
            << " distance samples per mesh. Levels are 1-to-4 levels; sqrt3 schemes (ours and "
               "OpenMesh's) make 2 steps per level. Distances are relative to each input's "
               "bbox diagonal; ratios are per seed, then averaged.\n";

  std::vector<FamilyResult> results;
  for (const CadFamily family : families) {
    std::cerr << "[cad] " << test::cad_family_name(family) << "\n";
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
    print_family(fr, o, columns);
    std::cout.flush();
    results.push_back(std::move(fr));
  }
  print_summary(results, o, columns);
  return 0;
}

}  // namespace stlrefine::fidelity
