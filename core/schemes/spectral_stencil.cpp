// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/spectral_stencil.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>

#include "core/analysis/local_matrix.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

using analysis::EigenvalueMove;
using analysis::LocalMatrix;
using analysis::PolarLayout;

std::vector<Eigen::VectorXd> ValenceMasks::rows(double fraction, double t) const {
  std::vector<Eigen::VectorXd> out(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i)
    out[i] = a[i] - t * (m[i] - fraction * scale * q[i]);
  return out;
}

namespace {

bool same_selection(const MoveSelection& x, const MoveSelection& y) {
  if (x.moves.size() != y.moves.size() || std::abs(x.scale - y.scale) > 1e-9) return false;
  for (std::size_t i = 0; i < x.moves.size(); ++i)
    if (x.moves[i].frequency != y.moves[i].frequency ||
        std::abs(x.moves[i].value - y.moves[i].value) > 1e-9)
      return false;
  return true;
}

// Moves with their multiplicities, in a canonical order, so two nets can be compared.
MoveSelection select(const MoveRule& rule, const LocalMatrix& a) {
  const std::vector<analysis::Eigenvalue> values = analysis::spectrum(a);
  MoveSelection s = rule(values);
  std::vector<EigenvalueMove> expanded;
  for (const EigenvalueMove& mv : s.moves) {
    // A cluster counts once per multiplicity: a net that holds only part of a Jordan
    // block (Loop n = 3 below two rings) must not compare equal.
    int alg = 1;
    for (const analysis::Eigenvalue& e : values)
      if (e.frequency == mv.frequency && std::abs(e.value - mv.value) < 1e-12) alg = e.algebraic;
    for (int i = 0; i < alg; ++i) expanded.push_back(mv);
  }
  std::sort(expanded.begin(), expanded.end(), [](const EigenvalueMove& x, const EigenvalueMove& y) {
    if (x.frequency != y.frequency) return x.frequency < y.frequency;
    return x.value.real() != y.value.real() ? x.value.real() < y.value.real()
                                            : x.value.imag() < y.value.imag();
  });
  s.moves = std::move(expanded);
  return s;
}

}  // namespace

ValenceMasks derive_masks(const Split4Stencil& base, const MoveRule& rule, int n) {
  const analysis::Refiner refine = analysis::Refiner::of(base);
  const LocalMatrix full = analysis::local_subdivision_matrix(refine, n);
  const MoveSelection wanted = select(rule, full);
  ValenceMasks out;
  out.valence = n;
  out.clean_rings = full.layout.rings;
  if (wanted.moves.empty()) return out;
  // The smallest closed net whose spectrum holds the same moved eigenvalues.
  LocalMatrix net = full;
  for (int r = 1; r < full.layout.rings; ++r) {
    try {
      LocalMatrix candidate = analysis::local_subdivision_matrix(refine, n, {r, true});
      if (same_selection(select(rule, candidate), wanted)) {
        net = std::move(candidate);
        break;
      }
    } catch (const Error&) {
      // r rings are not closed under one step: try more.
    }
  }
  const MoveSelection chosen = rule(analysis::spectrum(net));
  const analysis::ModificationBasis basis = analysis::modification_basis(net, chosen.moves);
  out.rings = net.layout.rings;
  out.scale = chosen.scale;
  out.moves = chosen.moves;
  const PolarLayout& lay = net.layout;
  for (int p = -1; p < lay.positions(); ++p) {
    const int row = p < 0 ? 0 : lay.index(p, 0);
    const double change =
        std::max(basis.m.row(row).cwiseAbs().maxCoeff(), basis.q.row(row).cwiseAbs().maxCoeff());
    if (change < 1e-13) continue;
    out.positions.push_back(p);
    out.a.push_back(net.a.row(row).transpose());
    out.m.push_back(basis.m.row(row).transpose());
    out.q.push_back(basis.q.row(row).transpose());
  }
  return out;
}

SpectralMaskTable::SpectralMaskTable(const Split4Stencil& base, MoveRule rule, int max_valence)
    : base_(base),
      rule_(std::move(rule)),
      max_valence_(std::max(max_valence, 2)),
      once_(new std::once_flag[max_valence_ + 1]),
      by_valence_(new ValenceMasks[max_valence_ + 1]) {}

const ValenceMasks& SpectralMaskTable::at(int valence) const {
  if (valence < 3 || valence > max_valence_) return none_;
  std::call_once(once_[valence], [&] {
    // isolate(): while the derivation's own parallel loops wait, this thread must not pick
    // up unrelated work that could ask for the same valence again.
    tbb::this_task_arena::isolate(
        [&] { by_valence_[valence] = derive_masks(base_, rule_, valence); });
  });
  return by_valence_[valence];
}

double SpectralSchedule::move_fraction(int step) const {
  if (step < plain_steps) return 0;
  if (ramp_steps <= 0) return 1;
  return std::min(1.0, std::sqrt(double(step) / ramp_steps));
}

SpectralStencil::SpectralStencil(std::unique_ptr<Split4Stencil> base,
                                 const SpectralMaskTable& table, SpectralSchedule schedule)
    : base_(std::move(base)), table_(table), schedule_(schedule) {}

void SpectralStencil::points(const Level& coarse, const IrregularVertices& irregular,
                             std::span<Vec3> vertex_out, std::span<Vec3> edge_out) const {
  base_->points(coarse, irregular, vertex_out, edge_out);
  if (schedule_.move_fraction(coarse.step) == 0) return;
  apply(coarse, find_sites(coarse, irregular), vertex_out, edge_out);
}

void SpectralStencil::edge_points(const Level& coarse, std::span<Vec3> out) const {
  base_->edge_points(coarse, out);
  if (schedule_.move_fraction(coarse.step) == 0) return;
  apply(coarse, find_sites(coarse, irregular_vertices(coarse)), {}, out);
}

void SpectralStencil::vertex_points(const Level& coarse, std::span<Vec3> out) const {
  base_->vertex_points(coarse, out);
  if (schedule_.move_fraction(coarse.step) == 0) return;
  apply(coarse, find_sites(coarse, irregular_vertices(coarse)), out, {});
}

SpectralStencil::Sites SpectralStencil::find_sites(const Level& coarse,
                                                   const IrregularVertices& irregular) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  Sites out;
  // The masks of the valences present here, derived side by side (each on its first use
  // ever) before the walk below, whose tasks then only read them.
  std::vector<std::uint8_t> present(table_.max_valence() + 1, 0);
  std::vector<int> valences;
  for (const auto& [v, n] : *irregular.list)
    if (n >= 3 && n <= table_.max_valence() && !present[n]) present[n] = 1, valences.push_back(n);
  tbb::parallel_for(std::size_t(0), valences.size(),
                    [&](std::size_t i) { table_.at(valences[i]); });
  std::vector<std::pair<VertexId, int>> candidates;
  std::fill(present.begin(), present.end(), 0);
  for (const auto& [v, n] : *irregular.list) {
    if (n < 3 || n > table_.max_valence() || table_.at(n).empty()) continue;
    if (f.kind(v) != VertexKind::Smooth) continue;
    candidates.emplace_back(v, n);
    present[n] = 1;
  }
  if (candidates.empty()) return out;
  const double t = schedule_.move_fraction(coarse.step);
  out.rows.resize(present.size());
  for (std::size_t n = 0; n < present.size(); ++n)
    if (present[n]) out.rows[n] = table_.at(int(n)).rows(schedule_.fraction, t);

  std::vector<Site> all(candidates.size());
  parallel_for_each_index(candidates.size(), [&](std::size_t i) {
    const auto [v, n] = candidates[i];
    std::vector<VertexId> ids =
        analysis::walk_polar_net(m, m.halfedge(v), table_.at(n).clean_rings);
    if (ids.empty()) return;
    for (VertexId w : ids)
      if (f.kind(w) != VertexKind::Smooth) return;
    all[i] = {v, n, std::move(ids)};
  });
  for (Site& s : all)
    if (!s.net.empty()) out.sites.push_back(std::move(s));
  return out;
}

void SpectralStencil::apply(const Level& coarse, const Sites& sites, std::span<Vec3> vertex_out,
                            std::span<Vec3> edge_out) const {
  const Mesh& m = coarse.mesh;
  // Sites have disjoint changed points (their clean rings hold no other special vertex),
  // so they are written in parallel.
  parallel_for_each_index(sites.sites.size(), [&](std::size_t i) {
    const Site& site = sites.sites[i];
    const int n = site.valence;
    const std::vector<VertexId>& ids = site.net;
    const ValenceMasks& masks = table_.at(n);
    const PolarLayout lay{n, masks.rings};
    // Coarse lattice point (k, a, b), a + b <= rings.
    auto coarse_at = [&](int k, int a, int b) {
      if (a == 0 && b == 0) return ids[0];
      if (a == 0) return ids[lay.index(PolarLayout::position(b, 0), k + 1)];
      return ids[lay.index(PolarLayout::position(a, b), k)];
    };
    for (std::size_t r = 0; r < masks.positions.size(); ++r) {
      const int p = masks.positions[r];
      int fa = 0, fb = 0;
      if (p >= 0) PolarLayout::lattice(p, fa, fb);
      const bool even = fa % 2 == 0 && fb % 2 == 0;  // the centre included
      const std::span<Vec3> out = even ? vertex_out : edge_out;
      if (out.empty()) continue;
      const Eigen::VectorXd& w = sites.rows[n][r];
      for (int j = 0; j < (p < 0 ? 1 : n); ++j) {
        // Fine point (j, fa, fb) of a 1-to-4 step: an old vertex when both coordinates are
        // even, else the edge point between the two coarse points it halves.
        std::uint32_t target;
        if (even) {
          target = coarse_at(j, fa / 2, fb / 2).idx;
        } else {
          VertexId e0, e1;
          if (fa % 2 == 1 && fb % 2 == 0) {
            e0 = coarse_at(j, fa / 2, fb / 2), e1 = coarse_at(j, fa / 2 + 1, fb / 2);
          } else if (fa % 2 == 0) {
            e0 = coarse_at(j, fa / 2, fb / 2), e1 = coarse_at(j, fa / 2, fb / 2 + 1);
          } else {
            e0 = coarse_at(j, (fa - 1) / 2, (fb + 1) / 2),
            e1 = coarse_at(j, (fa + 1) / 2, (fb - 1) / 2);
          }
          const HalfedgeId h = halfedge_to(m, e0, e1);
          if (!h.valid())
            throw Error(ErrorCode::Internal, "spectral_masks", "no edge in a clean net");
          target = m.edge(h).idx;
        }
        Vec3 sum = w[0] * m.position(ids[0]);
        for (int q = 0; q < lay.positions(); ++q)
          for (int k = 0; k < n; ++k)
            sum += w[lay.index(q, k)] * m.position(ids[lay.index(q, k + j)]);
        out[target] = sum;
      }
    }
  });
}

}  // namespace stlrefine
