// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_adaptive_sweep (issue 17 item 5b): every adaptive scheme (lsf, butterfly,
// sqrt3-interp) on the generated CAD-like families and a fine icosphere, over many seeds, at
// tolerances from 1e-2 to 1e-5 of the bounding-box diagonal: faces, true-surface RMS and
// folded faces per tolerance, where and why each run stopped, and the uniform levels of the
// same scheme next to them. Checks that a tighter tolerance never gives fewer faces nor a
// larger RMS (a relative slack of `--rms-slack` for the sampling) and prints every breach.
// Markdown on stdout. Hand-run, never a test.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "bench/fidelity/cad_metrics.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

using namespace stlrefine;

namespace {

using test::bbox_diagonal;

std::string sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2e", v);
  return buf;
}

struct Row {
  bool ok = false;
  std::string error;
  std::size_t faces = 0;
  double rms = 0;  // / diag
  std::size_t folded = 0;
  RefineReport report;
};

Row run(const Mesh& input, const test::TrueSurface& surface, double diag, RefineParams p,
        std::size_t samples) {
  Row row;
  try {
    p.threads = 1;
    RefineResult r = refine(input, p);
    const fidelity::CadMetrics m = fidelity::measure_cad(r.mesh, surface, samples);
    row.faces = r.mesh.num_faces();
    row.rms = m.rms / diag;
    row.folded = m.folded;
    row.report = r.report;
    row.ok = true;
  } catch (const std::exception& e) {
    row.error = e.what();
  }
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"adaptive refinement monotonicity sweep (issue 17 item 5b)"};
  std::vector<std::string> families{"cylinder", "torus", "sphere", "blob", "rounded-box", "tube"};
  std::vector<std::string> schemes{"lsf", "butterfly", "sqrt3-interp"};
  std::vector<double> tols{1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 1e-5};
  int seeds = 3, first_seed = 1, max_level = 3;
  std::size_t samples = 20'000;
  std::uint64_t max_faces = 2'000'000;
  double coarseness = 1.0, rms_slack = 0.02;
  bool icosphere = true, uniform = true, verbose = false;
  app.add_option("--families", families, "CAD-like families (cad_like.h names)");
  app.add_option("--schemes", schemes, "adaptive schemes");
  app.add_option("--tols", tols, "tolerances, relative to the bbox diagonal");
  app.add_option("--seeds", seeds, "seeds per family");
  app.add_option("--first-seed", first_seed, "first seed");
  app.add_option("--max-level", max_level, "adaptive level cap (sqrt3: twice this in steps)");
  app.add_option("--max-faces", max_faces, "face budget");
  app.add_option("--samples", samples, "RMS samples per mesh");
  app.add_option("--coarseness", coarseness, "cad_like coarseness");
  app.add_option("--rms-slack", rms_slack, "relative RMS rise tolerated as sampling noise");
  app.add_flag("!--no-icosphere", icosphere, "skip the fine icosphere");
  app.add_flag("!--no-uniform", uniform, "skip the uniform rows");
  app.add_flag("--verbose", verbose, "one line per run");
  CLI11_PARSE(app, argc, argv);

  struct Case {
    std::string name;
    std::uint64_t seed;
    Mesh mesh;
    std::shared_ptr<const test::TrueSurface> surface;
  };
  std::vector<Case> cases;
  if (icosphere)
    cases.push_back({"icosphere-3", 0, build_mesh(test::icosphere_soup(3, 10.0)).mesh,
                     test::sphere_surface({0, 0, 0}, 10.0)});
  for (const std::string& f : families) {
    const auto family = test::cad_family_from_name(f);
    if (!family) {
      std::cerr << "unknown family " << f << "\n";
      return 2;
    }
    for (int s = first_seed; s < first_seed + seeds; ++s) {
      test::CadShape shape = test::make_cad_shape(*family, {std::uint64_t(s), coarseness});
      cases.push_back({f, std::uint64_t(s), build_mesh(shape.soup).mesh, shape.surface});
    }
  }

  std::size_t runs = 0, breaches = 0, failures = 0, unexplained = 0;
  std::cout << "| scheme | shape | seed | tol/diag | faces | levels | RMS/diag | folded | "
               "stopped | over tol at stop (not converging) | worst over tol/diag "
               "|\n|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const std::string& scheme : schemes) {
    const bool sqrt3 = scheme.rfind("sqrt3", 0) == 0;
    for (const Case& c : cases) {
      const double diag = bbox_diagonal(c.mesh);
      std::vector<Row> rows;
      for (const double t : tols) {
        RefineParams p;
        p.scheme = scheme;
        p.adaptive_tol = t * diag;
        p.max_level = sqrt3 ? 2 * max_level : max_level;
        p.max_faces = max_faces;
        rows.push_back(run(c.mesh, *c.surface, diag, p, samples));
        ++runs;
        const Row& r = rows.back();
        if (!r.ok) {
          ++failures;
          std::cout << "| " << scheme << " | " << c.name << " | " << c.seed << " | " << sci(t)
                    << " | failed: " << r.error << " |\n";
          continue;
        }
        const RefineReport& rep = r.report;
        const std::size_t over = sqrt3 ? rep.faces_over_criterion : rep.edges_over_tolerance;
        if (over > 0 && rep.stop_reason.empty()) ++unexplained;
        if (verbose || rows.size() == 1 || over > 0)
          std::cout << "| " << scheme << " | " << c.name << " | " << c.seed << " | " << sci(t)
                    << " | " << r.faces << " | " << rep.levels << " | " << sci(r.rms) << " | "
                    << r.folded << " | " << (rep.stop_reason.empty() ? "-" : rep.stop_reason)
                    << " | " << over << " (" << rep.edges_not_converging << ") | "
                    << sci(rep.max_over_tolerance / diag) << " |\n";
      }
      for (std::size_t i = 1; i < rows.size(); ++i) {
        const Row &a = rows[i - 1], &b = rows[i];
        if (!a.ok || !b.ok) continue;
        if (b.faces < a.faces || b.rms > a.rms * (1 + rms_slack)) {
          ++breaches;
          std::cout << "| **breach** " << scheme << " | " << c.name << " | " << c.seed << " | "
                    << sci(tols[i - 1]) << " -> " << sci(tols[i]) << " | faces " << a.faces
                    << " -> " << b.faces << " | | RMS " << sci(a.rms) << " -> " << sci(b.rms)
                    << " | | | | |\n";
        }
      }
      if (uniform) {
        for (int l = 1; l <= max_level; ++l) {
          RefineParams p;
          p.scheme = scheme;
          p.levels = sqrt3 ? 2 * l : l;
          p.max_faces = max_faces;
          const Row u = run(c.mesh, *c.surface, diag, p, samples);
          if (!u.ok) continue;
          // The adaptive rows at least as fine as this uniform level in faces must be at
          // least as accurate (per face at least as accurate as uniform refinement).
          std::string note;
          for (std::size_t i = 0; i < rows.size(); ++i)
            if (rows[i].ok && rows[i].faces >= u.faces && rows[i].rms > u.rms * (1 + rms_slack))
              note += " worse-than-uniform@" + sci(tols[i]);
          std::cout << "| " << scheme << " uniform | " << c.name << " | " << c.seed << " | L" << l
                    << " | " << u.faces << " | " << p.levels << " | " << sci(u.rms) << " | "
                    << u.folded << " |" << note << " | | |\n";
        }
      }
    }
  }
  std::cout << "\nruns " << runs << ", failed " << failures << ", monotonicity breaches "
            << breaches << ", stopped over tolerance without a reason " << unexplained << "\n";
  return 0;
}
