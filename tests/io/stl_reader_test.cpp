// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "core/io/stl.h"
#include "tests/io/allocation_probe.h"
#include "tests/io/io_test_util.h"

namespace stlrefine::test {
namespace {

// Lines: 1 solid, 2 facet, 3 outer loop, 4-6 vertex, 7 endloop, 8 endfacet, 9 endsolid.
const std::string kOneFacet =
    "solid one\n"
    "  facet normal 0 0 1\n"
    "    outer loop\n"
    "      vertex 0 0 0\n"
    "      vertex 1 0 0\n"
    "      vertex 0 1 0\n"
    "    endloop\n"
    "  endfacet\n"
    "endsolid one\n";

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

bool contains(const Error& e, const std::string& text) {
  return std::string(e.what()).find(text) != std::string::npos;
}

// --- the shared corpus, small copies in tests/data -------------------------------------

TEST(StlReader, ReadsBinaryGearwheel) {
  const TriangleSoup soup = read_stl_file(data_file("gearwheel.stl"));
  EXPECT_EQ(soup.format, StlFormat::Binary);
  EXPECT_EQ(soup.triangle_count(), 2444u);
  EXPECT_EQ(soup.name, "gearwheel");
  EXPECT_EQ(soup.trailing_bytes, 0u);
}

TEST(StlReader, ReadsSolidHeaderBinaryAsBinary) {
  const TriangleSoup soup = read_stl_file(data_file("malformed/solid_header_binary.stl"));
  EXPECT_EQ(soup.format, StlFormat::Binary);
  EXPECT_EQ(soup.triangle_count(), 2444u);
  EXPECT_EQ(soup.name, "solid gearwheel exported as BINARY stl");
  EXPECT_EQ(soup.coords, read_stl_file(data_file("gearwheel.stl")).coords);
}

TEST(StlReader, RejectsTruncatedSolidHeaderBinaryAsBinary) {
  // A "solid" prefix must not turn a damaged binary file into an ASCII syntax error.
  Bytes bytes = load(data_file("malformed/solid_header_binary.stl"));
  bytes.resize(84 + 50 * 10 + 7);
  const Error e = expect_malformed(bytes, "truncated");
  EXPECT_EQ(e.byte_offset(), 84u + 50 * 10);
}

TEST(StlReader, RejectsHeaderCountTooHigh) {
  const Error e =
      expect_malformed(load(data_file("malformed/bad_count_high.stl")), "count_mismatch");
  EXPECT_EQ(e.byte_offset(), 80u);
  EXPECT_TRUE(contains(e, "2544")) << e.what();
  EXPECT_TRUE(contains(e, "122284 bytes")) << e.what();
  EXPECT_TRUE(contains(e, "implies 2444 triangles")) << e.what();
}

TEST(StlReader, RejectsHeaderCountTooLow) {
  const Bytes bytes = load(data_file("malformed/bad_count_low.stl"));
  const Error e = expect_malformed(bytes, "count_mismatch");
  EXPECT_TRUE(contains(e, "2344")) << e.what();
  EXPECT_TRUE(contains(e, "implies 2444 triangles")) << e.what();
  // 100 surplus facets are geometry, not padding: allowing trailing bytes does not drop them.
  StlReadOptions lenient;
  lenient.allow_trailing_bytes = true;
  expect_malformed(bytes, "count_mismatch", lenient);
}

TEST(StlReader, RejectsZeroHeaderCountWithFacets) {
  const Error e = expect_malformed(load(data_file("malformed/count_zero.stl")), "count_mismatch");
  EXPECT_TRUE(contains(e, "says 0 triangles")) << e.what();
  EXPECT_TRUE(contains(e, "implies 2444 triangles")) << e.what();
}

TEST(StlReader, RejectsTruncatedFacet) {
  const Error e = expect_malformed(load(data_file("malformed/truncated.stl")), "truncated");
  EXPECT_EQ(e.byte_offset(), 84u + 50 * 1222);
  EXPECT_TRUE(contains(e, "inside facet 1222")) << e.what();
  EXPECT_TRUE(contains(e, "2444")) << e.what();
}

TEST(StlReader, RejectsNonFiniteCoordinatesWithFacetAndOffset) {
  // Facets 10, 20 and 30 hold NaN, +inf and -inf: each is reported in turn, by facet and
  // by the byte offset of the offending float, once the earlier ones are repaired.
  Bytes bytes = load(data_file("malformed/nan_coords.stl"));
  const auto repair = [&](std::size_t facet) {
    std::memcpy(&bytes[84 + 50 * facet + 12], &bytes[84 + 50 * (facet - 1) + 12], 36);
  };
  Error e = expect_malformed(bytes, "non_finite");
  EXPECT_EQ(e.byte_offset(), 84u + 50 * 10 + 12);  // vertex 0, x
  EXPECT_TRUE(contains(e, "facet 10, vertex 0: x")) << e.what();
  EXPECT_TRUE(contains(e, "NaN")) << e.what();
  repair(10);
  e = expect_malformed(bytes, "non_finite");
  EXPECT_EQ(e.byte_offset(), 84u + 50 * 20 + 12 + 4 * 4);  // vertex 1, y
  EXPECT_TRUE(contains(e, "+inf")) << e.what();
  repair(20);
  e = expect_malformed(bytes, "non_finite");
  EXPECT_EQ(e.byte_offset(), 84u + 50 * 30 + 12 + 4 * 8);  // vertex 2, z
  EXPECT_TRUE(contains(e, "-inf")) << e.what();
  repair(30);
  // Facet 40 only has a NaN stored normal: normals are ignored, so the file now reads.
  EXPECT_EQ(read_stl(bytes).triangle_count(), 252u);
}

struct CorpusCase {
  const char* file;
  std::size_t triangles;
  std::size_t vertices;  // after exact welding
};

TEST(StlReader, ReadsTopologyEdgeCasesAsIs) {
  // These files are valid STL; their defects are ingest's business, not the reader's.
  for (const CorpusCase& c :
       {CorpusCase{"nonmanifold_fin.stl", 13, 9}, CorpusCase{"two_cubes_shared_edge.stl", 24, 14},
        CorpusCase{"degenerate_tjunction.stl", 15, 9},
        CorpusCase{"issue945e_zero_area.stl", 94, 49}, CorpusCase{"flipped_facets.stl", 252, 128},
        CorpusCase{"open_cylinder.stl", 70, 48}}) {
    SCOPED_TRACE(c.file);
    const TriangleSoup soup = read_stl_file(data_file(std::string("malformed/") + c.file));
    EXPECT_EQ(soup.format, StlFormat::Binary);
    EXPECT_EQ(soup.triangle_count(), c.triangles);
    const IndexedSoup welded = weld(soup);
    EXPECT_EQ(welded.triangles.size(), c.triangles);
    EXPECT_EQ(welded.positions.size(), c.vertices);
  }
}

TEST(StlReader, AsciiGearwheelMatchesBinary) {
  const auto ascii_path = shared_file("malformed/gearwheel_ascii.stl");
  if (!std::filesystem::exists(ascii_path)) GTEST_SKIP() << ascii_path << " is absent";
  const TriangleSoup ascii = read_stl_file(ascii_path);
  const TriangleSoup binary = read_stl_file(data_file("gearwheel.stl"));
  EXPECT_EQ(ascii.format, StlFormat::Ascii);
  EXPECT_EQ(ascii.name, "gearwheel");
  ASSERT_EQ(ascii.coords.size(), binary.coords.size());
  double worst = 0;
  for (std::size_t i = 0; i < ascii.coords.size(); ++i) {
    worst = std::max(worst, std::fabs(double(ascii.coords[i]) - double(binary.coords[i])));
  }
  EXPECT_LE(worst, 6e-6);
  const IndexedSoup a = weld(ascii);
  const IndexedSoup b = weld(binary);
  EXPECT_EQ(a.positions.size(), 1222u);
  EXPECT_EQ(a.positions.size(), b.positions.size());
  EXPECT_EQ(a.triangles, b.triangles);
}

TEST(StlReader, ReadsLargeNonManifoldCorpusFile) {
  const auto path = shared_file("malformed/cycloidal_nonmanifold.stl");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent";
  const TriangleSoup soup = read_stl_file(path);
  EXPECT_EQ(soup.triangle_count(), 43368u);
  EXPECT_EQ(weld(soup).positions.size(), 21384u);
}

// --- binary, synthetic -------------------------------------------------------------------

TEST(StlReader, RejectsEmptyInput) {
  const Error e = expect_malformed(Bytes{}, "too_small");
  EXPECT_EQ(e.byte_offset(), 0u);
}

TEST(StlReader, Rejects83Bytes) {
  const Error e = expect_malformed(Bytes(83, 0), "too_small");
  EXPECT_EQ(e.byte_offset(), 83u);
}

TEST(StlReader, RejectsHeaderWithZeroTriangles) {
  const Error e = expect_malformed(binary_stl({}), "zero_triangles");
  EXPECT_EQ(e.byte_offset(), 80u);
}

TEST(StlReader, ReadsOneBinaryFacet) {
  const TriangleSoup soup = read_stl(binary_stl({unit_triangle(5)}, "  part 7  "));
  EXPECT_EQ(soup.name, "part 7");
  ASSERT_EQ(soup.triangle_count(), 1u);
  const std::array<float, 9> expected = unit_triangle(5);
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), soup.coords.begin()));
}

TEST(StlReader, RejectsHugeCountWithoutAllocating) {
  // 2^32-1 triangles would need 200 GB; the file has 2 facets. Nothing may be allocated
  // from the count: the probe refuses (and records) every request above 1 MB.
  Bytes bytes = binary_stl({unit_triangle(), unit_triangle(2)}, "x", 0xFFFFFFFFu);
  {
    AllocationProbe probe(1 << 20);
    const Error e = expect_malformed(bytes, "count_mismatch");
    EXPECT_TRUE(contains(e, "4294967295 triangles (214748364834 bytes)")) << e.what();
    EXPECT_TRUE(contains(e, "implies 2 triangles")) << e.what();
    EXPECT_FALSE(probe.refused());
    EXPECT_GT(probe.largest(), 0u);  // the probe is live: the message was allocated
    EXPECT_LT(probe.largest(), 1u << 20);
  }
  bytes.resize(bytes.size() - 7);
  AllocationProbe probe(1 << 20);
  expect_malformed(bytes, "truncated");
  EXPECT_FALSE(probe.refused());
}

TEST(StlReader, RejectsTrailingBytesByDefault) {
  Bytes bytes = binary_stl({unit_triangle()});
  bytes.insert(bytes.end(), {0, 0, 0});
  const Error e = expect_malformed(bytes, "trailing_bytes");
  EXPECT_EQ(e.byte_offset(), 134u);
  // Issue 16: no field, and no advice to set an option neither the HTTP API nor the CLI
  // has; the message says what is wrong with the file.
  EXPECT_EQ(e.field(), "");
  EXPECT_FALSE(contains(e, "allow_trailing_bytes")) << e.what();
  EXPECT_TRUE(contains(e, "3 stray bytes after the last of 1 facets (from byte 134)")) << e.what();
}

TEST(StlReader, AcceptsTrailingBytesWhenAllowed) {
  StlReadOptions lenient;
  lenient.allow_trailing_bytes = true;
  Bytes bytes = binary_stl({unit_triangle()});
  bytes.resize(bytes.size() + 49, 0xAB);
  const TriangleSoup soup = read_stl(bytes, lenient);
  EXPECT_EQ(soup.triangle_count(), 1u);
  EXPECT_EQ(soup.trailing_bytes, 49u);
  // One byte more is a whole extra facet: that is a count problem, not padding.
  bytes.push_back(0);
  expect_malformed(bytes, "count_mismatch", lenient);
}

TEST(StlReader, RejectsMoreTrianglesThanTheLimit) {
  StlReadOptions options;
  options.max_triangles = 1;
  const Error e = expect_malformed(binary_stl({unit_triangle(), unit_triangle(1)}),
                                   "too_many_triangles", options);
  EXPECT_EQ(e.field(), "max_triangles");
}

TEST(StlReader, RejectsCoordinatesBeyondTheLimit) {
  std::array<float, 9> far = unit_triangle();
  far[4] = 2e9f;  // vertex 1, y
  const Error e = expect_malformed(binary_stl({unit_triangle(), far}), "coordinate_out_of_range");
  EXPECT_EQ(e.byte_offset(), 84u + 50 + 12 + 16);
  EXPECT_EQ(e.field(), "max_abs_coordinate");

  StlReadOptions unlimited;
  unlimited.max_abs_coordinate = std::numeric_limits<double>::infinity();
  EXPECT_EQ(read_stl(binary_stl({far}), unlimited).triangle_count(), 1u);

  StlReadOptions ten;
  ten.max_abs_coordinate = 10;
  std::array<float, 9> edge = unit_triangle();
  edge[0] = -10.0f;
  EXPECT_EQ(read_stl(binary_stl({edge}), ten).triangle_count(), 1u);
  edge[0] = -10.000001f;
  expect_malformed(binary_stl({edge}), "coordinate_out_of_range", ten);
}

// --- not STL at all ------------------------------------------------------------------------

TEST(StlReader, RejectsPly) {
  const Error e = expect_malformed(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
      "not_stl");
  EXPECT_TRUE(contains(e, "PLY")) << e.what();
  // Binary PLY: a text header followed by floats.
  Bytes binary = bytes_of(
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n");
  binary.resize(binary.size() + 36, 0x3f);
  expect_malformed(binary, "not_stl");
}

TEST(StlReader, RejectsObj) {
  const Error e = expect_malformed("# exported\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not_stl");
  EXPECT_TRUE(contains(e, "OBJ")) << e.what();
  expect_malformed("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not_stl");
}

TEST(StlReader, RejectsRandomBytes) {
  std::mt19937 rng(12345);
  for (const std::size_t size : {200u, 4096u, 100'000u}) {
    SCOPED_TRACE(size);
    Bytes bytes(size);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    AllocationProbe probe(1 << 20);
    expect_malformed(bytes, "not_stl");
  }
}

TEST(StlReader, RejectsOtherFormats) {
  expect_malformed("hello, this is a text file and not a mesh at all\n", "not_stl");
  const Error gz = expect_malformed(Bytes{0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3}, "not_stl");
  EXPECT_TRUE(contains(gz, "gzip")) << gz.what();
  expect_malformed(Bytes{'P', 'K', 3, 4, 20, 0, 0, 0, 8, 0}, "not_stl");
}

// --- ASCII -------------------------------------------------------------------------------------

TEST(StlReader, ReadsOneAsciiFacet) {
  const TriangleSoup soup = read_stl(bytes_of(kOneFacet));
  EXPECT_EQ(soup.format, StlFormat::Ascii);
  EXPECT_EQ(soup.name, "one");
  EXPECT_EQ(soup.coords, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}));
}

TEST(StlReader, ReadsAsciiVariants) {
  // CRLF, a BOM and blank lines, upper case, '+' signs and exponents, tabs, an empty name,
  // an old exporter's "-1.#IND00" normal, and two solids in one file.
  const std::string text =
      "\xEF\xBB\xBF\r\n\r\nSOLID\r\n"
      "FACET NORMAL -1.#IND00 0 0\r\n\tOUTER LOOP\r\n"
      "\t\tVERTEX +1.5e+00 -2E-1 .25\r\n\t\tVERTEX 1 0 0\r\n\t\tVERTEX 0 1 1e-999\r\n"
      "\tENDLOOP\r\nENDFACET\r\nENDSOLID\r\n"
      "solid second\nfacet normal 0 0 0 outer loop vertex 0 0 0 vertex 2 0 0 vertex 0 2 0 "
      "endloop endfacet endsolid second";
  const TriangleSoup soup = read_stl(bytes_of(text));
  EXPECT_EQ(soup.format, StlFormat::Ascii);
  EXPECT_EQ(soup.name, "");
  ASSERT_EQ(soup.triangle_count(), 2u);
  EXPECT_EQ(soup.coords[0], 1.5f);
  EXPECT_EQ(soup.coords[1], -0.2f);
  EXPECT_EQ(soup.coords[2], 0.25f);
  EXPECT_EQ(soup.coords[8], 0.0f);  // 1e-999 underflows to zero: that is fine
  EXPECT_EQ(soup.coords[12], 2.0f);
}

TEST(StlReader, ReadsOldMacLineBreaks) {
  std::string text = kOneFacet;
  std::replace(text.begin(), text.end(), '\n', '\r');
  EXPECT_EQ(read_stl(bytes_of(text)).triangle_count(), 1u);
  const Error e = expect_malformed(replaced(text, "vertex 1 0 0", "vertex 1 x 0"), "syntax");
  EXPECT_EQ(e.line(), 5u);
}

TEST(StlReader, RejectsAsciiWithoutFacets) {
  const Error e = expect_malformed("solid empty\nendsolid empty\n", "zero_triangles");
  EXPECT_EQ(e.line(), 1u);
}

TEST(StlReader, RejectsMissingEndsolid) {
  const Error e = expect_malformed(replaced(kOneFacet, "endsolid one\n", ""), "syntax");
  EXPECT_EQ(e.line(), 9u);  // where the input ends
  EXPECT_TRUE(contains(e, "missing 'endsolid'")) << e.what();
  // Cut inside a facet.
  const Error inside =
      expect_malformed(kOneFacet.substr(0, kOneFacet.find("    endloop")), "syntax");
  EXPECT_TRUE(contains(inside, "ends inside facet 0")) << inside.what();
}

TEST(StlReader, RejectsQuadFacets) {
  const Error e = expect_malformed(
      replaced(kOneFacet, "    endloop", "      vertex 1 1 0\n    endloop"), "syntax");
  EXPECT_EQ(e.line(), 7u);
  EXPECT_TRUE(contains(e, "more than 3 vertices")) << e.what();
}

TEST(StlReader, RejectsFacetsWithTwoVertices) {
  const Error e = expect_malformed(replaced(kOneFacet, "      vertex 0 1 0\n", ""), "syntax");
  EXPECT_EQ(e.line(), 6u);
  EXPECT_TRUE(contains(e, "only 2 vertices")) << e.what();
}

TEST(StlReader, RejectsBadKeywords) {
  Error e = expect_malformed(replaced(kOneFacet, "outer loop", "outer lop"), "syntax");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_TRUE(contains(e, "'lop'")) << e.what();
  e = expect_malformed(replaced(kOneFacet, "  facet normal", "  facett normal"), "syntax");
  EXPECT_EQ(e.line(), 2u);
  e = expect_malformed(replaced(kOneFacet, "facet normal 0 0 1", "facet normal"), "syntax");
  EXPECT_EQ(e.line(), 3u);  // "outer" is not a normal component
  e = expect_malformed(kOneFacet + "garbage\n", "syntax");
  EXPECT_EQ(e.line(), 10u);
}

TEST(StlReader, RejectsBadNumbers) {
  for (const char* bad : {"abc", "1.0.0", "1,5", "0x10", "--1", "+-1", "1e"}) {
    SCOPED_TRACE(bad);
    const Error e = expect_malformed(
        replaced(kOneFacet, "vertex 1 0 0", std::string("vertex 1 ") + bad + " 0"), "syntax");
    EXPECT_EQ(e.line(), 5u);
    EXPECT_TRUE(contains(e, "facet 0, vertex 1: y")) << e.what();
  }
}

TEST(StlReader, RejectsOverflowingAsciiNumbers) {
  for (const char* big : {"1e999", "-1e999", "3.5e38", "1e99999"}) {
    SCOPED_TRACE(big);
    const Error e = expect_malformed(
        replaced(kOneFacet, "vertex 0 1 0", std::string("vertex 0 1 ") + big), "non_finite");
    EXPECT_EQ(e.line(), 6u);
    EXPECT_TRUE(contains(e, "overflows")) << e.what();
  }
  for (const char* literal : {"nan", "inf", "-Infinity"}) {
    SCOPED_TRACE(literal);
    const Error e = expect_malformed(
        replaced(kOneFacet, "vertex 0 0 0", std::string("vertex ") + literal + " 0 0"),
        "non_finite");
    EXPECT_EQ(e.line(), 4u);
  }
}

TEST(StlReader, RejectsAsciiCoordinatesBeyondTheLimit) {
  const Error e = expect_malformed(replaced(kOneFacet, "vertex 1 0 0", "vertex 1e10 0 0"),
                                   "coordinate_out_of_range");
  EXPECT_EQ(e.line(), 5u);
  EXPECT_EQ(e.field(), "max_abs_coordinate");
}

TEST(StlReader, RejectsLinesOverTheLimit) {
  // Whitespace, a token, and an endsolid name that run past max_ascii_line_length.
  const std::size_t limit = StlReadOptions{}.max_ascii_line_length;
  Error e = expect_malformed(
      replaced(kOneFacet, "    outer loop", std::string(limit + 1, ' ') + "outer loop"),
      "line_too_long");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.field(), "max_ascii_line_length");
  e = expect_malformed(replaced(kOneFacet, "vertex 1 0 0", "vertex 1 0 " + std::string(limit, '0')),
                       "line_too_long");
  EXPECT_EQ(e.line(), 5u);
  e = expect_malformed(replaced(kOneFacet, "endsolid one", "endsolid " + std::string(limit, 'x')),
                       "line_too_long");
  EXPECT_EQ(e.line(), 9u);
  // Exactly at the limit is fine.
  const std::string at_limit = "      vertex 1 0 0";
  EXPECT_EQ(
      read_stl(bytes_of(replaced(kOneFacet, at_limit,
                                 std::string(limit - at_limit.size() + 6, ' ') + "vertex 1 0 0")))
          .triangle_count(),
      1u);
}

TEST(StlReader, RejectsHugeSolidName) {
  const std::string text =
      "solid " + std::string(10 << 20, 'n') + "\n" + kOneFacet.substr(kOneFacet.find("  facet"));
  const Bytes bytes = bytes_of(text);
  AllocationProbe probe(1 << 20);
  const Error e = expect_malformed(bytes, "name_too_long");
  EXPECT_EQ(e.line(), 1u);
  EXPECT_EQ(e.field(), "max_ascii_name_length");
  EXPECT_FALSE(probe.refused());
}

TEST(StlReader, AcceptsNameAtTheLimit) {
  StlReadOptions options;
  options.max_ascii_name_length = 8;
  EXPECT_EQ(read_stl(bytes_of(replaced(kOneFacet, "solid one", "solid 12345678")), options).name,
            "12345678");
  expect_malformed(replaced(kOneFacet, "solid one", "solid 123456789"), "name_too_long", options);
}

TEST(StlReader, RejectsTooManyAsciiFacets) {
  StlReadOptions options;
  options.max_triangles = 1;
  const std::size_t facet = kOneFacet.find("  facet");
  const std::string two =
      replaced(kOneFacet, "endsolid",
               kOneFacet.substr(facet, kOneFacet.find("endsolid") - facet) + "endsolid");
  EXPECT_EQ(read_stl(bytes_of(two)).triangle_count(), 2u);
  const Error e = expect_malformed(two, "too_many_triangles", options);
  EXPECT_EQ(e.field(), "max_triangles");
}

// --- options and files -----------------------------------------------------------------------

TEST(StlReader, ValidatesOptions) {
  const auto expect_invalid = [](const StlReadOptions& options, const std::string& field) {
    try {
      read_stl(bytes_of(kOneFacet), options);
      ADD_FAILURE() << "expected InvalidParameter for " << field;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_EQ(e.field(), field);
    }
  };
  StlReadOptions o;
  o.max_ascii_line_length = 10;
  expect_invalid(o, "max_ascii_line_length");
  o = {};
  o.max_abs_coordinate = std::nan("");
  expect_invalid(o, "max_abs_coordinate");
  o = {};
  o.max_triangles = 0;
  expect_invalid(o, "max_triangles");
}

TEST(StlReader, ReportsUnreadableFiles) {
  try {
    read_stl_file(data_file("does/not/exist.stl"));
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    EXPECT_EQ(e.reason(), "cannot_open");
    EXPECT_EQ(e.field(), "path");
  }
}

}  // namespace
}  // namespace stlrefine::test
