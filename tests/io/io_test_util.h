// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "core/io/stl.h"

namespace stlrefine::test {

using Bytes = std::vector<std::uint8_t>;

inline std::filesystem::path data_file(const std::string& name) {
  return std::filesystem::path(STLREFINE_TEST_DATA_DIR) / name;
}
inline std::filesystem::path shared_file(const std::string& name) {
  return std::filesystem::path(STLREFINE_SHARED_MESHES) / name;
}

inline Bytes load(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot open " << path;
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

inline Bytes bytes_of(std::string_view text) {
  return Bytes(text.begin(), text.end());
}

inline std::span<const std::uint8_t> span_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

//! Binary STL from facets of 9 floats each; `count` overrides the header count.
inline Bytes binary_stl(const std::vector<std::array<float, 9>>& facets,
                        std::string_view header = "test",
                        std::optional<std::uint32_t> count = std::nullopt) {
  Bytes out(84 + 50 * facets.size(), 0);
  std::memcpy(out.data(), header.data(), std::min<std::size_t>(header.size(), 80));
  const std::uint32_t n = count.value_or(static_cast<std::uint32_t>(facets.size()));
  std::memcpy(out.data() + 80, &n, 4);
  for (std::size_t f = 0; f < facets.size(); ++f) {
    std::memcpy(out.data() + 84 + 50 * f + 12, facets[f].data(), 36);
  }
  return out;
}

inline std::array<float, 9> unit_triangle(float offset = 0) {
  return {offset, 0, 0, offset + 1, 0, 0, offset, 1, 0};
}

//! Reads `bytes`, expecting MalformedStl with `reason`; returns the error for more checks.
inline Error expect_malformed(std::span<const std::uint8_t> bytes, const std::string& reason,
                              const StlReadOptions& options = {}) {
  try {
    const TriangleSoup soup = read_stl(bytes, options);
    ADD_FAILURE() << "expected MalformedStl '" << reason << "', read " << soup.triangle_count()
                  << " triangles";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::MalformedStl) << e.what();
    EXPECT_EQ(e.reason(), reason) << e.what();
    return e;
  }
  return Error(ErrorCode::Internal, "no_error", "no error was thrown");
}

inline Error expect_malformed(const Bytes& bytes, const std::string& reason,
                              const StlReadOptions& options = {}) {
  return expect_malformed(std::span<const std::uint8_t>(bytes), reason, options);
}

inline Error expect_malformed(std::string_view text, const std::string& reason,
                              const StlReadOptions& options = {}) {
  return expect_malformed(bytes_of(text), reason, options);
}

}  // namespace stlrefine::test
