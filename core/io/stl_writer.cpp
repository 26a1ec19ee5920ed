// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>

#include "core/error.h"
#include "core/io/stl.h"
#include "core/parallel.h"

namespace stlrefine {
namespace {

constexpr std::size_t kHeaderBytes = 80;
constexpr std::size_t kFacetBytes = 50;
// Longest shortest-round-trip float ("-1.17549435e-38") plus the separating space.
constexpr std::size_t kMaxFloatChars = 16;
constexpr std::size_t kMaxAsciiFacetBytes = 14 + 3 * kMaxFloatChars + 1  // "  facet normal"
                                            + 15                         // "    outer loop\n"
                                            + 3 * (12 + 3 * kMaxFloatChars + 1)  // "vertex"
                                            + 12 + 11;  // "    endloop\n", "  endfacet\n"
// The reader's default name limit: what we write, we can read back.
constexpr std::size_t kMaxNameBytes = 1024;

//! The name as one line of printable ASCII (others become '_'), trimmed and capped.
std::string clean_name(std::string_view name, std::size_t max_bytes) {
  std::string out;
  for (const char ch : name.substr(0, max_bytes)) {
    const auto c = static_cast<unsigned char>(ch);
    out += (c >= 0x20 && c < 0x7f) ? ch : '_';
  }
  const std::size_t b = out.find_first_not_of(' ');
  if (b == std::string::npos) return {};
  return out.substr(b, out.find_last_not_of(' ') - b + 1);
}

struct Facet {
  float normal[3];
  float corner[3][3];
};

//! The unit normal of the triangle of float corners (zero if degenerate).
void set_normal(Facet& facet) {
  Vec3 p[3];
  for (std::size_t k = 0; k < 3; ++k)
    p[k] = Vec3(facet.corner[k][0], facet.corner[k][1], facet.corner[k][2]);
  const Vec3 n = normalized(triangle_normal(p[0], p[1], p[2]));
  facet.normal[0] = static_cast<float>(n.x);
  facet.normal[1] = static_cast<float>(n.y);
  facet.normal[2] = static_cast<float>(n.z);
}

Error non_finite(std::uint32_t vertex, std::size_t face) {
  return Error(ErrorCode::Internal, "non_finite",
               "cannot write STL: vertex " + std::to_string(vertex) + " of face " +
                   std::to_string(face) + " is not finite as a float");
}

//! Corners rounded to float, the unit normal of the rounded triangle (zero if degenerate).
Facet facet_of(std::span<const Vec3> positions, std::span<const VertexId> corners, std::size_t f) {
  Facet out;
  for (std::size_t k = 0; k < 3; ++k) {
    const Vec3& v = positions[corners[3 * f + k].idx];
    const float xyz[3] = {static_cast<float>(v.x), static_cast<float>(v.y),
                          static_cast<float>(v.z)};
    if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2]))
      throw non_finite(corners[3 * f + k].idx, f);
    std::memcpy(out.corner[k], xyz, sizeof xyz);
  }
  set_normal(out);
  return out;
}

void store_u32le(char* p, std::uint32_t v) {
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap32(v);
  std::memcpy(p, &v, 4);
}

//! The 50-byte record of a facet (the 2 attribute bytes 0).
void store_facet(char* p, const Facet& facet) {
  std::uint32_t bits[12];
  std::memcpy(bits, &facet, sizeof bits);
  for (std::size_t i = 0; i < 12; ++i) store_u32le(p + 4 * i, bits[i]);
  p[48] = p[49] = 0;
}

//! The 84 bytes before the facets: the name (never starting with "solid": naive readers
//! would take the file for ASCII), zero padding, the facet count.
std::array<char, kHeaderBytes + 4> binary_header(std::size_t faces, std::string_view solid_name) {
  if (faces > std::numeric_limits<std::uint32_t>::max()) {
    throw Error(ErrorCode::BudgetExceeded, "too_many_triangles",
                "binary STL holds at most 2^32-1 triangles, the mesh has " + std::to_string(faces));
  }
  std::array<char, kHeaderBytes + 4> out{};
  std::string header = clean_name(solid_name, kHeaderBytes);
  if (header.size() >= 5 && (header[0] | 0x20) == 's' && (header[1] | 0x20) == 'o' &&
      (header[2] | 0x20) == 'l' && (header[3] | 0x20) == 'i' && (header[4] | 0x20) == 'd') {
    header = ("binary " + header).substr(0, kHeaderBytes);
  }
  std::memcpy(out.data(), header.data(), header.size());
  store_u32le(out.data() + kHeaderBytes, static_cast<std::uint32_t>(faces));
  return out;
}

//! Records of faces [first, first + count) of the mesh into `out`.
void store_facets(const Mesh& mesh, std::size_t first, std::size_t count, char* out) {
  const std::span<const Vec3> positions = mesh.positions();
  const std::span<const VertexId> corners = mesh.corner_vertices();
  for (std::size_t f = first; f < first + count; ++f, out += kFacetBytes)
    store_facet(out, facet_of(positions, corners, f));
}

std::string write_binary(const Mesh& mesh, std::string_view solid_name) {
  const std::size_t faces = mesh.num_faces();
  const auto header = binary_header(faces, solid_name);
  std::string out(binary_stl_size(faces), '\0');
  std::memcpy(out.data(), header.data(), header.size());
  store_facets(mesh, 0, faces, out.data() + header.size());
  return out;
}

char* put(char* p, std::string_view s) {
  std::memcpy(p, s.data(), s.size());
  return p + s.size();
}

char* put_floats(char* p, const float v[3]) {
  for (int i = 0; i < 3; ++i) {
    *p++ = ' ';
    p = std::to_chars(p, p + kMaxFloatChars, v[i]).ptr;
  }
  *p++ = '\n';
  return p;
}

std::string write_ascii(const Mesh& mesh, std::string_view solid_name) {
  const std::string name = clean_name(solid_name, kMaxNameBytes);
  const std::size_t faces = mesh.num_faces();
  std::string out(2 * (name.size() + 16) + kMaxAsciiFacetBytes * faces, '\0');
  char* p = out.data();
  p = put(p, "solid ");
  p = put(p, name);
  *p++ = '\n';
  const std::span<const Vec3> positions = mesh.positions();
  const std::span<const VertexId> corners = mesh.corner_vertices();
  for (std::size_t f = 0; f < faces; ++f) {
    const Facet facet = facet_of(positions, corners, f);
    p = put(p, "  facet normal");
    p = put_floats(p, facet.normal);
    p = put(p, "    outer loop\n");
    for (const auto& corner : facet.corner) {
      p = put(p, "      vertex");
      p = put_floats(p, corner);
    }
    p = put(p, "    endloop\n  endfacet\n");
  }
  p = put(p, "endsolid ");
  p = put(p, name);
  *p++ = '\n';
  out.resize(static_cast<std::size_t>(p - out.data()));
  return out;
}

}  // namespace

std::string write_stl(const Mesh& mesh, StlFormat format, std::string_view solid_name) {
  return format == StlFormat::Ascii ? write_ascii(mesh, solid_name)
                                    : write_binary(mesh, solid_name);
}

void write_binary_stl(const Mesh& mesh, const ByteSink& sink, std::string_view solid_name) {
  const std::size_t faces = mesh.num_faces();
  const auto header = binary_header(faces, solid_name);
  sink(std::string_view(header.data(), header.size()));
  constexpr std::size_t kChunkFaces = 32768;  // 1.6 MB: written as it is, not gathered
  std::string chunk(kFacetBytes * std::min(faces, kChunkFaces), '\0');
  for (std::size_t first = 0; first < faces; first += kChunkFaces) {
    const std::size_t count = std::min(kChunkFaces, faces - first);
    try {  // the records of a piece are made in parallel (the bytes do not depend on it)
      parallel_for_each_range(count, [&](std::size_t begin, std::size_t end) {
        store_facets(mesh, first + begin, end - begin, chunk.data() + kFacetBytes * begin);
      });
    } catch (const Error& e) {
      if (e.code() == ErrorCode::Cancelled) throw;
      // Which failing face a parallel pass reports is not fixed: report the first, as
      // write_stl does.
      store_facets(mesh, first, count, chunk.data());
      throw;
    }
    sink(std::string_view(chunk.data(), kFacetBytes * count));
  }
}

BinaryStl::BinaryStl(const Mesh& mesh, std::string_view solid_name)
    : header_(binary_header(mesh.num_faces(), solid_name)) {
  take_positions(mesh, nullptr);
  take_corners(mesh);
}

BinaryStl::BinaryStl(Mesh&& mesh, std::string_view solid_name)
    : header_(binary_header(mesh.num_faces(), solid_name)) {
  Mesh taken = std::move(mesh);
  take_positions(taken, &taken.mutable_positions());
  take_corners(taken);
}

void BinaryStl::take_positions(const Mesh& mesh, BigVector<Vec3>* release) {
  const std::span<const Vec3> positions = mesh.positions();
  positions_.resize(3 * positions.size());
  for (std::size_t v = 0; v < positions.size(); ++v) {
    positions_[3 * v] = static_cast<float>(positions[v].x);
    positions_[3 * v + 1] = static_cast<float>(positions[v].y);
    positions_[3 * v + 2] = static_cast<float>(positions[v].z);
  }
  if (release) BigVector<Vec3>().swap(*release);
}

void BinaryStl::take_corners(const Mesh& mesh) {
  // The check write_stl makes as it goes (the first face with a corner not finite as a
  // float), made here before any byte is asked for.
  const std::span<const VertexId> corners = mesh.corner_vertices();
  corners_.resize(corners.size());
  for (std::size_t c = 0; c < corners.size(); ++c) {
    const std::uint32_t v = corners[c].idx;
    const float* p = &positions_[3 * std::size_t{v}];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw non_finite(v, c / 3);
    corners_[c] = v;
  }
}

void BinaryStl::read(std::uint64_t offset, std::span<char> out) const {
  char* p = out.data();
  std::size_t left = out.size();
  if (offset < header_.size()) {
    const std::size_t n = std::min<std::uint64_t>(left, header_.size() - offset);
    std::memcpy(p, header_.data() + offset, n);
    p += n;
    left -= n;
    offset += n;
  }
  const auto facet = [this](std::size_t f) {
    Facet facet;
    for (std::size_t k = 0; k < 3; ++k)
      std::memcpy(facet.corner[k], &positions_[3 * std::size_t{corners_[3 * f + k]}],
                  3 * sizeof(float));
    set_normal(facet);
    return facet;
  };
  while (left > 0) {
    const std::uint64_t at = offset - header_.size();
    const std::size_t f = at / kFacetBytes;
    const std::size_t within = at % kFacetBytes;
    std::size_t n;
    if (within == 0 && left >= kFacetBytes) {
      store_facet(p, facet(f));
      n = kFacetBytes;
    } else {
      char record[kFacetBytes];
      store_facet(record, facet(f));
      n = std::min(left, kFacetBytes - within);
      std::memcpy(p, record + within, n);
    }
    p += n;
    left -= n;
    offset += n;
  }
}

void write_stl_file(const std::filesystem::path& path, const Mesh& mesh, StlFormat format,
                    std::string_view solid_name) {
  if (format == StlFormat::Ascii) return write_file_atomically(path, write_ascii(mesh, solid_name));
  write_file_atomically(path,
                        [&](const ByteSink& sink) { write_binary_stl(mesh, sink, solid_name); });
}

}  // namespace stlrefine
