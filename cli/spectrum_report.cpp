// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "cli/spectrum_report.h"

#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <memory>

#include "core/schemes/butterfly.h"
#include "core/schemes/butterfly_g1.h"
#include "core/schemes/loop.h"
#include "core/schemes/loop_g2.h"
#include "core/schemes/registry.h"

namespace stlrefine::analysis {

namespace {

std::string printf_string(const char* format, double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, x);
  return buf;
}

std::string fixed6(double x) {
  if (std::abs(x) < 5e-7) return "0";
  return printf_string("%.6f", x);
}

std::string map_word(const CharacteristicMapCheck& m) {
  if (!m.checked) return "-";
  if (!m.regular) return "folds";
  return m.injective ? "ok" : "overlaps";
}

std::string c1_word(const SpectralSummary& s) {
  return s.c1 ? "yes" : s.c1_jordan ? "Jordan" : "no";
}

// The lambda cluster at frequency 1, if lambda sits there.
const Eigenvalue* lambda_entry(const SpectralSummary& s) {
  for (const Eigenvalue& e : s.values)
    if (std::abs(e.modulus() - s.lambda) < 1e-8 && e.frequency == 1) return &e;
  return nullptr;
}

// Appends the pieces in order (GCC 12 warns falsely on "literal" + std::string chains).
void append(std::string& out, std::initializer_list<std::string_view> parts) {
  for (std::string_view p : parts) out += p;
}

std::string frequencies(const std::vector<int>& f) {
  std::string out;
  for (int x : f) append(out, {out.empty() ? "" : ",", std::to_string(x)});
  return out;
}

}  // namespace

std::string format_value(std::complex<double> v) {
  if (std::abs(v.imag()) < 5e-7) return fixed6(v.real());
  return fixed6(v.real()) + (v.imag() < 0 ? "-" : "+") + fixed6(std::abs(v.imag())) + "i";
}

int default_map_levels(const Refiner& refiner) {
  return refiner.scale() == 2 ? 4 : 3;
}

ValenceReport analyse_valence(const Refiner& refiner, int valence) {
  ValenceReport r{local_subdivision_matrix(refiner, valence), {}};
  r.summary = summarize(refiner, r.matrix, default_map_levels(refiner));
  return r;
}

std::string format_lines(std::string_view title, const ValenceReport& r) {
  const SpectralSummary& s = r.summary;
  const PolarLayout& lay = r.matrix.layout;
  std::string out = "# " + std::string(title) + ", valence " + std::to_string(lay.valence) +
                    ": local subdivision matrix " + std::to_string(lay.size()) + " x " +
                    std::to_string(lay.size()) + " (" + std::to_string(lay.rings) +
                    " rings), one step at scale 1/" + std::to_string(r.matrix.scale) + "\n";
  out += "# eigenvalue  modulus  frequency  algebraic  geometric\n";
  for (const Eigenvalue& e : s.values) {
    out += format_value(e.value) + "  " + fixed6(e.modulus()) + "  " + std::to_string(e.frequency) +
           "  " + std::to_string(e.algebraic) + "  " + std::to_string(e.geometric) + "\n";
  }
  out += "# subdominant " + fixed6(s.lambda) + " at frequency " +
         frequencies(s.lambda_frequencies) + " (algebraic " +
         std::to_string(s.lambda_multiplicity) + "), next " + fixed6(s.next) + ", lambda^2 " +
         fixed6(s.lambda * s.lambda) + "\n";
  const CharacteristicMapCheck& m = s.characteristic_map;
  out += "# characteristic map of the frequency-1 pair (" + format_value(s.frequency1) + "): ";
  if (m.checked) {
    out += std::string(m.regular ? "regular" : "not regular") + ", " +
           (m.injective ? "injective" : "not injective") + " (rings " +
           std::to_string(m.inner_ring) + ".." + std::to_string(m.outer_ring) + " after " +
           std::to_string(m.levels) + " steps, smallest triangle " + fixed6(m.min_area_ratio) +
           " of the mean)\n";
  } else {
    out += "not checked\n";
  }
  out += "# C1 (Reif): " + c1_word(s) +
         "; G2 eigenvalue condition: " + (s.g2_eigenvalues ? "yes" : "no") + "\n";
  return out;
}

std::string format_table(const std::vector<ValenceReport>& reports, int count) {
  std::string out =
      "| n | R | lambda | freq | alg/geo | next | lambda^2 | map | C1 | G2 | leading eigenvalues "
      "(value@frequency, xmultiplicity) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const ValenceReport& r : reports) {
    const SpectralSummary& s = r.summary;
    const Eigenvalue* l = lambda_entry(s);
    std::string alg_geo = l ? std::to_string(l->algebraic) + "/" + std::to_string(l->geometric)
                            : std::to_string(s.lambda_multiplicity) + "/-";
    std::string leading;
    for (int i = 0; i < count && i < static_cast<int>(s.values.size()); ++i) {
      const Eigenvalue& e = s.values[i];
      append(leading, {leading.empty() ? "" : " · ", format_value(e.value), "@",
                       std::to_string(e.frequency)});
      if (e.algebraic > 1) append(leading, {"x", std::to_string(e.algebraic)});
    }
    append(out, {"| ",  std::to_string(r.matrix.layout.valence),
                 " | ", std::to_string(r.matrix.layout.rings),
                 " | ", fixed6(s.lambda),
                 " | ", frequencies(s.lambda_frequencies),
                 " | ", alg_geo,
                 " | ", fixed6(s.next),
                 " | ", fixed6(s.lambda * s.lambda),
                 " | ", map_word(s.characteristic_map),
                 " | ", c1_word(s),
                 " | ", s.g2_eigenvalues ? "yes" : "no",
                 " | ", leading,
                 " |\n"});
  }
  return out;
}

std::string format_curve(std::string_view title, const std::vector<Eigenvalue>& values) {
  std::string out = std::string(title) + ":";
  for (const Eigenvalue& e : values) {
    append(out, {" ", format_value(e.value)});
    if (e.algebraic > 1)
      append(out, {"x", std::to_string(e.algebraic), e.jordan() ? " (Jordan)" : ""});
  }
  return out;
}

namespace {

constexpr int kDocFirst = 3, kDocLast = 16, kDocCount = 7;

std::string doc_table(const Refiner& refiner) {
  std::vector<ValenceReport> reports;
  for (int n = kDocFirst; n <= kDocLast; ++n) reports.push_back(analyse_valence(refiner, n));
  return format_table(reports, kDocCount);
}

// The changed masks of one table, one row per valence that has any.
std::string mask_table(const SpectralMaskTable& table, double fraction) {
  std::string out =
      "| n | rings read | clean rings | changed masks | moved eigenvalues (value@frequency) | "
      "target | smallest weight | largest weight |\n|---|---|---|---|---|---|---|---|\n";
  for (int n = kDocFirst; n <= kDocLast; ++n) {
    const ValenceMasks& m = table.at(n);
    if (m.empty()) continue;
    std::string moved;
    for (const EigenvalueMove& mv : m.moves)
      moved +=
          (moved.empty() ? "" : ", ") + format_value(mv.value) + "@" + std::to_string(mv.frequency);
    double lo = 1e300, hi = -1e300;
    for (const Eigen::VectorXd& row : m.rows(fraction, 1.0))
      lo = std::min(lo, row.minCoeff()), hi = std::max(hi, row.maxCoeff());
    out += "| " + std::to_string(n) + " | " + std::to_string(m.rings) + " | " +
           std::to_string(m.clean_rings) + " | " + std::to_string(m.positions.size()) + " | " +
           moved + " | " + fixed6(fraction * m.scale) + " | " + fixed6(lo) + " | " + fixed6(hi) +
           " |\n";
  }
  return out;
}

}  // namespace

std::string spectra_markdown() {
  std::string out =
      "# Spectra of the subdivision schemes\n\n"
      "Generated by `stlrefine spectrum --markdown` (build target `docs_spectra`); the test\n"
      "`docs_spectra_current` fails when this file differs from what the code prints. Do not\n"
      "edit it by hand.\n\n"
      "## How the numbers are made\n\n"
      "For a scheme and a valence n, `core/analysis` builds the local subdivision matrix A from\n"
      "the production stencils: a planar polar net (the vertex, then R rings of regular\n"
      "lattice; sector k spanned by spokes k and k+1) is refined by the scheme's own code with\n"
      "one unit value per run (values ride in z; LSF, which reads the geometry, is linearised\n"
      "at the flat net), without the fold guard. R is the smallest number of rings whose net\n"
      "one step maps onto more than R fine rings (closed, and it determines a first surface\n"
      "ring). One step is one 1-to-4 step (scale 1/2) or two sqrt3 steps (scale 1/3, the\n"
      "double step S~ = R S S of the sqrt3 papers; the fine spoke along the coarse one undoes\n"
      "the rotation). A commutes with the rotation by one sector, so the discrete Fourier\n"
      "transform splits it into one small block per frequency f; f and n - f are conjugate and\n"
      "reported together (multiplicity 2). Eigenvalues of one block closer than 1e-4 are one\n"
      "cluster (a Jordan block spreads the computed roots; the cluster mean is accurate):\n"
      "`alg/geo` are its algebraic and geometric multiplicities.\n\n"
      "Columns: `lambda` the subdominant modulus and `freq` its frequencies; `next` the largest\n"
      "modulus below it; `map` Reif's characteristic map of the leading frequency-1 pair,\n"
      "refined 4 (sqrt3: 3) steps by the scheme: `ok` = every triangle of the first surface\n"
      "ring positively oriented and both boundary curves simple (regular and injective);\n"
      "`C1`: 1 simple, lambda a double eigenvalue of frequency 1 with two eigenvectors, all\n"
      "others smaller, map ok (Reif; PU Theorem 4.1 with k = 1); `Jordan`: the same but with\n"
      "equal Jordan chains at lambda (PU's G1 butterfly at valence 3); `G2`: in addition every\n"
      "other modulus below lambda^2 except a semisimple lambda^2 at frequency 0 or 2 (the\n"
      "quadratics of the characteristic map; Loop's own frequency-0 lambda^2 is one).\n\n";
  struct Entry {
    const char* name;
    const char* note;
  };
  const Entry entries[] = {
      {"loop", "Loop: lambda = 3/8 + cos(2 pi/n)/4, frequency-0 lambda^2 (spec 1, 6)."},
      {"loop-g2",
       "Prautzsch-Umlauf G2 Loop, kappa = 0.5: every eigenvalue in [lambda^2, lambda) but "
       "Loop's own frequency-0 lambda^2 moved to lambda^2/2 (valences 3 and >= 7)."},
      {"butterfly",
       "Modified butterfly (Zorin et al.): 1, 1/2, 1/2, then 1/4 at every valence (spec 2)."},
      {"butterfly-g1",
       "Prautzsch-Umlauf G1 butterfly: the original butterfly with every eigenvalue of modulus "
       ">= mu (the leading frequency-1 one) moved to mu/2 (valences 3 and >= 8); plain in the "
       "first step, this table is every later step."},
      {"lsf", "Local surface fitting, linearised at the flat net."},
      {"sqrt3", "Kobbelt's sqrt3, double step."},
      {"sqrt3-interp",
       "Labsik-Greiner interpolatory sqrt3, double step: 1, 1/3, 1/3, 1/9 (spec 3.3)."},
      {"sqrt3-unified",
       "Lin-Luo unified sqrt3 with alpha = 1 (interpolatory), double step. At valence 3 a "
       "frequency-0 complex pair lies above the frequency-1 eigenvalue."},
  };
  for (const Entry& e : entries) {
    const auto scheme = make_scheme(e.name);
    out += "## " + std::string(e.name) + "\n\n" + e.note + "\n\n" +
           doc_table(Refiner::of(*scheme)) + "\n";
  }
  {
    const ButterflyStencil original(ButterflyStencil::Extraordinary::EightPoint);
    out +=
        "## original butterfly (the base of butterfly-g1)\n\n"
        "Dyn, Levin and Gregory's butterfly, w = 1/16: the 8-point rule at every vertex. Valence "
        "3: lambda = 1/4 with algebraic multiplicity 7; valences >= 8: a frequency-2 pair above "
        "the frequency-1 one, whose map is still ok (PU section 6).\n\n" +
        doc_table(Refiner::of(original)) + "\n";
  }
  out +=
      "## Curve rules\n\n"
      "The 7 x 7 matrix of one step (sqrt3: two) along a straight boundary, 3 curve vertices "
      "either side.\n\n";
  for (const char* name : {"loop", "butterfly", "lsf", "sqrt3", "sqrt3-interp", "sqrt3-unified"}) {
    const auto scheme = make_scheme(name);
    out += "- " +
           format_curve(std::string("`") + name + "`",
                        spectrum(curve_subdivision_matrix(Refiner::of(*scheme)))) +
           "\n";
  }
  out +=
      "\n## Masks the spectral schemes change\n\n"
      "Derived from the base stencil's own matrices, each valence when a mesh first has it, "
      "for every valence up to " +
      std::to_string(kSpectralMaxValence) +
      " (higher valences keep the base rules). A mask reads `rings read` rings (the smallest "
      "closed net that holds every moved eigenvalue: for Loop at n >= 7 one ring, so only the "
      "spoke E-mask changes, PU eq. 5.2) and applies where `clean rings` rings around the "
      "vertex are regular and smooth. Weights are those of the full move.\n\n"
      "### loop-g2 (kappa = 0.5)\n\n" +
      mask_table(loop_g2_masks(), 0.5) + "\n### butterfly-g1\n\n" +
      mask_table(butterfly_g1_masks(), kButterflyG1Fraction);
  return out;
}

}  // namespace stlrefine::analysis
