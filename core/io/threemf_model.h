// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A 3MF model part (the XML in 3D/3dmodel.model) to a MeshInput, streamed (internal to
// core/io; threemf_reader.cpp finds the part in the zip and feeds it here as it inflates).
// Every build item's object, a mesh or components (nested, each with its transform), is
// flattened with the item's transform into one part per build item; the model's unit is
// reported. What the XML may cost is bounded by the options before the build is expanded:
// the meshes' stored triangles and vertices (max_triangles, 3 max_triangles), the objects,
// components and build items (kMax3mf*), and the build's expanded triangle count and the
// work expanding it costs (components may instance an object many times; see
// kMax3mfWorkPerTriangle).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "core/io/mesh_formats.h"

namespace stlrefine::io_detail {

inline constexpr std::size_t kMax3mfObjects = 1 << 16;
inline constexpr std::size_t kMax3mfComponents = 1 << 20;
inline constexpr std::size_t kMax3mfBuildItems = 1 << 16;
//! Components nested deeper than this are refused (a chain, not only a cycle).
inline constexpr int kMax3mfComponentDepth = 32;
//! Expanding the build may cost at most kMax3mfWorkPerTriangle max_triangles +
//! kMax3mfWorkSlack: 1 per instance of an object holding triangles, plus the vertices its
//! triangles use and its triangles (objects without triangles are skipped). A triangle
//! costs at most 4; the rest pays for component nesting.
inline constexpr std::uint64_t kMax3mfWorkPerTriangle = 8;
inline constexpr std::uint64_t kMax3mfWorkSlack = 1024;

class ThreeMfModel {
 public:
  //! `part` names the model part in messages.
  ThreeMfModel(const StlReadOptions& options, std::string part);
  ~ThreeMfModel();
  ThreeMfModel(const ThreeMfModel&) = delete;
  ThreeMfModel& operator=(const ThreeMfModel&) = delete;

  //! The next bytes of the part's XML; `last` on the final call.
  void feed(const char* data, std::size_t size, bool last);
  //! After the last feed: the flattened build.
  MeshInput finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

//! A whole model part already in memory (the fuzzer and tests reach the XML through it).
MeshInput read_3mf_model(std::span<const std::uint8_t> xml, const StlReadOptions& options,
                         const std::string& part = "3D/3dmodel.model");

}  // namespace stlrefine::io_detail
