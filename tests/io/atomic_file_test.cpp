// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// The one atomic file writer (core/io/atomic_file.h) and the streamed binary STL
// (write_binary_stl, BinaryStl) against write_stl.
#include "core/io/atomic_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/io/stl.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

namespace fs = std::filesystem;

class AtomicFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stlrefine_atomic_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::set<std::string> entries() const {
    std::set<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_)) out.insert(e.path().filename().string());
    return out;
  }
  static std::string contents(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }

  fs::path dir_;
};

TEST_F(AtomicFile, WritesThePiecesAndReplacesTheOldFile) {
  const fs::path path = dir_ / "out.bin";
  write_file_atomically(path, std::string_view("old"));
  EXPECT_EQ(contents(path), "old");
  // Small pieces are gathered, one larger than the gathering buffer goes as it is.
  const std::string big(3 << 20, 'b');
  write_file_atomically(path, [&](const ByteSink& sink) {
    sink("a");
    sink(big);
    sink("c");
  });
  EXPECT_EQ(contents(path), "a" + big + "c");
  EXPECT_EQ(entries(), std::set<std::string>{"out.bin"});
}

TEST_F(AtomicFile, AProducerThatThrowsLeavesTheOldFileAndNoTemporary) {
  const fs::path path = dir_ / "out.bin";
  write_file_atomically(path, std::string_view("old"));
  EXPECT_THROW(write_file_atomically(path,
                                     [](const ByteSink& sink) {
                                       sink(std::string(2 << 20, 'x'));  // written already
                                       throw std::runtime_error("stop");
                                     }),
               std::runtime_error);
  EXPECT_EQ(contents(path), "old");
  EXPECT_EQ(entries(), std::set<std::string>{"out.bin"});
}

TEST_F(AtomicFile, ADiskFullWriteNamesThePathAndLeavesNoPartialFile) {
  const fs::path path = dir_ / "out.bin";
  write_file_atomically(path, std::string_view("old"));
  // The temporary file leads to /dev/full: every write fails with ENOSPC.
  fs::create_symlink("/dev/full", dir_ / ".out.bin.tmp");
  AtomicFileOptions options;
  options.temporary_name = ".out.bin.tmp";
  try {
    write_file_atomically(path, std::string_view("new bytes"), options);
    ADD_FAILURE() << "expected an error";
  } catch (const FileError& e) {
    EXPECT_EQ(e.code(), ErrorCode::Internal);
    EXPECT_EQ(e.reason(), "write_failed");
    EXPECT_EQ(e.field(), "path");
    EXPECT_EQ(e.os_error(), std::errc::no_space_on_device);
    EXPECT_NE(std::string(e.what()).find((dir_ / ".out.bin.tmp").string()), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(contents(path), "old");
  EXPECT_EQ(entries(), std::set<std::string>{"out.bin"});
}

TEST_F(AtomicFile, AMissingDirectoryCannotBeCreated) {
  const fs::path path = dir_ / "missing" / "out.bin";
  try {
    write_file_atomically(path, std::string_view("x"));
    ADD_FAILURE() << "expected an error";
  } catch (const FileError& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    EXPECT_EQ(e.reason(), "cannot_create");
    EXPECT_EQ(e.field(), "path");
    EXPECT_EQ(e.os_error(), std::errc::no_such_file_or_directory);
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
  EXPECT_TRUE(entries().empty());
}

TEST_F(AtomicFile, KeepsTheGivenMode) {
  const fs::path path = dir_ / "secret";
  AtomicFileOptions options;
  options.mode = 0600;
  write_file_atomically(path, std::string_view("k"), options);
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
}

// ------------------------------------------------------------- the streamed binary STL

//! A mesh of a few thousand faces whose positions are not representable as float.
Mesh fine_sphere() {
  return to_mesh(icosphere_soup(4, 10.0 / 3.0));
}

TEST(StreamedStl, GivesTheBytesOfWriteStlInPieces) {
  const Mesh mesh = to_mesh(icosphere_soup(6, 10.0 / 3.0));
  ASSERT_GT(mesh.num_faces(), 65536u);  // more than two pieces of facets
  std::string streamed;
  std::size_t pieces = 0;
  write_binary_stl(
      mesh,
      [&](std::string_view bytes) {
        streamed.append(bytes);
        ++pieces;
      },
      "part");
  EXPECT_EQ(streamed, write_stl(mesh, StlFormat::Binary, "part"));
  EXPECT_EQ(streamed.size(), binary_stl_size(mesh.num_faces()));
  EXPECT_GE(pieces, 4u);  // the header, then the facets in pieces
}

TEST(StreamedStl, AnyRangeOfTheHeldStlIsTheFilesBytes) {
  const Mesh mesh = fine_sphere();
  const std::string whole = write_stl(mesh, StlFormat::Binary, "solid part");
  const BinaryStl stl(mesh, "solid part");
  ASSERT_EQ(stl.size(), whole.size());
  EXPECT_EQ(stl.memory_bytes(), 12 * mesh.num_vertices() + 12 * mesh.num_faces());
  std::string all(whole.size(), '\0');
  stl.read(0, all);
  EXPECT_EQ(all, whole);
  // Made from a mesh it takes apart: the same bytes.
  const BinaryStl taken(fine_sphere(), "solid part");
  std::string all_taken(whole.size(), '\0');
  taken.read(0, all_taken);
  EXPECT_EQ(all_taken, whole);
  // Ranges starting and ending inside the header and inside facets.
  for (const auto& [offset, length] :
       std::initializer_list<std::pair<std::size_t, std::size_t>>{{0, 1},
                                                                  {3, 80},
                                                                  {80, 10},
                                                                  {83, 50},
                                                                  {84, 50},
                                                                  {100, 7},
                                                                  {133, 1},
                                                                  {1234, 4321},
                                                                  {whole.size() - 1, 1},
                                                                  {whole.size() - 77, 77}}) {
    std::string part(length, '\0');
    stl.read(offset, part);
    EXPECT_EQ(part, whole.substr(offset, length)) << offset << " " << length;
  }
}

TEST(StreamedStl, RefusesPositionsBeyondFloatBeforeAnyByte) {
  Mesh mesh = fine_sphere();
  const VertexId last_face_corner = mesh.corner_vertices().back();
  mesh.mutable_positions()[last_face_corner.idx] = Vec3(0, 1e300, 0);
  std::string expected;
  try {
    write_stl(mesh);
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    expected = e.what();
  }
  try {
    const BinaryStl stl(mesh);
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Internal);
    EXPECT_EQ(e.reason(), "non_finite");
    EXPECT_EQ(e.what(), expected);
  }
}

TEST_F(AtomicFile, WriteStlFileStreamsTheSameBytes) {
  const Mesh mesh = fine_sphere();
  write_stl_file(dir_ / "out.stl", mesh, StlFormat::Binary, "x");
  EXPECT_EQ(contents(dir_ / "out.stl"), write_stl(mesh, StlFormat::Binary, "x"));
  // A position beyond float: the old file stays, no partial file.
  Mesh bad = fine_sphere();
  bad.mutable_positions()[bad.corner_vertices().back().idx] = Vec3(1e300, 0, 0);
  EXPECT_THROW(write_stl_file(dir_ / "out.stl", bad), Error);
  EXPECT_EQ(contents(dir_ / "out.stl"), write_stl(mesh, StlFormat::Binary, "x"));
  EXPECT_EQ(entries(), std::set<std::string>{"out.stl"});
}

}  // namespace
}  // namespace stlrefine::test
