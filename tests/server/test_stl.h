// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Small STL files built in code, and a reader for checking binary STL answers.

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace stlrefine::test {

using Corner = std::array<float, 3>;
using Triangle = std::array<Corner, 3>;

//! Unit octahedron (vertices +-e_x, +-e_y, +-e_z), 8 outward facets.
std::vector<Triangle> octahedron_triangles();

//! Binary STL; `count` overrides the facet count in the header (to make it lie).
std::string binary_stl(const std::vector<Triangle>& triangles,
                       std::optional<std::uint32_t> count = std::nullopt);
std::string ascii_stl(const std::vector<Triangle>& triangles);

//! The facets of a binary STL. \throw std::runtime_error unless size == 84 + 50 n.
std::vector<Triangle> read_binary_stl(std::span<const char> bytes);
std::vector<Triangle> read_binary_stl(const std::string& bytes);

//! The bytes of a file as they are (empty when it cannot be read).
std::string read_file(const std::filesystem::path& path);

//! True when every corner of `input` occurs bit-identically among the corners of `output`.
bool corners_preserved(const std::vector<Triangle>& input, const std::vector<Triangle>& output);

}  // namespace stlrefine::test
