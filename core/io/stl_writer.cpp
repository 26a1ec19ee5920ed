// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>

#include "core/error.h"
#include "core/io/stl.h"

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

//! Corners rounded to float, the unit normal of the rounded triangle (zero if degenerate).
Facet facet_of(std::span<const Vec3> positions, std::span<const VertexId> corners, std::size_t f) {
  Facet out;
  Vec3 p[3];
  for (std::size_t k = 0; k < 3; ++k) {
    const Vec3& v = positions[corners[3 * f + k].idx];
    const float xyz[3] = {static_cast<float>(v.x), static_cast<float>(v.y),
                          static_cast<float>(v.z)};
    if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
      throw Error(ErrorCode::Internal, "non_finite",
                  "cannot write STL: vertex " + std::to_string(corners[3 * f + k].idx) +
                      " of face " + std::to_string(f) + " is not finite as a float");
    }
    std::memcpy(out.corner[k], xyz, sizeof xyz);
    p[k] = Vec3(xyz[0], xyz[1], xyz[2]);
  }
  const Vec3 n = normalized(triangle_normal(p[0], p[1], p[2]));
  out.normal[0] = static_cast<float>(n.x);
  out.normal[1] = static_cast<float>(n.y);
  out.normal[2] = static_cast<float>(n.z);
  return out;
}

void store_u32le(char* p, std::uint32_t v) {
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap32(v);
  std::memcpy(p, &v, 4);
}

std::string write_binary(const Mesh& mesh, std::string_view solid_name) {
  const std::size_t faces = mesh.num_faces();
  if (faces > std::numeric_limits<std::uint32_t>::max()) {
    throw Error(ErrorCode::BudgetExceeded, "too_many_triangles",
                "binary STL holds at most 2^32-1 triangles, the mesh has " + std::to_string(faces));
  }
  std::string out(kHeaderBytes + 4 + kFacetBytes * faces, '\0');
  // Never start the header with "solid": naive readers would take the file for ASCII.
  std::string header = clean_name(solid_name, kHeaderBytes);
  if (header.size() >= 5 && (header[0] | 0x20) == 's' && (header[1] | 0x20) == 'o' &&
      (header[2] | 0x20) == 'l' && (header[3] | 0x20) == 'i' && (header[4] | 0x20) == 'd') {
    header = ("binary " + header).substr(0, kHeaderBytes);
  }
  std::memcpy(out.data(), header.data(), header.size());
  store_u32le(out.data() + kHeaderBytes, static_cast<std::uint32_t>(faces));

  const std::span<const Vec3> positions = mesh.positions();
  const std::span<const VertexId> corners = mesh.corner_vertices();
  char* p = out.data() + kHeaderBytes + 4;
  for (std::size_t f = 0; f < faces; ++f, p += kFacetBytes) {
    const Facet facet = facet_of(positions, corners, f);
    std::uint32_t bits[12];
    std::memcpy(bits, &facet, sizeof bits);
    for (std::size_t i = 0; i < 12; ++i) store_u32le(p + 4 * i, bits[i]);
    // The 2 attribute bytes stay 0.
  }
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

Error os_error(ErrorCode code, const char* reason, const std::string& what,
               const std::filesystem::path& path) {
  const std::string why = std::error_code(errno, std::generic_category()).message();
  return Error(code, reason, what + " '" + path.string() + "': " + why).with_field("path");
}

}  // namespace

std::string write_stl(const Mesh& mesh, StlFormat format, std::string_view solid_name) {
  return format == StlFormat::Ascii ? write_ascii(mesh, solid_name)
                                    : write_binary(mesh, solid_name);
}

void write_stl_file(const std::filesystem::path& path, const Mesh& mesh, StlFormat format,
                    std::string_view solid_name) {
  const std::string bytes = write_stl(mesh, format, solid_name);

  // A unique temporary name next to the target, so that rename() is atomic (same file
  // system) and concurrent writers in one process do not collide.
  static std::atomic<std::uint64_t> counter{0};
  std::filesystem::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);

  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) throw os_error(ErrorCode::InvalidParameter, "cannot_create", "cannot create", tmp);
  const auto abandon = [&](const char* what) {
    Error e = os_error(ErrorCode::Internal, "write_failed", what, tmp);
    ::close(fd);
    ::unlink(tmp.c_str());
    return e;
  };
  const char* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw abandon("cannot write");
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) throw abandon("cannot sync");
  if (::close(fd) != 0) {
    Error e = os_error(ErrorCode::Internal, "write_failed", "cannot close", tmp);
    ::unlink(tmp.c_str());
    throw e;
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    Error e = os_error(ErrorCode::InvalidParameter, "cannot_create", "cannot replace", path);
    ::unlink(tmp.c_str());
    throw e;
  }
}

}  // namespace stlrefine
