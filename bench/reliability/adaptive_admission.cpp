// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_adaptive_admission: one refinement request under a memory capacity, the way
// the daemon admits it (issue 16 item 4): the up-front estimate, then run_refine's
// MemoryGrowFn refusing any whole-request figure above the capacity. Prints the estimate,
// every 64 MiB the figures pass, the outcome and the peak RSS the request added (VmHWM
// after clear_refs, minus VmRSS before). One request per process, so the peak is its own.
//
//   stlrefine_adaptive_admission FILE QUERY CAPACITY_MIB
//   e.g. FILE fandisk.stl, QUERY 'scheme=sqrt3-interp&adaptive_tol=1e-9&max_level=6',
//   CAPACITY_MIB 3008 (what --memory-budget 3G leaves one request)

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <span>
#include <string>

#include "api/memory_model.h"
#include "api/params.h"
#include "api/pipeline.h"
#include "core/error.h"
#include "core/refine.h"

namespace {

long status_kib(const char* key) {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind(key, 0) == 0) return std::stol(line.substr(std::string(key).size()));
  return -1;
}

double mib(std::uint64_t bytes) {
  return double(bytes) / double(1 << 20);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace stlrefine;
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s FILE QUERY CAPACITY_MIB\n", argv[0]);
    return 2;
  }
  std::ifstream file(argv[1], std::ios::binary);
  const std::string body((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(body.data()),
                                            body.size());
  const api::RefineRequest request =
      api::parse_refine_params(api::parse_query(argv[2]), api::RequestLimits{});
  const std::uint64_t capacity = std::stoull(argv[3]) << 20;

  const api::MemoryEstimate estimate =
      api::estimate_refine_memory(bytes, api::stl_shape(bytes), request);
  std::printf("estimate %.1f MiB (output faces at most %llu), capacity %.1f MiB\n",
              mib(estimate.peak_bytes), static_cast<unsigned long long>(estimate.output_faces),
              mib(capacity));
  if (estimate.peak_bytes > capacity) {
    std::printf("outcome 422 up front\n");
    return 0;
  }

  { std::ofstream("/proc/self/clear_refs") << "5"; }  // VmHWM := VmRSS
  const long base = status_kib("VmRSS:");
  const auto start = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  std::uint64_t granted = 0, shown = 0;
  const MemoryGrowFn grow = [&](std::uint64_t figure) {
    if (figure > capacity) return false;
    granted = std::max(granted, figure);
    if (granted >= shown + (std::uint64_t{64} << 20)) {
      shown = granted;
      std::printf("%8.2f s  figure %8.1f MiB  rss %8.1f MiB\n", seconds(), mib(granted),
                  double(status_kib("VmRSS:") - base) / 1024);
    }
    return true;
  };
  try {
    const api::RefineOutcome out = api::run_refine(bytes, request, {}, nullptr, grow);
    std::printf("outcome done: %s faces\n", out.report["output"]["faces"].dump().c_str());
  } catch (const MemoryBudgetError& e) {
    std::printf("outcome %s: %s\n", e.needed_bytes() > capacity ? "422 (over capacity)" : "503",
                e.what());
  } catch (const Error& e) {
    std::printf("outcome error %s (%s): %s\n", e.reason().c_str(), e.field().c_str(), e.what());
  }
  std::printf("%.2f s, peak figure granted %.1f MiB, peak RSS added %.1f MiB\n", seconds(),
              mib(granted), double(status_kib("VmHWM:") - base) / 1024);
  return 0;
}
