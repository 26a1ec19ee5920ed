// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "slicer/writers.h"

#include <gtest/gtest.h>

#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "tests/slicer/slicer_test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

using slicer::Layer;
using slicer::LoopKind;
using slicer::SliceFormat;

// Box with a cavity holding an island, plus a separate open box: outer loops, holes, an
// island and open polylines in one part.
Mesh mixed_part() {
  const IndexedSoup nested =
      merged(merged(cube_soup(10.0), translated(inverted(cube_soup(6.0)), {2, 2, 2})),
             translated(cube_soup(2.0), {4, 4, 4}));
  return to_mesh(merged(nested, translated(open_box_soup(4.0), {-20.5, -3.25, 1.0})));
}

std::string write(const Mesh& mesh, const slicer::SliceParams& params, SliceFormat format,
                  slicer::WriterOptions options = {}) {
  const auto writer = slicer::make_writer(format, options);
  return slicer::write_slices_to_string(mesh, params, *writer);
}

// ------------------------------------------------------------------ an independent CLI reader

struct CliPolyline {
  int id = 0, dir = 0;
  std::vector<double> xy;
};
struct CliLayer {
  double z = 0;
  std::vector<CliPolyline> polylines;
};
struct CliFile {
  bool binary = false;
  double units = 0;
  int version = 0;
  std::size_t declared_layers = 0;
  std::string label;
  std::vector<double> dimension;
  std::vector<CliLayer> layers;
  bool geometry_end = false;
};

std::vector<double> split_numbers(std::string_view text) {
  std::vector<double> out;
  std::string s(text);
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) out.push_back(std::strtod(item.c_str(), nullptr));
  return out;
}

// Reads the header line by line up to $$HEADEREND, then ASCII commands or binary long/short
// commands (little-endian), as the CLI 2.0 specification describes them.
CliFile read_cli(const std::string& bytes) {
  CliFile file;
  std::size_t pos = bytes.find("$$HEADERSTART");
  EXPECT_EQ(pos, 0u);
  const std::size_t header_end = bytes.find("$$HEADEREND");
  EXPECT_NE(header_end, std::string::npos);
  std::stringstream header(bytes.substr(0, header_end));
  for (std::string line; std::getline(header, line);) {
    if (line == "$$BINARY") file.binary = true;
    if (line.rfind("$$UNITS/", 0) == 0) file.units = std::strtod(line.c_str() + 8, nullptr);
    if (line.rfind("$$VERSION/", 0) == 0) file.version = std::atoi(line.c_str() + 10);
    if (line.rfind("$$LAYERS/", 0) == 0)
      file.declared_layers = std::size_t(std::atol(line.c_str() + 9));
    if (line.rfind("$$LABEL/", 0) == 0) file.label = line.substr(8);
    if (line.rfind("$$DIMENSION/", 0) == 0) file.dimension = split_numbers(line.substr(12));
  }
  pos = header_end + std::strlen("$$HEADEREND");
  if (file.binary) {
    const auto take = [&](auto& value) {
      EXPECT_LE(pos + sizeof(value), bytes.size());
      std::memcpy(&value, bytes.data() + pos, sizeof(value));
      pos += sizeof(value);
    };
    while (pos < bytes.size()) {
      std::uint16_t command = 0;
      take(command);
      if (command == 127) {  // start layer, long
        float z;
        take(z);
        file.layers.push_back({z, {}});
      } else if (command == 128) {  // start layer, short
        std::uint16_t z;
        take(z);
        file.layers.push_back({double(z), {}});
      } else if (command == 130) {  // start polyline, long
        std::int32_t id, dir, n;
        take(id), take(dir), take(n);
        CliPolyline p{id, dir, {}};
        for (std::int32_t i = 0; i < 2 * n; ++i) {
          float v;
          take(v);
          p.xy.push_back(v);
        }
        EXPECT_FALSE(file.layers.empty());
        file.layers.back().polylines.push_back(p);
      } else {
        ADD_FAILURE() << "unexpected binary command " << command << " at byte " << pos - 2;
        break;
      }
    }
    return file;
  }
  std::stringstream geometry(bytes.substr(pos));
  std::string line;
  std::getline(geometry, line);  // the rest of the $$HEADEREND line
  std::getline(geometry, line);
  EXPECT_EQ(line, "$$GEOMETRYSTART");
  while (std::getline(geometry, line)) {
    if (line.rfind("$$LAYER/", 0) == 0) {
      file.layers.push_back({std::strtod(line.c_str() + 8, nullptr), {}});
    } else if (line.rfind("$$POLYLINE/", 0) == 0) {
      const std::vector<double> v = split_numbers(line.substr(11));
      EXPECT_GE(v.size(), 3u);
      CliPolyline p{int(v[0]), int(v[1]), std::vector<double>(v.begin() + 3, v.end())};
      EXPECT_EQ(std::size_t(v[2]) * 2, p.xy.size()) << line;
      EXPECT_FALSE(file.layers.empty());
      file.layers.back().polylines.push_back(p);
    } else if (line == "$$GEOMETRYEND") {
      file.geometry_end = true;
    } else {
      ADD_FAILURE() << "unexpected line " << line;
    }
  }
  return file;
}

// Each CLI layer holds the slicer's loops (dir 1 outer, 0 hole; first point repeated at the
// end) then its open polylines (dir 2), with the same coordinates up to `cast`.
template <class Cast>
void expect_cli_matches(const CliFile& file, const std::vector<Layer>& layers, Cast cast) {
  ASSERT_EQ(file.layers.size(), layers.size());
  EXPECT_EQ(file.declared_layers, layers.size());
  for (std::size_t k = 0; k < layers.size(); ++k) {
    const Layer& l = layers[k];
    EXPECT_EQ(file.layers[k].z, cast(l.z));
    ASSERT_EQ(file.layers[k].polylines.size(), l.loops.size() + l.open.size()) << "layer " << k;
    for (std::size_t i = 0; i < file.layers[k].polylines.size(); ++i) {
      const CliPolyline& p = file.layers[k].polylines[i];
      const bool closed = i < l.loops.size();
      const auto& pts = closed ? l.loops[i].points : l.open[i - l.loops.size()].points;
      EXPECT_EQ(p.id, 1);
      EXPECT_EQ(p.dir, closed ? (l.loops[i].kind == LoopKind::Outer ? 1 : 0) : 2);
      ASSERT_EQ(p.xy.size(), 2 * (pts.size() + (closed ? 1 : 0)));
      for (std::size_t j = 0; j < p.xy.size() / 2; ++j) {
        const auto& q = pts[j % pts.size()];  // the repeated first point wraps around
        EXPECT_EQ(p.xy[2 * j], cast(q.x));
        EXPECT_EQ(p.xy[2 * j + 1], cast(q.y));
      }
    }
  }
}

TEST(CliWriter, AsciiReadsBackToTheSameContours) {
  const Mesh mesh = mixed_part();
  const auto params = uniform(0.7);
  const CliFile file = read_cli(write(mesh, params, SliceFormat::CliAscii, {"my part, v2", 1.0}));
  EXPECT_FALSE(file.binary);
  EXPECT_EQ(file.units, 1.0);
  EXPECT_EQ(file.version, 200);
  EXPECT_EQ(file.label, "1,my part_ v2");  // commas would split the label
  EXPECT_TRUE(file.geometry_end);
  ASSERT_EQ(file.dimension.size(), 6u);
  EXPECT_EQ(file.dimension[0], -20.5);
  EXPECT_EQ(file.dimension[5], 10.0);
  const auto layers = slicer::slice_all(mesh, params);
  std::size_t holes = 0, open = 0;
  for (const auto& l : layers) {
    for (const auto& loop : l.loops) holes += loop.kind == LoopKind::Hole;
    open += l.open.size();
  }
  ASSERT_GT(holes, 0u);
  ASSERT_GT(open, 0u);
  expect_cli_matches(file, layers, [](double v) { return v; });  // exact round trip
}

TEST(CliWriter, AsciiUnitsScaleEveryCoordinate) {
  const Mesh mesh = to_mesh(cube_soup(10.0));
  const CliFile file = read_cli(write(mesh, uniform(5.0), SliceFormat::CliAscii, {"cube", 0.5}));
  EXPECT_EQ(file.units, 0.5);
  ASSERT_EQ(file.layers.size(), 2u);
  EXPECT_EQ(file.layers[0].z, 5.0);                    // 2.5 mm in units of 0.5 mm
  const auto& xy = file.layers[1].polylines.at(0).xy;  // the 10 mm square is 20 units wide
  ASSERT_EQ(xy.size(), 2u * 9u);                       // corners and side diagonals, closed
  for (std::size_t i = 0; i < xy.size(); i += 2) {
    EXPECT_TRUE(xy[i] == 0 || xy[i] == 20 || xy[i + 1] == 0 || xy[i + 1] == 20);
    EXPECT_TRUE(xy[i] >= 0 && xy[i] <= 20 && xy[i + 1] >= 0 && xy[i + 1] <= 20);
  }
}

TEST(CliWriter, BinaryReadsBackToTheSameContours) {
  const Mesh mesh = mixed_part();
  const auto params = uniform(0.7);
  const std::string bytes = write(mesh, params, SliceFormat::CliBinary);
  // The binary geometry starts right after "$$HEADEREND": no line break, no GEOMETRYSTART.
  const std::size_t end = bytes.find("$$HEADEREND") + std::strlen("$$HEADEREND");
  ASSERT_GE(bytes.size(), end + 6);
  EXPECT_EQ(std::uint8_t(bytes[end]), 127);
  EXPECT_EQ(std::uint8_t(bytes[end + 1]), 0);
  EXPECT_EQ(bytes.find("$$GEOMETRY"), std::string::npos);
  const CliFile file = read_cli(bytes);
  EXPECT_TRUE(file.binary);
  expect_cli_matches(file, slicer::slice_all(mesh, params),
                     [](double v) { return double(float(v)); });
}

// ------------------------------------------------------------------ JSON

TEST(JsonWriter, ParsesWithTheSchemaAndExactNumbers) {
  const Mesh mesh = mixed_part();
  const auto params = uniform(0.7);
  const nlohmann::json doc =
      nlohmann::json::parse(write(mesh, params, SliceFormat::Json, {"part \"7\"", 1}));
  const auto layers = slicer::slice_all(mesh, params);
  EXPECT_EQ(doc.at("format"), "stlrefine-slices");
  EXPECT_EQ(doc.at("version"), 1);
  EXPECT_EQ(doc.at("units"), "mm");
  EXPECT_EQ(doc.at("name"), "part _7_");
  EXPECT_EQ(doc.at("layer_height"), 0.7);
  EXPECT_EQ(doc.at("bounds").at("min"), nlohmann::json({-20.5, -3.25, 0.0}));
  EXPECT_EQ(doc.at("layer_count"), layers.size());
  ASSERT_EQ(doc.at("layers").size(), layers.size());
  std::size_t outer = 0, holes = 0;
  for (std::size_t k = 0; k < layers.size(); ++k) {
    const auto& jl = doc["layers"][k];
    const Layer& l = layers[k];
    EXPECT_EQ(jl.at("index"), k);
    EXPECT_EQ(jl.at("z").get<double>(), l.z);
    EXPECT_EQ(jl.at("area").get<double>(), l.area);
    ASSERT_EQ(jl.at("polygons").size(), l.loops.size());
    for (std::size_t i = 0; i < l.loops.size(); ++i) {
      const auto& jp = jl["polygons"][i];
      const auto& loop = l.loops[i];
      EXPECT_EQ(jp.at("type"), loop.kind == LoopKind::Outer ? "outer" : "hole");
      ++(loop.kind == LoopKind::Outer ? outer : holes);
      if (loop.parent < 0) {
        EXPECT_TRUE(jp.at("parent").is_null());
      } else {
        EXPECT_EQ(jp.at("parent"), loop.parent);
        EXPECT_LT(jp.at("parent").get<int>(), int(i));
      }
      EXPECT_EQ(jp.at("depth"), loop.depth);
      EXPECT_EQ(jp.at("area").get<double>(), loop.area);
      ASSERT_EQ(jp.at("points").size(), loop.points.size());
      for (std::size_t j = 0; j < loop.points.size(); ++j) {
        EXPECT_EQ(jp["points"][j][0].get<double>(), loop.points[j].x);
        EXPECT_EQ(jp["points"][j][1].get<double>(), loop.points[j].y);
      }
    }
    ASSERT_EQ(jl.at("open").size(), l.open.size());
    for (std::size_t i = 0; i < l.open.size(); ++i)
      EXPECT_EQ(jl["open"][i].at("points").size(), l.open[i].points.size());
  }
  EXPECT_EQ(doc.at("summary").at("outer_loops"), outer);
  EXPECT_EQ(doc.at("summary").at("holes"), holes);
  EXPECT_GT(holes, 0u);
}

TEST(JsonWriter, EmptyMeshRangeStillGivesAValidDocument) {
  const Mesh cube = to_mesh(cube_soup(1.0));
  const auto doc = nlohmann::json::parse(write(cube, at({5.0, 6.0}), SliceFormat::Json));
  EXPECT_TRUE(doc.at("layer_height").is_null());
  ASSERT_EQ(doc.at("layers").size(), 2u);
  EXPECT_TRUE(doc["layers"][0].at("polygons").empty());
}

// ------------------------------------------------------------------ SVG

// Minimal XML well-formedness: one prolog, then properly nested and closed elements.
::testing::AssertionResult well_formed(const std::string& xml) {
  std::vector<std::string> stack;
  std::size_t pos = 0, elements = 0;
  if (xml.rfind("<?xml", 0) != 0) return ::testing::AssertionFailure() << "no XML declaration";
  while ((pos = xml.find('<', pos)) != std::string::npos) {
    const std::size_t end = xml.find('>', pos);
    if (end == std::string::npos) return ::testing::AssertionFailure() << "unclosed tag at " << pos;
    const std::string tag = xml.substr(pos + 1, end - pos - 1);
    pos = end + 1;
    if (tag[0] == '?') continue;
    if (tag.find('<') != std::string::npos) return ::testing::AssertionFailure() << "'<' in a tag";
    if (tag[0] == '/') {
      if (stack.empty() || stack.back() != tag.substr(1))
        return ::testing::AssertionFailure() << "</" << tag.substr(1) << "> closes nothing open";
      stack.pop_back();
      continue;
    }
    ++elements;
    if (tag.back() == '/') continue;
    stack.push_back(tag.substr(0, tag.find_first_of(" \n")));
  }
  if (!stack.empty()) return ::testing::AssertionFailure() << "<" << stack.back() << "> not closed";
  return ::testing::AssertionSuccess() << elements << " elements";
}

TEST(SvgWriter, IsWellFormedWithOneGroupPerLayerAndEvenOddHoles) {
  const Mesh mesh = mixed_part();
  const auto params = uniform(0.7);
  const std::string svg = write(mesh, params, SliceFormat::Svg, {"<b&d>", 1});
  EXPECT_TRUE(well_formed(svg));
  const auto layers = slicer::slice_all(mesh, params);
  std::size_t groups = 0, paths = 0, polylines = 0, closes = 0;
  for (std::size_t p = 0; (p = svg.find("<g id=\"layer-", p)) != std::string::npos; ++p) ++groups;
  for (std::size_t p = 0; (p = svg.find("<path ", p)) != std::string::npos; ++p) ++paths;
  for (std::size_t p = 0; (p = svg.find("<polyline ", p)) != std::string::npos; ++p) ++polylines;
  for (std::size_t p = 0; (p = svg.find('Z', p)) != std::string::npos; ++p) ++closes;
  std::size_t loops = 0, open = 0, non_empty = 0;
  for (const auto& l : layers) {
    loops += l.loops.size();
    open += l.open.size();
    non_empty += !l.loops.empty();
  }
  EXPECT_EQ(groups, layers.size());
  EXPECT_EQ(paths, non_empty);  // one path per layer: all its loops, holes cut by evenodd
  EXPECT_EQ(closes, loops);
  EXPECT_EQ(polylines, open);
  EXPECT_NE(svg.find("fill-rule:evenodd"), std::string::npos);
  EXPECT_NE(svg.find("viewBox=\""), std::string::npos);
  EXPECT_NE(svg.find("<title>_b_d_: "), std::string::npos);
  EXPECT_NE(svg.find("id=\"layer-0\""), std::string::npos);
}

// ------------------------------------------------------------------ streaming and files

TEST(WriteSlices, StreamsHeaderThenEachLayerThenFooter) {
  const Mesh mesh = to_mesh(icosphere_soup(3, 10.0));
  const auto writer = slicer::make_writer(SliceFormat::CliAscii);
  std::vector<std::string> chunks;
  slicer::SliceParams params = uniform(0.5);
  params.threads = 2;
  slicer::write_slices(mesh, params, *writer,
                       [&](std::string_view bytes) { chunks.emplace_back(bytes); });
  ASSERT_EQ(chunks.size(), 40u + 2u);
  EXPECT_EQ(chunks.front().rfind("$$HEADERSTART", 0), 0u);
  EXPECT_EQ(chunks.back(), "$$GEOMETRYEND\n");
  for (std::size_t k = 0; k < 40; ++k) {
    const std::string& c = chunks[k + 1];
    ASSERT_EQ(c.rfind("$$LAYER/", 0), 0u);
    EXPECT_EQ(std::strtod(c.c_str() + 8, nullptr), -10.0 + 0.25 + 0.5 * double(k));
  }
}

TEST(WriteSlices, ParallelAndSingleThreadedBytesAreIdentical) {
  RefineParams rp;
  rp.levels = 2;
  const Mesh mesh = refine(to_mesh(torus_soup(24, 12, 15, 5)), rp).mesh;
  for (SliceFormat format :
       {SliceFormat::Json, SliceFormat::Svg, SliceFormat::CliAscii, SliceFormat::CliBinary}) {
    slicer::SliceParams p = uniform(0.1);
    p.threads = 1;
    const std::string one = write(mesh, p, format);
    p.threads = 2;
    EXPECT_EQ(one, write(mesh, p, format)) << slicer::to_string(format);
  }
}

TEST(WriteSlices, RefusedRequestWritesNothingAndLeavesNoFile) {
  const Mesh mesh = to_mesh(cube_soup(10.0));
  slicer::SliceParams p = uniform(1.0);
  p.max_points = 5;
  const auto writer = slicer::make_writer(SliceFormat::Json);
  std::string out;
  EXPECT_EQ(error_of([&] {
              slicer::write_slices(mesh, p, *writer, [&](std::string_view b) { out.append(b); });
            }),
            "budget_exceeded:max_points");
  EXPECT_TRUE(out.empty());

  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "stlrefine_slicer_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  EXPECT_EQ(error_of([&] { slicer::write_slices_file(dir / "x.json", mesh, p, *writer); }),
            "budget_exceeded:max_points");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  p.max_points = 1000;
  slicer::write_slices_file(dir / "x.json", mesh, p, *writer);
  std::ifstream in(dir / "x.json");
  const auto doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc.at("layers").size(), 10u);
  std::filesystem::remove_all(dir);
}

// ------------------------------------------------- empty layers cost output (issue 16, item 8)

constexpr SliceFormat kFormats[] = {SliceFormat::Json, SliceFormat::Svg, SliceFormat::CliAscii,
                                    SliceFormat::CliBinary};

// The fewest bytes one more contour point adds in each format (writers.h).
std::size_t point_bytes(SliceFormat format) {
  return format == SliceFormat::Json ? 6 : format == SliceFormat::CliBinary ? 8 : 4;
}

// One facet, as the 134-byte binary STL a client would upload, read and welded: the
// triangle (0,0,0) (1,0,0) (0,1,top).
Mesh single_triangle(float top) {
  std::string bytes(80, 'x');
  const std::uint32_t count = 1;
  const float facet[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, top};
  bytes.append(reinterpret_cast<const char*>(&count), 4);
  bytes.append(reinterpret_cast<const char*>(facet), sizeof facet);
  bytes.append(2, '\0');
  EXPECT_EQ(bytes.size(), 134u);
  const std::span<const std::uint8_t> view(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                                           bytes.size());
  return build_mesh(weld(read_stl(view))).mesh;
}

// A sink that refuses to grow past `limit` bytes: a request that should have been refused
// up front fails fast instead of building a 140 MB string.
struct CappedSink {
  std::size_t limit;
  std::string out;
  void operator()(std::string_view bytes) {
    out.append(bytes);
    if (out.size() > limit)
      throw std::runtime_error("the output passed " + std::to_string(limit) + " bytes");
  }
};

TEST(WriteSlices, AMillionEmptySvgLayersOfOneTriangleAreRefusedBeforeAnyByte) {
  // The reproduction: a flat 134-byte triangle, z from 0 to 100 mm at 0.1 um, under the
  // daemon's default point cap. Today: 999,999 empty <g> groups, 140 MB.
  const Mesh triangle = single_triangle(0);
  slicer::SliceParams p = uniform(1e-4);
  p.z_min = 0;
  p.z_max = 100;
  p.max_points = 20'000'000;
  const auto writer = slicer::make_writer(SliceFormat::Svg);
  CappedSink sink{1 << 20, {}};
  try {
    slicer::write_slices(triangle, p, *writer, [&](std::string_view b) { sink(b); });
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded) << e.what();
    EXPECT_EQ(e.field(), "max_points");
    EXPECT_EQ(e.reason(), "point_budget");
    EXPECT_NE(std::string(e.what()).find("1000000 layers"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(sink.out.empty());
  // The same through explicit heights: every layer counts, wherever it is.
  slicer::SliceParams h;
  for (int k = 0; k < 1000; ++k) h.heights.push_back(1 + k * 0.1);
  h.max_points = 999 * slicer::empty_layer_points(SliceFormat::Svg);
  EXPECT_EQ(error_of([&] {
              slicer::write_slices(triangle, h, *writer, [&](std::string_view b) { sink(b); });
            }),
            "budget_exceeded:max_points");
  EXPECT_TRUE(sink.out.empty());
}

TEST(WriteSlices, EachFormatChargesWhatItsEmptyLayersCost) {
  // 2,000 planes over a flat triangle at z = 0: every layer empty, no contour point. The
  // budget they need is exactly layers x empty_layer_points, refused one point below
  // (nothing written), and what is then written fits in that many of the format's
  // shortest points (plus header and footer).
  const Mesh triangle = single_triangle(0);
  for (const SliceFormat format : kFormats) {
    SCOPED_TRACE(slicer::to_string(format));
    const std::uint64_t per_layer = slicer::empty_layer_points(format);
    EXPECT_GE(per_layer, 1u);
    slicer::SliceParams p = uniform(0.01);
    p.z_min = 0;
    p.z_max = 20;
    const std::uint64_t layers = 2000;
    const auto writer = slicer::make_writer(format);
    p.max_points = layers * per_layer - 1;
    CappedSink refused{1 << 20, {}};
    EXPECT_EQ(error_of([&] {
                slicer::write_slices(triangle, p, *writer, [&](std::string_view b) { refused(b); });
              }),
              "budget_exceeded:max_points");
    EXPECT_TRUE(refused.out.empty());

    p.max_points = layers * per_layer;
    CappedSink written{1 << 24, {}};
    const slicer::SliceStats stats =
        slicer::write_slices(triangle, p, *writer, [&](std::string_view b) { written(b); });
    EXPECT_EQ(stats.layers, layers);
    EXPECT_EQ(stats.crossings, 0u);
    EXPECT_LE(written.out.size(), p.max_points * point_bytes(format) + 4096);
    // The charge is not far above the cost either (heights here are short numbers).
    EXPECT_GE(written.out.size(), p.max_points * point_bytes(format) / 4);
  }
}

TEST(SliceParams, PointsPerLayerIsChargedByThePlanAndTheSweep) {
  const Mesh triangle = single_triangle(10);
  slicer::SliceParams p = uniform(1.0);  // 10 layers, each crossing the triangle once
  p.points_per_layer = 7;
  p.max_points = 69;
  EXPECT_EQ(error_of([&] { slicer::plan_layers(triangle, p); }), "budget_exceeded:max_points");
  p.max_points = 70;  // the plan fits; its 10 crossings do not
  EXPECT_EQ(slicer::plan_layers(triangle, p).heights.size(), 10u);
  bool called = false;
  EXPECT_EQ(error_of([&] { slicer::slice(triangle, p, [&](Layer&&) { called = true; }); }),
            "budget_exceeded:max_points");
  EXPECT_FALSE(called);
  p.max_points = 80;
  EXPECT_EQ(slicer::slice_all(triangle, p).size(), 10u);
  p.points_per_layer = (std::uint64_t{1} << 20) + 1;
  EXPECT_EQ(error_of([&] { p.validate(); }), "invalid_parameter:points_per_layer");
}

TEST(Formats, NamesParseAndBadOnesNameTheField) {
  for (SliceFormat f :
       {SliceFormat::Json, SliceFormat::Svg, SliceFormat::CliAscii, SliceFormat::CliBinary})
    EXPECT_EQ(slicer::parse_slice_format(slicer::to_string(f)), f);
  EXPECT_EQ(slicer::parse_slice_format("cli-ascii"), SliceFormat::CliAscii);
  EXPECT_EQ(error_of([] { slicer::parse_slice_format("dxf"); }), "invalid_parameter:format");
  EXPECT_EQ(error_of([] {
              slicer::make_writer(SliceFormat::CliAscii, {"x", 0.0});
            }),
            "invalid_parameter:cli_units");
  EXPECT_STREQ(slicer::media_type(SliceFormat::Svg), "image/svg+xml");
}

}  // namespace
}  // namespace stlrefine::test
