// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// LSF's batch kernels (lsf.h): the fits of smooth and dart vertices, and of crease vertices'
// sectors, four at a time. Internal to the lsf*.cpp files: the stencil (lsf.cpp) fills the
// batches, the kernels write each estimate where the stencil wants it.

#include <array>
#include <cstddef>
#include <cstdint>

#include "core/schemes/lsf.h"

namespace stlrefine::lsf {

struct GuardVertex;  // lsf_rules.h

//! Smooth and dart vertices whose closed ring has kMinBatchValence..kMaxBatchValence points
//! are fitted four at a time, one vertex per lane of lsf_math::V4d (lsf_kernels.cpp). Every lane
//! runs the operations of fit_sample and half_points in the same order (the even- and odd-indexed
//! points summed apart and then added, as the pair kernels do), so the results are
//! bit-identical to the one-vertex path; what changes is that the angle bookkeeping, the
//! reductions and the certified 5x5 solve of four vertices share their instructions, and
//! nothing is summed across lanes. Lanes the fast solve cannot certify take solve_fit.
inline constexpr int kLanes = 4;
inline constexpr std::size_t kMinBatchValence = 5;  // below five points the general solve decides
inline constexpr std::size_t kMaxBatchValence = 12;

//! Up to kLanes samples of the same size, one per lane, and where their estimates go.
struct FitBatch {
  int lanes = 0;
  alignas(32) double ox[kLanes], oy[kLanes], oz[kLanes];  // the vertices V
  alignas(32) double x[kMaxBatchValence][kLanes];         // ring offsets P_i - V
  alignas(32) double y[kMaxBatchValence][kLanes];
  alignas(32) double z[kMaxBatchValence][kLanes];
  Vec3* dest[kMaxBatchValence][kLanes];  // where P_i's estimate goes (EstimateSlots)
  // Closed rings of smooth vertices: the guard record (normal, flat flag, spoke flags) of the
  // lane's vertex; null for a dart (its normal is its sector's).
  GuardVertex* record[kLanes];
};

//! Where the estimates go (see LsfStencil::edge_points): the edge's slot of one array for the
//! estimate along its lower-numbered half-edge, of the other for the other one. Chosen by
//! index, not by a branch: which half-edge is lower is a coin toss the predictor loses.
struct EstimateSlots {
  Vec3* lower;
  Vec3* upper;
  Vec3* at(EdgeId e, bool along_lower) const {
    return (along_lower ? lower : upper) + std::size_t{e.idx};
  }
};

using FitBatchFn = void (*)(const FitBatch&, std::size_t, bool);

//! The batches of one task: whole rings of smooth and dart vertices by valence, one-sided
//! sectors of crease vertices by size. fit() runs a full batch through the kernel, which
//! writes each estimate to its slot.
struct Batches {
  std::array<FitBatch, kMaxBatchValence + 1> ring, sector;
  FitBatchFn kernel;

  //! The kernel `choice` names (LsfKernel::Auto: AVX2 where the CPU has it).
  explicit Batches(LsfKernel choice);
  void fit(FitBatch& b, std::size_t n, bool closed) {
    kernel(b, n, closed);
    b.lanes = 0;
  }
  //! Fits what is left: the unused lanes get copies of lane 0.
  void flush();
};

//! Walks v's ring into the batch of its valence when v is smooth or a dart (whose whole ring
//! is fitted too) with a closed ring of kMinBatchValence..kMaxBatchValence points, and fits
//! the batch when it is full; false, with nothing changed, for every other vertex. A dart's
//! sharp spoke gets an estimate too: harmless, the sharp edge's point is the curve rule's.
bool batch_smooth_vertex(const Mesh& m, VertexId v, const EstimateSlots& slots, Batches& batches,
                         GuardVertex* record);

//! A crease vertex's sectors, as for_each_sector_fit cuts them (the ring from its first
//! sharp spoke, closed by a copy of that spoke's point; on a boundary the fan from its
//! boundary spoke, closed by the far end of the incoming boundary edge; each sector from one
//! sharp spoke to the next, both included), into the sector batches by size; false, with
//! nothing changed, when a ring or sector is too large (the caller fits the vertex alone).
bool batch_crease_vertex(const Mesh& m, const Features& f, VertexId v, const EstimateSlots& slots,
                         Batches& batches);

}  // namespace stlrefine::lsf
