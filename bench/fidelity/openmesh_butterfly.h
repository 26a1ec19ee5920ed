// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// OpenMesh's ModifiedButterflyT and InterpolatingSqrt3LGT as peer rows. Compiled from
// openmesh_butterfly.cpp when CMake found OpenMesh, otherwise from
// openmesh_butterfly_missing.cpp.

#include "core/mesh/mesh.h"

namespace stlrefine::fidelity {

//! False when the benchmark was built without OpenMesh.
bool have_openmesh();

//! Converts `mesh` to an OpenMesh TriMesh (untimed), runs ModifiedButterflyT `levels`
//! times (timed: `seconds`) and converts the result back through build_mesh.
//! \throw std::runtime_error when OpenMesh is missing or fails.
Mesh openmesh_butterfly(const Mesh& mesh, int levels, double& seconds);

//! The same for InterpolatingSqrt3LGT (Labsik-Greiner interpolating sqrt3), `steps` steps.
Mesh openmesh_sqrt3_lg(const Mesh& mesh, int steps, double& seconds);

}  // namespace stlrefine::fidelity
