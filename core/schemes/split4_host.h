// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <span>

#include "core/schemes/scheme.h"

namespace stlrefine {

//! The geometric rules of a 1-to-4 scheme: where new edge points go and, for
//! approximating schemes, where old vertices move. Reads the coarse level only.
class Split4Stencil {
 public:
  virtual ~Split4Stencil() = default;
  //! Writes one point per coarse edge, indexed by EdgeId.
  virtual void edge_points(const Level& coarse, std::span<Vec3> out) const = 0;
  //! Writes one point per coarse vertex. Interpolating stencils keep the default (copy).
  virtual void vertex_points(const Level& coarse, std::span<Vec3> out) const;
  virtual bool interpolating() const = 0;
};

//! 1-to-4 split (Loop / butterfly / LSF topology). New vertex ids: old vertices keep
//! theirs, then one per coarse edge (V + e). Face 4f+k is the corner triangle at corner
//! k of coarse face f, 4f+3 the middle one. Halves of sharp edges stay sharp.
//! For interpolating stencils the fold guard runs: an edge point whose child faces would
//! turn more than 90 degrees from their parent is moved back towards its chord midpoint.
Level split4(const Level& coarse, const Split4Stencil& stencil, StepStats& stats);

}  // namespace stlrefine
