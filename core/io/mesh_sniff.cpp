// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The one format sniffer (by content: a request's body has no file name) and read_mesh,
// which every route and the CLI read files through.

#include <algorithm>
#include <cstring>
#include <string_view>

#include "core/io/mesh_formats.h"
#include "core/io/reader_util.h"

namespace stlrefine {

const char* to_string(MeshFormat format) {
  switch (format) {
    case MeshFormat::Stl:
      return "stl";
    case MeshFormat::Obj:
      return "obj";
    case MeshFormat::Ply:
      return "ply";
    case MeshFormat::ThreeMf:
      return "3mf";
  }
  return "stl";
}

namespace {

bool starts_with(std::span<const std::uint8_t> bytes, std::string_view prefix) {
  return bytes.size() >= prefix.size() &&
         std::memcmp(bytes.data(), prefix.data(), prefix.size()) == 0;
}

//! The first KiB holds no control byte but whitespace (UTF-8 and Latin-1 pass).
bool textual(std::span<const std::uint8_t> bytes) {
  const std::size_t n = std::min<std::size_t>(bytes.size(), 1024);
  return std::all_of(
      bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n), [](std::uint8_t c) {
        return c >= 0x20 ? c != 0x7f
                         : (c == '\n' || c == '\r' || c == '\t' || c == '\f' || c == '\v');
      });
}

//! The first word of the first non-blank line is an OBJ statement.
bool obj_statement(std::span<const std::uint8_t> bytes) {
  std::string_view text(reinterpret_cast<const char*>(bytes.data()),
                        std::min<std::size_t>(bytes.size(), 1024));
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  const std::size_t start = text.find_first_not_of(" \t\r\n\f\v");
  if (start == std::string_view::npos) return false;
  text.remove_prefix(start);
  if (text.front() == '#') return true;
  const std::string_view word = text.substr(0, text.find_first_of(" \t\r\n"));
  // A word cut by the 1 KiB window is too long to be a keyword anyway.
  for (const char* keyword :
       {"v", "vt", "vn", "vp", "f", "o", "g", "s", "l", "p", "usemtl", "mtllib"})
    if (word == keyword) return true;
  return false;
}

}  // namespace

MeshFormat sniff_mesh_format(std::span<const std::uint8_t> bytes) {
  if (starts_with(bytes, "PK\x03\x04")) return MeshFormat::ThreeMf;
  if (starts_with(bytes, "ply\n") || starts_with(bytes, "ply\r")) return MeshFormat::Ply;
  if (textual(bytes) && obj_statement(bytes)) return MeshFormat::Obj;
  return MeshFormat::Stl;
}

MeshInput read_mesh(std::span<const std::uint8_t> bytes, const StlReadOptions& options) {
  switch (sniff_mesh_format(bytes)) {
    case MeshFormat::Obj:
      return read_obj(bytes, options);
    case MeshFormat::Ply:
      return read_ply(bytes, options);
    case MeshFormat::ThreeMf:
      return read_3mf(bytes, options);
    case MeshFormat::Stl:
      break;
  }
  MeshInput in;
  in.format = MeshFormat::Stl;
  in.soup = read_stl(bytes, options);
  in.parts.push_back({in.soup.name, 0, in.soup.triangle_count()});
  return in;
}

}  // namespace stlrefine
