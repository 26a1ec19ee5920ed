// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "core/features/features.h"
#include "core/mesh/mesh.h"
#include "core/schemes/scheme.h"

namespace stlrefine {

//! What a refinement request asks for. Every field has its range next to it.
struct RefineParams {
  std::string scheme = "butterfly";  //!< one of scheme_names()
  int levels = 1;                    //!< [0, 8]
  FeatureParams features;
  std::uint64_t max_faces = 20'000'000;  //!< [1, 2^31): refuse before work above this
  int threads = 0;                       //!< [0, 256]; 0 = every core
  //! Curvature-adaptive mode when this or adaptive_angle is > 0 (`levels` is then unused):
  //! chordal tolerance in model units (mm) [0, 1e6]. 1-to-4 schemes (interpolating ones:
  //! lsf, butterfly) split edges whose edge point leaves the chord by more than this,
  //! red-green closed; sqrt3 schemes refine triangles whose new point leaves the flat
  //! triangle (a trisection point its chord) by more, forward adaptive (spec 3.6).
  double adaptive_tol = 0;
  //! Curvature-adaptive criterion in degrees [0, 180]: refine where the normals of two
  //! neighbouring faces across a non-sharp edge differ by more than this (Labsik-Greiner
  //! use 20 and 10). With adaptive_tol as well, either criterion refines.
  double adaptive_angle = 0;
  int max_level = 4;  //!< [1, 8]: the level cap of the adaptive mode
  //! sqrt3-unified only (ignored by the other schemes): the Lin-Luo alpha of smooth input
  //! vertices [0, 1] (1 interpolates, 0 is Kobbelt's sqrt3) ...
  double alpha = 1.0;
  //! ... and of crease and corner input vertices (boundaries included) [0, 1], so a part can
  //! stay exact on its feature lines and be smoothed elsewhere.
  double alpha_features = 1.0;
  //! loop-g2 only: the eigenvalues Prautzsch and Umlauf move go to kappa lambda^2, (0, 1]
  //! (smaller: further below lambda^2, larger negative weights; spec 6).
  double kappa = 0.5;
  //! loop-g2 only: Remark 5.3's gradual modification, the move growing as
  //! sqrt(step / ramp_steps) until step ramp_steps, [0, 8]; 0 = the full move from the start.
  int ramp_steps = 0;

  //! True when a curvature-adaptive criterion is on.
  bool adaptive() const { return adaptive_tol > 0 || adaptive_angle > 0; }

  //! \throw Error(InvalidParameter) naming the field.
  void validate() const;
};

//! The scheme options params carry (alpha, alpha_features, kappa, ramp_steps).
SchemeOptions scheme_options(const RefineParams& params);

class Split4Stencil;
//! The 1-to-4 stencil the adaptive mode uses with `scheme`, or null when it has none (the
//! red-green mode needs an interpolating 1-to-4 scheme).
const Split4Stencil* adaptive_scheme(const Scheme& scheme);
class Sqrt3Stencil;
//! The stencil of a sqrt3 scheme (every one has the forward adaptive mode), or null.
const Sqrt3Stencil* adaptive_sqrt3_scheme(const Scheme& scheme);

//! Progress sink: fraction in [0, 1] and a short stage name ("level 2/3").
using ProgressFn = std::function<void(double fraction, std::string_view stage)>;

struct RefineReport {
  std::string scheme;
  int levels = 0;
  std::size_t input_vertices = 0, input_faces = 0;
  std::size_t output_vertices = 0, output_faces = 0;
  std::size_t sharp_edges_in = 0, sharp_edges_out = 0;
  std::size_t corners = 0, creases = 0, darts = 0;
  std::size_t fold_fallbacks = 0;
  //! Adaptive mode: the criteria, steps made (`levels`: the finest level reached) and, at
  //! the cap, the edges (1-to-4) or faces (sqrt3) a criterion would still refine.
  double adaptive_tol = 0;
  double adaptive_angle = 0;
  std::size_t edges_over_tolerance = 0;
  std::size_t faces_over_criterion = 0;
  //! Largest distance any input vertex moved (0 for interpolating schemes).
  double max_input_displacement = 0;
  double seconds = 0;
};

struct RefineResult {
  Mesh mesh;
  RefineReport report;
};

//! Predicted face count; \throw Error(BudgetExceeded, field "max_faces") with the
//! number in the message when it exceeds params.max_faces. In the adaptive mode it is an
//! upper bound (the uniform count at max_level) and is not enforced here: the refinement
//! stops with the same error as soon as its exact count would pass max_faces.
std::uint64_t check_face_budget(std::size_t faces, const RefineParams& params);

//! What the adaptive sqrt3 host needs: no two edges join the same two vertices and no two
//! faces have the same three. Its output's edges are known by their vertex pairs; ingest
//! leaves doubled edges where it cuts a non-manifold edge apart, and a facet plus its
//! reverse is a two-face pillow. Uniform levels and the adaptive 1-to-4 host (lsf,
//! butterfly) refine such meshes.
//! \throw Error(NotTriangleMesh, "adaptive_non_simple") naming the vertices or faces.
void require_simple_mesh(const Mesh& mesh);

//! Applies params.scheme params.levels times. Checks the face budget before any work,
//! the cancel flag between levels. Takes the mesh by value: move it in to save a copy.
//! \throw Error(InvalidParameter | BudgetExceeded | Cancelled); Error(NotTriangleMesh) in the
//! adaptive mode of a sqrt3 scheme on a mesh that is not simple (see require_simple_mesh).
RefineResult refine(Mesh mesh, const RefineParams& params, const ProgressFn& progress = {},
                    const std::atomic<bool>* cancel = nullptr);

}  // namespace stlrefine
