// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "test_stl.h"

#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string_view>

namespace stlrefine::test {

std::vector<Triangle> octahedron_triangles() {
  const Corner px{1, 0, 0}, nx{-1, 0, 0}, py{0, 1, 0}, ny{0, -1, 0}, pz{0, 0, 1}, nz{0, 0, -1};
  return {{px, py, pz}, {py, nx, pz}, {nx, ny, pz}, {ny, px, pz},
          {py, px, nz}, {nx, py, nz}, {ny, nx, nz}, {px, ny, nz}};
}

std::string binary_stl(const std::vector<Triangle>& triangles, std::optional<std::uint32_t> count) {
  const std::string_view name = "stlrefine server test";
  std::string out(name);
  out.resize(80, '\0');
  const std::uint32_t n = count.value_or(static_cast<std::uint32_t>(triangles.size()));
  out.append(reinterpret_cast<const char*>(&n), 4);
  for (const Triangle& t : triangles) {
    const float normal[3] = {0, 0, 0};
    out.append(reinterpret_cast<const char*>(normal), sizeof normal);
    for (const Corner& c : t) out.append(reinterpret_cast<const char*>(c.data()), 12);
    out.append(2, '\0');
  }
  return out;
}

std::string ascii_stl(const std::vector<Triangle>& triangles) {
  std::ostringstream os;
  os << "solid test\n";
  for (const Triangle& t : triangles) {
    os << "  facet normal 0 0 0\n    outer loop\n";
    for (const Corner& c : t) os << "      vertex " << c[0] << " " << c[1] << " " << c[2] << "\n";
    os << "    endloop\n  endfacet\n";
  }
  os << "endsolid test\n";
  return os.str();
}

std::vector<Triangle> read_binary_stl(std::span<const char> bytes) {
  if (bytes.size() < 84) throw std::runtime_error("shorter than a binary STL header");
  std::uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 80, 4);
  if (bytes.size() != 84 + 50 * std::size_t{n})
    throw std::runtime_error("size " + std::to_string(bytes.size()) + " does not match " +
                             std::to_string(n) + " facets");
  std::vector<Triangle> out(n);
  for (std::size_t i = 0; i < n; ++i)
    std::memcpy(out[i].data(), bytes.data() + 84 + 50 * i + 12, 36);
  return out;
}

std::vector<Triangle> read_binary_stl(const std::string& bytes) {
  return read_binary_stl(std::span<const char>(bytes.data(), bytes.size()));
}

bool corners_preserved(const std::vector<Triangle>& input, const std::vector<Triangle>& output) {
  // Compare bit patterns, not float values: "unchanged" means bit-identical.
  auto bits = [](const Corner& c) {
    std::array<std::uint32_t, 3> b;
    std::memcpy(b.data(), c.data(), 12);
    return b;
  };
  std::set<std::array<std::uint32_t, 3>> have;
  for (const Triangle& t : output)
    for (const Corner& c : t) have.insert(bits(c));
  for (const Triangle& t : input)
    for (const Corner& c : t)
      if (!have.count(bits(c))) return false;
  return true;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace stlrefine::test
