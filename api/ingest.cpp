// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/ingest.h"

#include <chrono>
#include <utility>

namespace stlrefine::api {

Ingested ingest_stl(std::span<const std::uint8_t> bytes, double weld_tolerance,
                    const StlReadOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  Ingested in;
  in.weld_tolerance = weld_tolerance;
  {
    // Scoped: the two soups are freed as soon as the mesh exists.
    const TriangleSoup soup = read_stl(bytes, options);
    in.format = soup.format;
    in.triangles = soup.triangle_count();
    in.trailing_bytes = soup.trailing_bytes;
    IndexedSoup welded = weld(soup, weld_tolerance);
    in.welded_vertices = welded.positions.size();
    in.result = build_mesh(welded);
  }
  in.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return in;
}

}  // namespace stlrefine::api
