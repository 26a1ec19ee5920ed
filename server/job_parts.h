// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A job whose upload is a zip of mesh files (api/archive.h), or a 3MF of several objects
// refined to STL: one job, each part refined (and
// sliced) on its own with its own name, report entry and result files (part<k>.stl or .3mf,
// part<k>.contours.<ext>), one report.json listing them, and result.zip bundling them under
// the parts' names. Inside the job store (job_runner.cpp, job_routes.cpp, job_view.cpp).

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "api/archive.h"
#include "api/plan.h"
#include "api/problem.h"

namespace stlrefine::server {

//! The limits a job's zip is read under: its inflated content no larger than a body this
//! server takes (`max_body_bytes`).
api::ArchiveLimits job_archive_limits(std::uint64_t max_body_bytes);

//! The parts of a job's upload, or nullopt for a one-part job: a zip's mesh files
//! (api::read_part_archive under `limits`), or, when the output is STL, a 3MF's objects
//! (more than one), each as a binary STL in mm (its build transform and declared unit
//! applied) named after the object ("object<k>" when it has no name).
//! \throw api::ArchiveError; Error(MalformedStl) for a 3MF that cannot be read.
std::optional<std::vector<api::ArchivePart>> job_parts(std::span<const std::uint8_t> bytes,
                                                       const api::RefineRequest& request,
                                                       const api::ArchiveLimits& limits);

//! The plan of a parts job, made at submit: every part planned (its parameters validated on
//! it, its faces and memory predicted; a part that cannot be read is refused now), and the
//! largest part's plan returned with the parts' inputs added to its peak (they are held
//! while it runs). `result_bytes`: the parts' predicted results, twice (result.zip).
//! \throw api::ArchiveError naming the entry (a part's error, its message prefixed).
api::RefinePlan plan_parts_job(const api::RefinePlan& parameters,
                               const std::vector<api::ArchivePart>& parts,
                               std::uint64_t* result_bytes);

//! The 4xx of an archive refused (the error's problem with `entry`).
api::Problem archive_problem(const api::ArchiveError& e);

//! Runs every part of a parts job (`plan`: its parameters) in `dir`. Each file is appended
//! to `results` (and its size to `bytes`) once whole, so a failure part-way removes exactly
//! those. `publish(fraction, stage)`: one fraction over all parts, weighted by their
//! predicted work, never backwards. Returns the job's report.
nlohmann::ordered_json run_parts_job(const api::RefinePlan& plan,
                                     const std::vector<api::ArchivePart>& parts,
                                     const std::filesystem::path& dir,
                                     const std::atomic<bool>* cancel, const MemoryGrowFn& grow,
                                     const std::function<void(double, const std::string&)>& publish,
                                     std::vector<std::string>& results, std::uint64_t& bytes);

//! Whether `file` is a part's result file name (part<k>.stl|.3mf|.contours.<ext>).
bool part_file_name(const std::string& file);

//! The job JSON's `parts`: name, input and output faces, links to its files (under `self`).
nlohmann::ordered_json parts_json(const nlohmann::ordered_json& report, const std::string& self);

//! The name of the part whose file `file` is (its entry's last component), from the job's
//! report; empty if none.
std::string part_of_file(const nlohmann::ordered_json& report, const std::string& file);

}  // namespace stlrefine::server
