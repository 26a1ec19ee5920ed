// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/ingest.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <string>
#include <utility>

#include "core/error.h"

namespace stlrefine::api {

namespace {

using Tri = std::array<std::uint32_t, 3>;

bool collapsed(const Tri& t) {
  return t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
}

//! Welding within a tolerance merged two corners of every triangle although the file has
//! a proper one: the tolerance is at fault, not the file, and the 422 names it.
//! (build_mesh would refuse the soup as "no_faces" without a field.)
void refuse_collapsing_tolerance(const TriangleSoup& soup, const IndexedSoup& welded,
                                 double weld_tolerance) {
  if (weld_tolerance == 0 || !std::all_of(welded.triangles.begin(), welded.triangles.end(),
                                          [](const Tri& t) { return collapsed(t); }))
    return;
  const std::vector<float>& c = soup.coords;
  const auto same = [&](std::size_t a, std::size_t b) {
    return c[a] == c[b] && c[a + 1] == c[b + 1] && c[a + 2] == c[b + 2];
  };
  bool proper = false;
  for (std::size_t t = 0; t + 9 <= c.size() && !proper; t += 9)
    proper = !same(t, t + 3) && !same(t + 3, t + 6) && !same(t + 6, t);
  if (!proper) return;  // degenerate as stored: build_mesh says so
  // The part's size, to compare the tolerance with.
  double extent = 0;
  for (std::size_t k = 0; k < 3; ++k) {
    float lo = c[k], hi = c[k];
    for (std::size_t i = k; i < c.size(); i += 3) {
      lo = std::min(lo, c[i]);
      hi = std::max(hi, c[i]);
    }
    extent = std::max(extent, static_cast<double>(hi) - static_cast<double>(lo));
  }
  const auto num = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.6g", v);
    return std::string(text);
  };
  throw Error(
      ErrorCode::NotTriangleMesh, "weld_collapsed",
      "weld_tolerance = " + num(weld_tolerance) + " merges two corners of every one of the " +
          std::to_string(welded.triangles.size()) + " triangles (the part is " + num(extent) +
          " across): use a tolerance below the shortest edges, or 0 for exact welding")
      .with_field("weld_tolerance");
}

}  // namespace

Ingested ingest_input(const MeshInput& input, double weld_tolerance, const UnitOptions& units,
                      std::optional<std::size_t> part) {
  const auto start = std::chrono::steady_clock::now();
  Ingested in;
  in.weld_tolerance = weld_tolerance;
  in.file_format = input.format;
  in.format = input.soup.format;
  in.trailing_bytes = input.soup.trailing_bytes;
  {
    // Scoped: the part's soup and the welded soup are freed as soon as the mesh exists.
    TriangleSoup selected;
    const TriangleSoup* soup = &input.soup;
    in.parts = input.parts;
    if (part) {
      const MeshPart& p = input.parts.at(*part);
      selected.format = input.soup.format;
      selected.name = p.name;
      const auto first =
          input.soup.coords.begin() + static_cast<std::ptrdiff_t>(9 * p.first_triangle);
      selected.coords.assign(first, first + static_cast<std::ptrdiff_t>(9 * p.triangle_count));
      soup = &selected;
      in.parts = {MeshPart{p.name, 0, p.triangle_count}};
    }
    in.triangles = soup->triangle_count();
    IndexedSoup welded = weld(*soup, weld_tolerance);
    refuse_collapsing_tolerance(*soup, welded, weld_tolerance);
    in.welded_vertices = welded.positions.size();
    in.result = build_mesh(welded);
  }
  in.units = input.unit ? apply_units(in.result.mesh, units, input.unit->name, input.unit->mm)
                        : apply_units(in.result.mesh, units);
  in.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return in;
}

Ingested ingest_mesh(std::span<const std::uint8_t> bytes, double weld_tolerance,
                     const StlReadOptions& options, const UnitOptions& units) {
  const auto start = std::chrono::steady_clock::now();
  Ingested in = ingest_input(read_mesh(bytes, options), weld_tolerance, units);
  in.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return in;
}

}  // namespace stlrefine::api
