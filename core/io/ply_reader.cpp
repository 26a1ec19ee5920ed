// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// PLY (ASCII, binary little and big endian): the `vertex` element's x, y, z (any scalar
// type, in any order among other properties) and the `face` element's vertex_indices list
// (fanned into triangles). Other elements and properties are read past. Every count in
// the header is checked against the bytes that follow before anything is allocated.

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/io/huge_pages.h"
#include "core/io/mesh_formats.h"
#include "core/io/reader_util.h"

namespace stlrefine {

namespace {

using io_detail::malformed;

enum class Encoding { Ascii, Little, Big };

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

struct TypeName {
  const char* name;
  Type type;
};
constexpr TypeName kTypes[] = {
    {"char", Type::Int8},      {"int8", Type::Int8},       {"uchar", Type::UInt8},
    {"uint8", Type::UInt8},    {"short", Type::Int16},     {"int16", Type::Int16},
    {"ushort", Type::UInt16},  {"uint16", Type::UInt16},   {"int", Type::Int32},
    {"int32", Type::Int32},    {"uint", Type::UInt32},     {"uint32", Type::UInt32},
    {"float", Type::Float32},  {"float32", Type::Float32}, {"double", Type::Float64},
    {"float64", Type::Float64}};

std::size_t size_of(Type t) {
  switch (t) {
    case Type::Int8:
    case Type::UInt8:
      return 1;
    case Type::Int16:
    case Type::UInt16:
      return 2;
    case Type::Int32:
    case Type::UInt32:
    case Type::Float32:
      return 4;
    case Type::Float64:
      return 8;
  }
  return 1;
}

bool is_integer(Type t) {
  return t != Type::Float32 && t != Type::Float64;
}

struct Property {
  std::string name;
  Type type = Type::Float32;
  bool list = false;
  Type count_type = Type::UInt8;  // lists only
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

//! What the header announces about one element instance's bytes: the least it can take.
std::uint64_t min_bytes(const Element& e, Encoding encoding) {
  std::uint64_t n = 0;
  for (const Property& p : e.properties)
    n += encoding == Encoding::Ascii ? 2 : size_of(p.list ? p.count_type : p.type);
  return n;
}

class PlyReader {
 public:
  PlyReader(std::span<const std::uint8_t> bytes, const StlReadOptions& options)
      : bytes_(bytes), lines_(bytes, options.max_ascii_line_length), options_(options) {}

  MeshInput parse() {
    read_header();
    MeshInput out;
    out.format = MeshFormat::Ply;
    out.soup.format = encoding_ == Encoding::Ascii ? StlFormat::Ascii : StlFormat::Binary;
    out.encoding = encoding_ == Encoding::Ascii    ? "ascii"
                   : encoding_ == Encoding::Little ? "binary_little_endian"
                                                   : "binary_big_endian";
    coords_ = &out.soup.coords;
    pos_ = lines_.offset();
    for (const Element& e : elements_) read_element(e);
    finish_body();
    if (coords_->empty())
      throw malformed("zero_triangles", "the PLY file has no face with 3 corners")
          .at_byte(bytes_.size());
    out.parts.push_back({"ply", 0, out.soup.triangle_count()});
    return out;
  }

 private:
  // ---- header ----------------------------------------------------------------------------

  [[noreturn]] void bad_header(const std::string& what) const {
    throw malformed("bad_header", what + " (header line " + std::to_string(lines_.line()) + ")")
        .at_line(lines_.line());
  }

  Type parse_type(std::string_view word) const {
    for (const TypeName& t : kTypes)
      if (word == t.name) return t.type;
    bad_header("unknown property type " + io_detail::quoted(word));
  }

  void read_header() {
    std::string_view line, rest, word;
    if (!lines_.next(line) || line != "ply") bad_header("a PLY file starts with the line 'ply'");
    bool format = false, end = false;
    while (!end && lines_.next(line)) {
      rest = line;
      if (!io_detail::next_word(rest, word)) continue;
      if (word == "comment" || word == "obj_info") continue;
      if (word == "end_header") {
        end = true;
      } else if (word == "format") {
        std::string_view name, version;
        if (format) bad_header("a second 'format' line");
        if (!io_detail::next_word(rest, name) || !io_detail::next_word(rest, version) ||
            version != "1.0")
          bad_header("expected 'format <encoding> 1.0'");
        if (name == "ascii")
          encoding_ = Encoding::Ascii;
        else if (name == "binary_little_endian")
          encoding_ = Encoding::Little;
        else if (name == "binary_big_endian")
          encoding_ = Encoding::Big;
        else
          bad_header("unknown format " + io_detail::quoted(name));
        format = true;
      } else if (word == "element") {
        std::string_view name, count;
        if (!io_detail::next_word(rest, name) || !io_detail::next_word(rest, count))
          bad_header("expected 'element <name> <count>'");
        Element e;
        e.name = std::string(name);
        const auto r = std::from_chars(count.data(), count.data() + count.size(), e.count);
        if (r.ec != std::errc() || r.ptr != count.data() + count.size() ||
            e.count > std::uint64_t{0xffffffffu})
          bad_header("element " + io_detail::quoted(name) + " count " + io_detail::quoted(count) +
                     " is not a number below 2^32");
        if (std::any_of(elements_.begin(), elements_.end(),
                        [&](const Element& x) { return x.name == e.name; }))
          bad_header("element " + io_detail::quoted(name) + " appears twice");
        elements_.push_back(std::move(e));
      } else if (word == "property") {
        if (elements_.empty()) bad_header("a property before any element");
        Property p;
        std::string_view type, name;
        if (!io_detail::next_word(rest, type)) bad_header("expected 'property <type> <name>'");
        if (type == "list") {
          std::string_view count_type;
          if (!io_detail::next_word(rest, count_type) || !io_detail::next_word(rest, type))
            bad_header("expected 'property list <count type> <type> <name>'");
          p.list = true;
          p.count_type = parse_type(count_type);
          if (!is_integer(p.count_type)) bad_header("a list's count type must be an integer");
        }
        p.type = parse_type(type);
        if (!io_detail::next_word(rest, name)) bad_header("the property has no name");
        p.name = std::string(name);
        elements_.back().properties.push_back(std::move(p));
      } else {
        bad_header("unknown header keyword " + io_detail::quoted(word));
      }
    }
    if (!end) bad_header("no 'end_header' line");
    if (!format) bad_header("no 'format' line");
    check_elements();
  }

  //! The vertex and face elements and the limits, before any allocation.
  void check_elements() {
    const std::uint64_t body = bytes_.size() - lines_.offset();
    bool vertex_seen = false;
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      const Element& e = elements_[i];
      if (e.count > 0 && e.properties.empty())
        bad_header("element " + io_detail::quoted(e.name) + " has no property");
      if (e.name == "vertex") {
        vertex_seen = true;
        vertex_ = i;
        for (const Property& p : e.properties)
          for (std::size_t k = 0; k < 3; ++k)
            if (p.name == io_detail::axis_name(k)) {
              if (p.list) bad_header("vertex property " + p.name + " is a list");
              xyz_[k] = &p - e.properties.data();
            }
        for (std::size_t k = 0; k < 3; ++k)
          if (!xyz_[k])
            bad_header(std::string("the vertex element has no property ") +
                       io_detail::axis_name(k));
        if (e.count > 3 * std::uint64_t{options_.max_triangles}) {
          throw malformed("too_many_vertices", "the header announces " + std::to_string(e.count) +
                                                   " vertices, more than 3 max_triangles")
              .at_byte(lines_.offset())
              .with_field("max_triangles");
        }
      } else if (e.name == "face") {
        if (!vertex_seen) bad_header("the face element comes before the vertex element");
        face_ = i;
        for (const Property& p : e.properties)
          if (p.name == "vertex_indices" || p.name == "vertex_index") {
            if (!p.list) bad_header(p.name + " is not a list");
            if (!is_integer(p.type)) bad_header(p.name + " holds non-integers");
            indices_ = &p - e.properties.data();
          }
        if (!indices_) bad_header("the face element has no vertex_indices list");
        if (e.count > options_.max_triangles)
          throw io_detail::too_many_triangles(e.count, options_).at_byte(lines_.offset());
      }
    }
    if (!vertex_) bad_header("no vertex element");
    if (!face_) bad_header("no face element");
    // Then the sizes: the header is sound, but do its counts fit the bytes?
    for (const Element& e : elements_) {
      // Each instance takes at least this many bytes: a lying count ends here, not in an
      // allocation or a loop over billions of empty instances.
      const std::uint64_t least = min_bytes(e, encoding_);
      // (ASCII: the last line may lack its line break.)
      const std::uint64_t room = encoding_ == Encoding::Ascii ? body + 1 : body;
      if (e.count > 0 && least > 0 && e.count > room / least) {
        throw malformed("truncated", "element " + io_detail::quoted(e.name) + " announces " +
                                         std::to_string(e.count) + " instances of at least " +
                                         std::to_string(least) + " bytes, but only " +
                                         std::to_string(body) + " bytes follow the header")
            .at_byte(lines_.offset());
      }
    }
  }

  // ---- body ------------------------------------------------------------------------------

  //! One value of `type` as a double (binary: read at pos_; ASCII: the next token).
  double value(Type type, const char* what) {
    if (encoding_ == Encoding::Ascii) {
      std::string_view tok;
      if (!io_detail::next_word(rest_, tok))
        ascii_syntax(std::string("the line ends before ") + what);
      double v = 0;
      if (!io_detail::parse_double(tok, v))
        ascii_syntax(std::string(what) + " " + io_detail::quoted(tok) + " is not a number");
      if (is_integer(type) && v != std::floor(v))
        ascii_syntax(std::string(what) + " " + io_detail::quoted(tok) + " is not an integer");
      return v;
    }
    const std::size_t n = size_of(type);
    if (bytes_.size() - pos_ < n) {
      throw malformed("truncated", std::string("the file ends inside ") + what + " (byte " +
                                       std::to_string(pos_) + ")")
          .at_byte(pos_);
    }
    std::uint8_t b[8];
    std::memcpy(b, bytes_.data() + pos_, n);
    value_offset_ = pos_;
    pos_ += n;
    const bool swap = (encoding_ == Encoding::Big) != (std::endian::native == std::endian::big);
    if (swap) std::reverse(b, b + n);
    switch (type) {
      case Type::Int8:
        return static_cast<std::int8_t>(b[0]);
      case Type::UInt8:
        return b[0];
      case Type::Int16: {
        std::int16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case Type::UInt16: {
        std::uint16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case Type::Int32: {
        std::int32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case Type::UInt32: {
        std::uint32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case Type::Float32: {
        float v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case Type::Float64: {
        double v;
        std::memcpy(&v, b, 8);
        return v;
      }
    }
    return 0;
  }

  [[noreturn]] void ascii_syntax(const std::string& what) const {
    throw malformed("syntax", what + " (line " + std::to_string(lines_.line()) + ")")
        .at_line(lines_.line());
  }

  void locate(Error& e) const {
    if (encoding_ == Encoding::Ascii)
      e.at_line(lines_.line());
    else
      e.at_byte(value_offset_);
  }

  void begin_instance(const Element& e, std::uint64_t i) {
    if (encoding_ != Encoding::Ascii) return;
    std::string_view line;
    do {
      if (!lines_.next(line))
        throw malformed("truncated", "the file ends at " + e.name + " " + std::to_string(i) +
                                         " of the " + std::to_string(e.count) +
                                         " the header announces")
            .at_line(lines_.line());
      rest_ = line;
    } while (std::all_of(line.begin(), line.end(), io_detail::is_blank));
  }

  void end_instance(const Element& e, std::uint64_t i) {
    std::string_view extra;
    if (encoding_ == Encoding::Ascii && io_detail::next_word(rest_, extra))
      ascii_syntax(e.name + " " + std::to_string(i) +
                   " has more values than its properties: " + io_detail::quoted(extra));
  }

  void read_element(const Element& e) {
    const bool vertex = &e == &elements_[*vertex_];
    const bool face = &e == &elements_[*face_];
    if (vertex) io_detail::reserve_huge(positions_, 3 * e.count);
    for (std::uint64_t i = 0; i < e.count; ++i) {
      begin_instance(e, i);
      float xyz[3] = {0, 0, 0};
      for (std::size_t p = 0; p < e.properties.size(); ++p) {
        const Property& prop = e.properties[p];
        if (face && p == *indices_) {
          read_face(prop, i);
          continue;
        }
        if (prop.list) {
          skip_list(prop, e, i);
          continue;
        }
        const double v = value(prop.type, prop.name.c_str());
        if (vertex)
          for (std::size_t k = 0; k < 3; ++k)
            if (xyz_[k] == p) {
              const std::string where =
                  "vertex " + std::to_string(i) + ": " + io_detail::axis_name(k);
              xyz[k] = io_detail::checked_coordinate(v, options_, where,
                                                     [&](Error& err) { locate(err); });
            }
      }
      if (vertex) positions_.insert(positions_.end(), xyz, xyz + 3);
      end_instance(e, i);
    }
  }

  std::uint64_t list_count(const Property& prop, const std::string& what) {
    const double n = value(prop.count_type, what.c_str());
    if (!(n >= 0 && n <= 4294967295.0)) {
      Error err = malformed("bad_face", what + " has a count outside [0, 2^32)");
      locate(err);
      throw err;
    }
    return static_cast<std::uint64_t>(n);
  }

  void skip_list(const Property& prop, const Element& e, std::uint64_t i) {
    const std::uint64_t n = list_count(prop, e.name + " " + std::to_string(i) + " " + prop.name);
    if (encoding_ != Encoding::Ascii && n > (bytes_.size() - pos_) / size_of(prop.type))
      throw malformed("truncated", "list " + prop.name + " of " + e.name + " " + std::to_string(i) +
                                       " runs past the end of the file")
          .at_byte(pos_);
    for (std::uint64_t k = 0; k < n; ++k) value(prop.type, prop.name.c_str());
  }

  void read_face(const Property& prop, std::uint64_t i) {
    const std::string what = "face " + std::to_string(i);
    const std::size_t at = pos_;
    const std::uint64_t n = list_count(prop, what);
    if (n < 3) {
      Error err = malformed(
          "bad_face", what + " has " + std::to_string(n) + " corners; a face needs at least 3");
      locate(err);
      throw err;
    }
    if (encoding_ != Encoding::Ascii && n > (bytes_.size() - pos_) / size_of(prop.type))
      throw malformed("truncated", what + " announces " + std::to_string(n) +
                                       " corners, more than the file holds")
          .at_byte(at);
    const std::uint64_t vertices = positions_.size() / 3;
    std::uint64_t first = 0, previous = 0;
    for (std::uint64_t k = 0; k < n; ++k) {
      const double index = value(prop.type, "a vertex index");
      if (index < 0 || index >= static_cast<double>(vertices)) {
        Error err = malformed("bad_index", what + " names vertex " + std::to_string(index) +
                                               " of " + std::to_string(vertices));
        locate(err);
        throw err;
      }
      const auto v = static_cast<std::uint64_t>(index);
      if (k >= 2) {
        if (coords_->size() / 9 >= options_.max_triangles) {
          Error err = io_detail::too_many_triangles(coords_->size() / 9 + 1, options_);
          locate(err);
          throw err;
        }
        for (const std::uint64_t c : {first, previous, v})
          coords_->insert(coords_->end(), positions_.begin() + static_cast<std::ptrdiff_t>(3 * c),
                          positions_.begin() + static_cast<std::ptrdiff_t>(3 * c + 3));
      }
      if (k == 0) first = v;
      previous = v;
    }
  }

  void finish_body() {
    if (encoding_ == Encoding::Ascii) {
      std::string_view line;
      while (lines_.next(line))
        if (!std::all_of(line.begin(), line.end(), io_detail::is_blank))
          ascii_syntax("data after the last element: " + io_detail::quoted(line));
      return;
    }
    if (pos_ != bytes_.size()) {
      throw malformed("trailing_bytes", std::to_string(bytes_.size() - pos_) +
                                            " bytes after the last element the header "
                                            "announces (from byte " +
                                            std::to_string(pos_) + ")")
          .at_byte(pos_);
    }
  }

  std::span<const std::uint8_t> bytes_;
  io_detail::LineReader lines_;
  const StlReadOptions& options_;
  Encoding encoding_ = Encoding::Ascii;
  std::vector<Element> elements_;
  std::optional<std::size_t> vertex_, face_, indices_;
  std::optional<std::size_t> xyz_[3];
  std::size_t pos_ = 0;           // binary: the next byte
  std::size_t value_offset_ = 0;  // binary: where the last value started
  std::string_view rest_;         // ASCII: what is left of the instance's line
  std::vector<float> positions_;
  std::vector<float>* coords_ = nullptr;
};

}  // namespace

MeshInput read_ply(std::span<const std::uint8_t> bytes, const StlReadOptions& options) {
  options.validate();
  return PlyReader(bytes, options).parse();
}

}  // namespace stlrefine
