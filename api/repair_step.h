// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>

#include "api/ingest.h"

namespace stlrefine::api {

//! The step after ingest on every route: `repair` (none, fill_holes) applied to the mesh,
//! then the figures the report and its warnings need (Ingested::stats, Ingested::repair).
//! \throw Error(Cancelled) when *cancel is set between two holes.
void repair_ingested(Ingested& in, repair::RepairMode mode,
                     const std::atomic<bool>* cancel = nullptr);

}  // namespace stlrefine::api
