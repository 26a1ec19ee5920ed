// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The machinery shared by Prautzsch and Umlauf's spectrally improved schemes (spec 6):
// masks derived from the base stencil's own local subdivision matrices, cached per
// valence, and a 1-to-4 stencil that applies the base rules everywhere and the derived
// masks around extraordinary vertices with clean regular rings.

#include <Eigen/Dense>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "core/analysis/spectral_modification.h"
#include "core/schemes/split4_host.h"

namespace stlrefine {

//! The selection rule of a spectral scheme: which eigenvalue clusters of the base matrix
//! move, and the reference modulus s their target is a fraction of (lambda^2 for loop-g2,
//! the leading frequency-1 eigenvalue for butterfly-g1).
struct MoveSelection {
  std::vector<analysis::EigenvalueMove> moves;  //!< targets are filled in later
  double scale = 0;
};
using MoveRule = std::function<MoveSelection(const std::vector<analysis::Eigenvalue>&)>;

//! The masks one valence replaces: rows of A' = A - t (M - fraction s Q) (spectral_
//! modification.h) for the fine points of sector 0 that change (rotated copies for the
//! other sectors), over the coarse polar net of `rings` rings in PolarLayout order.
struct ValenceMasks {
  int valence = 0;
  //! Rings the masks read: the smallest closed net that holds every moved eigenvalue
  //! (1 for Loop at n >= 7: only the spoke E-mask changes, eq. 5.2; 2 for Loop at n = 3
  //! and for the butterfly). Modifying a larger net would change more masks for nothing.
  int rings = 0;
  //! Rings of the analysis net (2 Loop, 3 butterfly): the masks apply only where this many
  //! rings around the vertex are regular, smooth and free of other special vertices.
  int clean_rings = 0;
  double scale = 0;
  //! Changed fine points: -1 the centre, else a PolarLayout position of sector 0.
  std::vector<int> positions;
  std::vector<Eigen::VectorXd> a, m, q;  //!< per changed point
  std::vector<analysis::EigenvalueMove> moves;

  bool empty() const { return positions.empty(); }
  //! The rows for one step: a - t (m - fraction * scale * q).
  std::vector<Eigen::VectorXd> rows(double fraction, double t) const;
};

//! Derives the masks of one valence from `base` (analysis of the production stencil).
//! Empty when the rule moves nothing.
ValenceMasks derive_masks(const Split4Stencil& base, const MoveRule& rule, int valence);

//! Masks for every valence 3..max_valence, each derived on its first use (a mesh needs
//! only the valences it has; deriving all 46 costs 0.2 s for Loop, 0.7 s for the
//! butterfly on one core) and never changed afterwards. Thread-safe.
class SpectralMaskTable {
 public:
  //! `base` must outlive the table.
  SpectralMaskTable(const Split4Stencil& base, MoveRule rule, int max_valence);
  int max_valence() const { return max_valence_; }
  //! Empty for valences without changes or above max_valence.
  const ValenceMasks& at(int valence) const;

 private:
  const Split4Stencil& base_;
  MoveRule rule_;
  int max_valence_;
  std::unique_ptr<std::once_flag[]> once_;
  std::unique_ptr<ValenceMasks[]> by_valence_;
  ValenceMasks none_;
};

//! How strongly the masks apply in a step (Level::step of the coarse level).
struct SpectralSchedule {
  //! Fraction of the reference modulus the moved eigenvalues go to.
  double fraction = 0.5;
  //! Steps with the base rules only (butterfly-g1: 1, so every input vertex stays put).
  int plain_steps = 0;
  //! Remark 5.3: the move grows as sqrt(step / ramp_steps) until step ramp_steps; 0 = off.
  int ramp_steps = 0;

  //! The fraction t of the full move in a step.
  double move_fraction(int step) const;
};

//! The base stencil everywhere; around every interior extraordinary vertex whose valence
//! has masks and whose clean_rings rings are regular and smooth (no sharp edge, no other
//! special vertex), the changed fine points come from the masks instead. The candidates are
//! the level's irregular vertices, which the split4 host carries from level to level, so a
//! step costs the base stencil plus work around those vertices alone.
class SpectralStencil final : public Split4Stencil {
 public:
  SpectralStencil(std::unique_ptr<Split4Stencil> base, const SpectralMaskTable& table,
                  SpectralSchedule schedule);
  void points(const Level& coarse, const IrregularVertices& irregular, std::span<Vec3> vertex_out,
              std::span<Vec3> edge_out) const override;
  void edge_points(const Level& coarse, std::span<Vec3> out) const override;
  void vertex_points(const Level& coarse, std::span<Vec3> out) const override;
  bool uses_irregular() const override { return true; }
  //! Neighbours of extraordinary vertices move (from the second step on), so not
  //! interpolating in the sense of Scheme::interpolating (input vertices may still be).
  bool interpolating() const override { return false; }
  bool guards_folds() const override { return base_->interpolating(); }
  const Split4Stencil& base() const { return *base_; }

 private:
  // A vertex whose masks apply: its valence and its clean polar net (walk_polar_net).
  struct Site {
    VertexId centre;
    int valence = 0;
    std::vector<VertexId> net;
  };
  // The sites of a level, and the rows of this step per valence present.
  struct Sites {
    std::vector<Site> sites;
    std::vector<std::vector<Eigen::VectorXd>> rows;  // by valence
  };
  Sites find_sites(const Level& coarse, const IrregularVertices& irregular) const;
  // Overrides the changed points of every site: vertex points (even fine lattice points)
  // into vertex_out, edge points into edge_out; an empty span is skipped.
  void apply(const Level& coarse, const Sites& sites, std::span<Vec3> vertex_out,
             std::span<Vec3> edge_out) const;

  std::unique_ptr<Split4Stencil> base_;
  const SpectralMaskTable& table_;
  SpectralSchedule schedule_;
};

}  // namespace stlrefine
