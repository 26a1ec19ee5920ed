// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Timing and peak-RSS measurement for the benchmark. Every measured case runs in its own
// forked child, so one case's peak RSS (and heap state) cannot hide or inflate another's.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace stlrefine::bench {

//! What one forked child reports back through a pipe (trivially copyable on purpose).
struct Sample {
  double seconds = 0;          //!< wall time of the first (cold) run in this process
  double warm_seconds = 0;     //!< median wall time of the reruns (0 when there were none)
  int warm_runs = 0;           //!< reruns in this process (only for short cases)
  double cpu_seconds = 0;      //!< user + system CPU time of the first run (all threads)
  double convert_seconds = 0;  //!< building the algorithm's own input structure (untimed)
  std::uint64_t in_faces = 0;
  std::uint64_t out_faces = 0;
  std::uint64_t out_vertices = 0;
  long base_kb = 0;         //!< VmRSS just before the first run (input loaded and converted)
  long peak_kb = 0;         //!< peak RSS during the first run (VmHWM after a reset, else maxrss)
  long maxrss_kb = 0;       //!< getrusage(RUSAGE_SELF).ru_maxrss at the end of the first run
  bool peak_reset = false;  //!< true when /proc/self/clear_refs reset the peak after loading
  char note[768] = {};
};

//! One algorithm prepared on one input, ready to run once. Built untimed; run() is timed.
class Job {
 public:
  virtual ~Job() = default;
  virtual void run() = 0;
  virtual std::uint64_t in_faces() const = 0;
  virtual std::uint64_t out_faces() const = 0;
  virtual std::uint64_t out_vertices() const = 0;
  virtual double convert_seconds() const { return 0; }
  //! Anything the run wants reported (warnings a peer printed, repairs, ...).
  virtual std::string note() const { return {}; }
};

using JobFactory = std::function<std::unique_ptr<Job>()>;

//! Runs in the child. First runs `warm_up` (the same algorithm on a tiny mesh: thread pool
//! started, code paged in, lazy symbols bound; not timed), then builds the real job,
//! measures baseline RSS, resets the peak and runs it once:
//! the "cold" run, timed, with its peak RSS (a fresh process: every page is faulted in).
//! When that took less than `min_seconds`, rebuilds and reruns it ("warm": the heap now
//! holds freed memory) until `min_seconds` of reruns have accumulated (at most `max_runs`).
//! `prefault_bytes` > 0: after loading, touch and release that much fresh memory (huge
//! pages) first. On a VM whose host backs guest memory lazily, the first touch of guest
//! pages the host has not backed yet costs ~1 s/GB and varies from run to run; recycling
//! pages just touched does not. This puts every algorithm on already-backed memory, as on
//! a machine that has been running for a while.
Sample measure_job(const JobFactory& make, const JobFactory& warm_up, std::size_t prefault_bytes,
                   double min_seconds, int max_runs);

struct Outcome {
  bool ok = false;
  Sample sample;
  std::string failure;  //!< "exception: ...", "crashed (signal 11, Segmentation fault)", ...
  //! Share of all CPUs' time that other processes used while the child ran (its own CPU
  //! time taken out); negative when unknown. Our measure of interference.
  double others_busy = -1;
};

//! Forks; the child runs body() and sends its Sample through a pipe. A child that throws,
//! crashes, is killed or runs past timeout_seconds gives ok = false and a reason.
Outcome run_in_child(const std::function<Sample()>& body, int timeout_seconds);

double now_seconds();
long proc_status_kb(const char* key);  //!< "VmRSS:", "VmHWM:" from /proc/self/status
double median(std::vector<double> values);
void copy_note(Sample& sample, const std::string& text);

}  // namespace stlrefine::bench
