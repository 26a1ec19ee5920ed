// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <string>

namespace stlrefine::bench {

//! Markdown bullet list: CPU model, cores, RAM, kernel, compiler, build, library
//! versions, date.
std::string machine_markdown();

//! The three load averages from /proc/loadavg, e.g. "0.12 0.30 0.25".
std::string load_averages();
//! The 1-minute load average (negative when unreadable).
double load_average_1min();
//! Cumulative idle (idle + iowait) and total CPU time of all CPUs from /proc/stat, in
//! seconds. False when unreadable.
bool cpu_times(double& idle_seconds, double& total_seconds);
//! Fraction of all CPUs' time that was idle (idle + iowait in /proc/stat) over the next
//! `seconds` (negative when unreadable). Sleeps for that long.
double cpu_idle_fraction(double seconds);
//! MemAvailable from /proc/meminfo in kB (negative when unreadable).
long mem_available_kb();
//! Current UTC time, ISO 8601.
std::string utc_now();

}  // namespace stlrefine::bench
