// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Wavefront OBJ: `v` positions and `f` faces (fanned into triangles); texture coordinates,
// normals, groups, materials, lines and the rest are skipped. One pass over the lines, each
// capped, nothing allocated beyond what the lines read so far justify.

#include <algorithm>
#include <charconv>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "core/io/mesh_formats.h"
#include "core/io/reader_util.h"

namespace stlrefine {

namespace {

using io_detail::malformed;

class ObjReader {
 public:
  ObjReader(std::span<const std::uint8_t> bytes, const StlReadOptions& options)
      : lines_(bytes, options.max_ascii_line_length), options_(options) {}

  MeshInput parse() {
    MeshInput out;
    out.format = MeshFormat::Obj;
    out.soup.format = StlFormat::Ascii;
    coords_ = &out.soup.coords;
    std::string_view line;
    while (lines_.next(line)) {
      std::string_view rest = line;
      std::string_view keyword;
      if (!io_detail::next_word(rest, keyword) || keyword[0] == '#') continue;
      if (keyword == "v") {
        vertex(rest);
      } else if (keyword == "f") {
        face(rest);
      } else if (keyword == "o" && out.soup.name.empty()) {
        std::string_view name;
        if (io_detail::next_word(rest, name))
          out.soup.name.assign(name.substr(0, std::min<std::size_t>(name.size(), 256)));
      }
      // vt, vn, g, s, usemtl, mtllib, l, p, curves...: not part of the surface.
    }
    if (coords_->empty())
      throw malformed("zero_triangles", "the OBJ file has no face ('f' line) with 3 corners")
          .at_line(lines_.line());
    out.parts.push_back(
        {out.soup.name.empty() ? "obj" : out.soup.name, 0, out.soup.triangle_count()});
    return out;
  }

 private:
  [[noreturn]] void syntax(const std::string& what) const {
    throw malformed("syntax", what + " (line " + std::to_string(lines_.line()) + ")")
        .at_line(lines_.line());
  }

  void vertex(std::string_view rest) {
    if (positions_.size() / 3 >= 3 * options_.max_triangles) {
      throw malformed("too_many_vertices",
                      "more than " + std::to_string(3 * options_.max_triangles) +
                          " vertices (3 max_triangles) on line " + std::to_string(lines_.line()))
          .at_line(lines_.line())
          .with_field("max_triangles");
    }
    const std::size_t index = positions_.size() / 3 + 1;
    for (std::size_t k = 0; k < 3; ++k) {
      std::string_view tok;
      double v = 0;
      if (!io_detail::next_word(rest, tok))
        syntax("vertex " + std::to_string(index) + " has fewer than 3 coordinates");
      if (!io_detail::parse_double(tok, v))
        syntax("vertex " + std::to_string(index) + ": " + io_detail::axis_name(k) + " " +
               io_detail::quoted(tok) + " is not a number");
      const std::string where = "vertex " + std::to_string(index) + ": " + io_detail::axis_name(k) +
                                " (line " + std::to_string(lines_.line()) + ")";
      positions_.push_back(io_detail::checked_coordinate(
          v, options_, where, [&](Error& e) { e.at_line(lines_.line()); }));
    }
    // A 4th number (w) or vertex colours follow now and then: ignored.
  }

  //! The vertex a corner token names ("7", "-1", "7/2", "7//3", "7/2/3"), 0-based.
  std::size_t corner(std::string_view tok) const {
    const std::size_t slash = tok.find('/');
    const std::string_view index = tok.substr(0, slash);
    if (slash != std::string_view::npos) {
      // Up to two more fields, each empty or digits: t, n, //n, t/n.
      const std::string_view more = tok.substr(slash + 1);
      if (std::count(more.begin(), more.end(), '/') > 1 ||
          more.find_first_not_of("0123456789-/") != std::string_view::npos)
        syntax("face corner " + io_detail::quoted(tok) + " is not v, v/t, v//n or v/t/n");
    }
    long long i = 0;
    const auto r = std::from_chars(index.data(), index.data() + index.size(), i);
    if (index.empty() || r.ec != std::errc() || r.ptr != index.data() + index.size())
      syntax("face corner " + io_detail::quoted(tok) + " does not start with a vertex index");
    const long long count = static_cast<long long>(positions_.size() / 3);
    // 1-based; negative counts back from the last vertex defined so far.
    const long long resolved = i > 0 ? i - 1 : count + i;
    if (i == 0 || resolved < 0 || resolved >= count) {
      throw malformed("bad_index", "face corner " + io_detail::quoted(tok) + " on line " +
                                       std::to_string(lines_.line()) + " names vertex " +
                                       std::to_string(i) + ", but " + std::to_string(count) +
                                       " vertices are defined so far")
          .at_line(lines_.line());
    }
    return static_cast<std::size_t>(resolved);
  }

  void face(std::string_view rest) {
    std::string_view tok;
    std::size_t first = 0, previous = 0, corners = 0;
    while (io_detail::next_word(rest, tok)) {
      const std::size_t v = corner(tok);
      if (corners >= 2) {  // fan: (first, previous, v)
        if (coords_->size() / 9 >= options_.max_triangles)
          throw io_detail::too_many_triangles(coords_->size() / 9 + 1, options_)
              .at_line(lines_.line());
        for (const std::size_t c : {first, previous, v})
          coords_->insert(coords_->end(), positions_.begin() + 3 * c,
                          positions_.begin() + 3 * c + 3);
      }
      if (corners == 0) first = v;
      previous = v;
      ++corners;
    }
    if (corners < 3)
      syntax("face with " + std::to_string(corners) + " corners; a face needs at least 3");
  }

  io_detail::LineReader lines_;
  const StlReadOptions& options_;
  std::vector<float> positions_;  // 3 per vertex
  std::vector<float>* coords_ = nullptr;
};

}  // namespace

MeshInput read_obj(std::span<const std::uint8_t> bytes, const StlReadOptions& options) {
  options.validate();
  return ObjReader(bytes, options).parse();
}

}  // namespace stlrefine
