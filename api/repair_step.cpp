// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/repair_step.h"

#include <utility>

namespace stlrefine::api {

void repair_ingested(Ingested& in, repair::RepairMode mode, const std::atomic<bool>* cancel) {
  in.repair_mode = mode;
  in.stats = compute_stats(in.result.mesh);
  // A closed part has nothing to fill: no CGAL copy of it is made.
  if (mode != repair::RepairMode::FillHoles || in.stats.boundary_edges == 0) return;
  IngestResult filled = repair::fill_holes(in.result.mesh, {}, in.repair, cancel);
  if (in.repair.faces_added == 0) return;
  // The ingest report stays the file's; only the mesh is the repaired one.
  in.result.mesh = std::move(filled.mesh);
  in.stats = compute_stats(in.result.mesh);
}

}  // namespace stlrefine::api
