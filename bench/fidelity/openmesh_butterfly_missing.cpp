// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// Built instead of openmesh_butterfly.cpp when CMake did not find OpenMesh.
#include <stdexcept>

#include "bench/fidelity/openmesh_butterfly.h"

namespace stlrefine::fidelity {

bool have_openmesh() {
  return false;
}

Mesh openmesh_butterfly(const Mesh&, int, double&) {
  throw std::runtime_error("stlrefine_fidelity was built without OpenMesh");
}

Mesh openmesh_sqrt3_lg(const Mesh&, int, double&) {
  throw std::runtime_error("stlrefine_fidelity was built without OpenMesh");
}

}  // namespace stlrefine::fidelity
