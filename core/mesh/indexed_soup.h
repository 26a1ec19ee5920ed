// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/geometry/vec3.h"

namespace stlrefine {

//! Triangles over shared (welded) vertex positions, before any topology is built.
//! This is what STL welding produces and what build_mesh consumes.
struct IndexedSoup {
  std::vector<Vec3> positions;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

}  // namespace stlrefine
