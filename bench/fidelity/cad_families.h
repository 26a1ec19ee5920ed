// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// stlrefine_fidelity --cad-families: every scheme on every CAD-like family
// (tests/support/cad_like.h) for many seeds, against the true surfaces (issue 17).
// Our schemes run as a request runs them (bench/fidelity/api_run.h), with request
// parameters passed through (--param) and side-by-side parameter sets (--variant).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace stlrefine::fidelity {

struct CadOptions {
  std::vector<std::string> families;  //!< cad_family_name()s; empty: all
  int seeds = 10;
  std::uint64_t seed_base = 1000;  //!< seeds seed_base, seed_base + 1, ...
  double coarseness = 1.0;
  std::vector<std::string> schemes{"lsf",          "butterfly", "sqrt3-interp", "sqrt3-unified",
                                   "butterfly-g1", "loop",      "loop-g2",      "sqrt3"};
  std::vector<int> levels{1, 2, 3};  //!< 1-to-4 levels; sqrt3 schemes make twice as many steps
  bool openmesh = true;              //!< ModifiedButterflyT and InterpolatingSqrt3LGT rows
  //! `crease_angle` for every run of ours when given (else the request default applies).
  std::optional<double> crease_angle_deg;
  //! "name=value" request parameters for every run of ours (`scheme` and `levels` are the
  //! bench's own: --schemes, --levels).
  std::vector<std::string> params;
  //! "NAME:name=value,..." parameter sets. Without `scheme=`, each one runs every scheme of
  //! `schemes` with these parameters (labels "scheme [NAME]") and together they replace the
  //! plain rows; with `scheme=X` it is one more row, labelled NAME. Applied after `params`.
  std::vector<std::string> variants;
  //! Diagnostic: our rows call stlrefine::refine on the double-precision mesh with the
  //! RefineParams their parameters parse to, and every row starts from that mesh (no STL
  //! rounding, no pipeline post-pass), to tell the pipeline's effects from the scheme's.
  bool direct = false;
  int jobs = 1;                  //!< seeds run in parallel (each refinement single-threaded)
  std::size_t samples = 60'000;  //!< distance samples per mesh
  //! When set: <family>.md and <family>.svg (error vs faces) per family and all.md (the
  //! whole Markdown, as on stdout) are written there.
  std::string out_dir;
  std::string command;  //!< the command line, quoted in the Markdown
};

//! Markdown to stdout, progress to stderr. Returns the process exit code.
int run_cad_families(const CadOptions& options);

}  // namespace stlrefine::fidelity
