// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string_view>
#include <utility>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! Whether a host runs the fold guard: as the stencil asks (production), or never (the
//! spectral analysis, core/analysis, which must see the stencil's linear rules alone).
enum class FoldGuard { AsStencil, Off };

//! The interior vertices of a mesh whose valence is not 6, each with its valence: the only
//! places the spectral stencils (loop-g2, butterfly-g1) change anything. A 1-to-4 step keeps
//! this set (old vertices keep their ids and valences, new interior vertices have valence
//! 6), so the split4 host finds it once and carries it from level to level. It describes
//! one mesh only, recognised by its corner array and sizes (a copied or replaced mesh has
//! another array: the list is then found again).
struct IrregularVertices {
  std::shared_ptr<const std::vector<std::pair<VertexId, int>>> list;
  const VertexId* corners = nullptr;
  std::size_t vertices = 0, faces = 0;
  bool valid_for(const Mesh& m) const {
    return list && corners == m.corner_vertices().data() && vertices == m.num_vertices() &&
           faces == m.num_faces();
  }
};

//! One subdivision level: connectivity and positions plus the sharp features on it.
struct Level {
  Mesh mesh;
  Features features;
  //! Refinement steps that made this level from the input (0 for the input). The sqrt3
  //! host trisects sharp edges in every second step, so it needs the parity.
  int step = 0;
  //! Per-vertex blend parameter of sqrt3-unified (Lin-Luo alpha: 1 interpolates, 0
  //! approximates), carried to new vertices by the sqrt3 host; empty for other schemes.
  BigVector<double> alpha{};
  //! Set by the split4 host when its stencil asked for it (split4_host.h); empty otherwise.
  IrregularVertices irregular{};
  //! Per face corner (3f + k, the corner at from(half-edge 3f + k)): the unit normal of the
  //! smooth surface the input stands for, which the split4 fold guard holds children to.
  //! Estimated once on the input (sector_normals) and carried to every later level by the
  //! split4 and sqrt3 hosts; empty otherwise (the guard then estimates it on the level).
  BigVector<Vec3> smooth_normals{};
  //! Whether the step that refines this level makes the fine level's smooth_normals: off
  //! for the last step of a refinement (refine() knows it; the output needs none, and they
  //! are 72 bytes per output face).
  bool pass_smooth_normals = true;
};

//! Counters a step adds to, reported to the user.
struct StepStats {
  //! Edge points pulled back towards the chord because a child face would have turned
  //! more than 90 degrees from its parent (the fold guard of interpolatory schemes).
  std::size_t fold_fallbacks = 0;
};

//! A subdivision scheme: a topology host (1-to-4, sqrt3) combined with a stencil.
class Scheme {
 public:
  virtual ~Scheme() = default;
  virtual std::string_view name() const = 0;
  //! True when every old vertex keeps its position bit-identically.
  virtual bool interpolating() const = 0;
  //! Face count after `levels` steps from `faces` faces (exact, so budgets hold).
  virtual std::uint64_t predict_faces(std::uint64_t faces, int levels) const = 0;
  //! Refines one level. Reads only `coarse` (double buffer).
  virtual Level refine_once(const Level& coarse, StepStats& stats) const = 0;
};

}  // namespace stlrefine
