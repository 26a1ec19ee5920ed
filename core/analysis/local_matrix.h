// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Local subdivision matrices built numerically from the production stencils (spec 6,
// numerical recipe step 2): a polar net around one vertex of valence n is refined by the
// scheme's own code and each column is the refined net for one unit input. No weight is
// copied here, so the matrix is the scheme that runs, not a second description of it.

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "core/analysis/polar_net.h"
#include "core/schemes/scheme.h"
#include "core/schemes/split4_host.h"

namespace stlrefine::analysis {

//! Level::step of every net the analysis refines: the stationary scheme, after
//! butterfly-g1's plain first step and any loop-g2 ramp. Even, so a sqrt3 pair starts
//! with the step that does not trisect, as the papers' double step does.
inline constexpr int kStationaryStep = 16;

//! One step of the analysis: one 1-to-4 step, or two sqrt3 steps (after two the lattice
//! is aligned with the coarse one again, at scale 1/3: the double step S~ = R S S of the
//! sqrt3 papers). Runs the production stencil without the fold guard, which is not linear.
class Refiner {
 public:
  //! \throw Error(Internal) for a scheme whose host the analysis does not know.
  static Refiner of(const Scheme& scheme);
  //! A 1-to-4 stencil that is not (or not yet) a registered scheme. The stencil must
  //! outlive the Refiner.
  static Refiner of(const Split4Stencil& stencil);

  Level operator()(const Level& coarse) const { return step_(coarse); }
  //! Lattice scale of one step: 2 (1-to-4) or 3 (sqrt3 double step).
  int scale() const { return scale_; }

 private:
  std::function<Level(const Level&)> step_;
  int scale_ = 2;
};

//! The square matrix A with fine = A coarse over the polar net of `layout.rings` rings,
//! both in PolarLayout order.
struct LocalMatrix {
  PolarLayout layout;
  int scale = 2;
  Eigen::MatrixXd a;
};

struct LocalMatrixOptions {
  //! Rings R of the net; 0 picks the smallest R whose net one step maps onto more than R
  //! fine rings (closed, and it determines a first surface ring: PU section 4, r1 > r0):
  //! 2 for Loop, 3 for the butterfly (spec 6). Explicit R must be closed.
  int rings = 0;
  //! Use the rotation symmetry: refine only the centre and one sector's points (1 + R(R+1)/2
  //! runs) and fill the other columns by rotation. Off: one run per column (tests compare).
  bool use_symmetry = true;
};

//! \pre valence >= 3. \throw Error(Internal) if the net is not closed for the requested
//! rings (or no R <= 6 qualifies when automatic), or the refined net is not a polar net.
LocalMatrix local_subdivision_matrix(const Refiner& refiner, int valence,
                                     const LocalMatrixOptions& options = {});

//! A coarse planar polar net of `rings` rings (plus a margin) as a Level ready to refine,
//! with the ids of its inner `rings` rings; shared by the matrix and the characteristic map.
struct NetLevel {
  Level level;
  std::vector<VertexId> ids;  //!< PolarLayout of `rings`
};
NetLevel make_net_level(int valence, int rings, int margin);

//! The fine polar net of `rings` rings after one analysis step of `coarse` (whose centre
//! is vertex 0 and whose spoke 0 points along +x): the fine spoke 0 is the centre's
//! neighbour in the +x direction, found on the refined planar geometry.
std::vector<VertexId> fine_polar_ids(const Mesh& fine, int rings);

//! A value per vertex without structure (no weighted sum of the stencils cancels it, as a
//! constant would): what the closure probes put outside the analysed net.
inline double probe_value(VertexId v) {
  return 1.5 + std::sin(1.2345 * v.idx + 0.5);
}

//! 1-D subdivision matrix of the scheme's curve rule (spec 2, 1, 3.4, 4): a straight
//! boundary of a planar strip, the 2 half_width + 1 curve vertices around one of them
//! before and after one analysis step.
Eigen::MatrixXd curve_subdivision_matrix(const Refiner& refiner, int half_width = 3);

}  // namespace stlrefine::analysis
