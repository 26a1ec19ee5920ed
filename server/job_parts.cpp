// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// A zip of mesh files as one job (job_parts.h): planned part by part at submit, run part by
// part, each part's files and report entry, result.zip bundling them.
#include "server/job_parts.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <set>

#include "api/pipeline.h"
#include "core/error.h"
#include "core/io/mesh_formats.h"
#include "core/io/stl.h"
#include "server/http_upload.h"
#include "server/job_progress.h"
#include "server/job_record.h"
#include "server/jobs.h"
#include "slicer/writers.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using namespace job_files;

namespace {

std::span<const std::uint8_t> span_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// "parts/bracket.stl" -> "bracket.stl": what its downloads and labels are named after.
std::string base_name(const std::string& entry) {
  return entry.substr(entry.rfind('/') + 1);
}

// What a part is called inside result.zip: its name's stem (base_name, download_stem) with
// only the characters content_disposition keeps in a filename ('_' for any other, one per
// multi-byte character), at most kMaxZipStem bytes, no leading or trailing dots or spaces.
// A 3MF's object names are free text: "..\\..\\x", "C:x" or a newline must not reach an
// extractor as a path.
constexpr std::size_t kMaxZipStem = 100;

std::string zip_stem(const std::string& name) {
  std::string stem;
  for (const char ch : download_stem(base_name(name))) {
    const auto c = static_cast<unsigned char>(ch);
    const bool keep = std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == ' ' || c == '(' ||
                      c == ')' || c == '+' || c == ',';
    if (!keep && (c & 0xC0) == 0x80) continue;  // a multi-byte character's continuation
    if (stem.size() >= kMaxZipStem) break;
    stem.push_back(keep ? ch : '_');
  }
  while (!stem.empty() && (stem.front() == '.' || stem.front() == ' ')) stem.erase(0, 1);
  while (!stem.empty() && (stem.back() == '.' || stem.back() == ' ')) stem.pop_back();
  return stem.empty() ? std::string("part") : stem;
}

std::string lowered(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// A part's error, its entry named (the parameters' field kept).
[[noreturn]] void rethrow_for(const std::string& entry, const Error& e) {
  std::string message = "zip entry '";
  message.append(entry.substr(0, 120)).append("': ").append(e.what());
  if (e.code() == ErrorCode::Cancelled) throw;  // said as it is
  api::ArchiveError named(e.code(), e.reason().empty() ? "bad_part" : e.reason(), message, entry);
  if (!e.field().empty()) named.with_field(e.field());  // a parameter's, when it is one
  throw named;
}

// The part's plan: the job's parameters on its bytes; its contours labelled with its name.
api::RefinePlan plan_part(const api::RefinePlan& parameters, const api::ArchivePart& part) {
  api::RefinePlan p = parameters;
  if (part.in_mm) p.request.units.units = api::LengthUnit::Millimetre;  // applied already
  if (p.request.slice) p.request.slice->writer.label = download_stem(base_name(part.name));
  try {
    return api::plan_body(std::move(p), span_of(part.bytes), api::ResultSink::JobFiles);
  } catch (const Error& e) {
    rethrow_for(part.name, e);
  }
}

// Predicted work of a part, for its share of the job's fraction (job_progress.cpp's units:
// ingest 3 per input face, refinement and writing ~5.5 per output face).
double part_work(const api::RefinePlan& plan) {
  return 3.0 * static_cast<double>(plan.shape.faces) +
         5.5 * static_cast<double>(std::max<std::uint64_t>(plan.predicted_faces, 1));
}

}  // namespace

api::ArchiveLimits job_archive_limits(std::uint64_t max_body_bytes) {
  api::ArchiveLimits limits;
  limits.max_total_bytes = max_body_bytes;
  return limits;
}

api::Problem archive_problem(const api::ArchiveError& e) {
  api::Problem p = api::problem_from_error(e);
  if (!e.entry().empty()) p.extensions["entry"] = e.entry();
  return p;
}

std::optional<std::vector<api::ArchivePart>> job_parts(std::span<const std::uint8_t> bytes,
                                                       const api::RefineRequest& request,
                                                       const api::ArchiveLimits& limits) {
  if (api::is_part_archive(bytes)) return api::read_part_archive(bytes, limits);
  if (request.mesh_format == MeshFormat::ThreeMf || sniff_mesh_format(bytes) != MeshFormat::ThreeMf)
    return std::nullopt;
  // Reading the objects (the reader's triangles, ~36 B each, then a binary STL copy of each
  // object, 50 B more) takes memory the budget must allow before it is taken, as a zip's
  // parts are: bounded by twice the bytes the package's XML inflates to (a triangle and its
  // share of vertices take at least ~43 B of XML). 503 while the budget is busy, 422 beyond
  // it (server/job_routes.cpp tells them apart).
  if (limits.reserve) {
    const std::uint64_t inflated = api::zip_inflated_bytes(bytes);
    const std::uint64_t wanted = saturating_add(inflated, inflated);
    if (!limits.reserve(wanted))
      throw api::ArchiveError(ErrorCode::BudgetExceeded, "memory_budget",
                              "the 3MF's objects take about " + std::to_string(wanted) +
                                  " bytes to read, more than the memory budget has free now",
                              "");
  }
  const MeshInput input = read_mesh(bytes);
  if (input.parts.size() < 2) return std::nullopt;
  const float mm = static_cast<float>(input.unit ? input.unit->mm : 1.0);
  std::vector<api::ArchivePart> parts;
  for (std::size_t k = 0; k < input.parts.size(); ++k) {
    const MeshPart& object = input.parts[k];
    api::ArchivePart part;
    part.name = object.name.empty() ? "object" + std::to_string(k + 1) : object.name;
    part.in_mm = true;
    // Binary STL: 80-byte header, count, then per facet a zero normal, 3 corners, 2 bytes.
    std::string& out = part.bytes;
    out.assign(80, '\0');
    const auto count = static_cast<std::uint32_t>(object.triangle_count);
    out.append(reinterpret_cast<const char*>(&count), 4);
    out.reserve(84 + 50 * std::size_t{count});
    const float* c = input.soup.coords.data() + 9 * object.first_triangle;
    for (std::size_t t = 0; t < object.triangle_count; ++t, c += 9) {
      float facet[12] = {};
      for (int i = 0; i < 9; ++i) facet[3 + i] = c[i] * mm;
      out.append(reinterpret_cast<const char*>(facet), sizeof facet);
      out.append(2, '\0');
    }
    parts.push_back(std::move(part));
  }
  return parts;
}

api::RefinePlan plan_parts_job(const api::RefinePlan& parameters,
                               const std::vector<api::ArchivePart>& parts,
                               std::uint64_t* result_bytes) {
  std::optional<api::RefinePlan> largest;
  std::uint64_t inputs = 0, results = 0;
  for (const api::ArchivePart& part : parts) {
    api::RefinePlan plan = plan_part(parameters, part);
    try {
      api::refuse_over_face_budget(plan);
    } catch (const Error& e) {
      rethrow_for(part.name, e);
    }
    inputs = saturating_add(inputs, part.bytes.size());
    results = saturating_add(results, predicted_result_bytes(plan.request, plan.memory));
    if (!largest || plan.memory.peak_bytes > largest->memory.peak_bytes) largest = std::move(plan);
  }
  // The parts run one at a time, beside the archive and its inflated parts.
  largest->memory.peak_bytes = saturating_add(largest->memory.peak_bytes, inputs);
  *result_bytes = saturating_add(results, results);
  return std::move(*largest);
}

nlohmann::ordered_json run_parts_job(const api::RefinePlan& plan,
                                     const std::vector<api::ArchivePart>& parts,
                                     const fs::path& dir, const std::atomic<bool>* cancel,
                                     const MemoryGrowFn& grow,
                                     const std::function<void(double, const std::string&)>& publish,
                                     std::vector<std::string>& results, std::uint64_t& bytes) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<api::RefinePlan> plans;
  double total_work = 0;
  for (const api::ArchivePart& part : parts) {
    plans.push_back(plan_part(plan, part));
    total_work += part_work(plans.back());
  }
  const std::size_t n = parts.size();
  nlohmann::ordered_json listed = nlohmann::ordered_json::array();
  std::vector<api::ZipFile> bundle;
  // Names in result.zip, lower-cased (extractors on Windows and macOS fold case): a part's
  // stem gets "-2", "-3"... until none of its names is taken, whatever the parts are called
  // (a/p.stl, b/p.stl and p-2.stl; a 3MF's objects p, p and p-2).
  std::set<std::string> used = {"report.json"};
  std::uint64_t in_faces = 0, out_faces = 0;
  double done_work = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const api::RefinePlan& part_plan = plans[k];
    const std::string label = "part " + std::to_string(k + 1) + "/" + std::to_string(n);
    JobProgress tracker(part_plan);
    const double work = part_work(part_plan);
    const auto overall = [&] {
      publish((done_work + work * tracker.fraction()) / total_work, label + ": " + tracker.stage());
    };
    tracker.enter(JobProgress::Stage::Ingest);
    overall();
    const auto progress = [&](double fraction, std::string_view stage) {
      tracker.on_core(fraction, stage);
      overall();
    };
    api::RefinedMesh refined;
    try {
      refined = api::run_refine_to_mesh(span_of(parts[k].bytes), part_plan, progress, cancel, grow);
    } catch (const MemoryBudgetError&) {
      throw;  // the runner tells 422 from a busy budget
    } catch (const Error& e) {
      rethrow_for(parts[k].name, e);
    }
    tracker.enter(JobProgress::Stage::Write);
    overall();
    const api::RefineOutcome& out = refined.outcome;
    const std::string base = "part" + std::to_string(k + 1);
    const std::string result =
        base + (part_plan.request.mesh_format == MeshFormat::ThreeMf ? ".3mf" : ".stl");
    if (refined.stream()) {
      write_atomically(dir / result,
                       [&](const ByteSink& sink) { write_binary_stl(refined.mesh, sink); });
      bytes += binary_stl_size(refined.mesh.num_faces());
    } else {
      write_atomically(dir / result, out.stl);
      bytes += out.stl.size();
    }
    results.push_back(result);
    // In result.zip under the part's own name: bracket.stl -> bracket_refined.stl.
    const std::string contours_ext =
        out.contours ? slicer::file_extension(part_plan.request.slice->format) : "";
    const std::string base_stem = zip_stem(parts[k].name);
    std::string stem = base_stem;
    for (int seen = 2;; ++seen) {
      const std::string refined_name = lowered(stem + "_refined" + result.substr(result.find('.')));
      const std::string slices_name = lowered(stem + "_slices" + contours_ext);
      if (!used.contains(refined_name) && (!out.contours || !used.contains(slices_name))) {
        used.insert(refined_name);
        if (out.contours) used.insert(slices_name);
        break;
      }
      stem = base_stem + "-" + std::to_string(seen);
    }
    bundle.push_back({stem + "_refined" + result.substr(result.find('.')), dir / result});
    nlohmann::ordered_json entry;
    entry["name"] = parts[k].name;
    entry["input_faces"] = out.report["input"].value("faces", 0ull);
    entry["output_faces"] = out.report["output"].value("faces", 0ull);
    entry["result"] = result;
    if (out.contours) {
      const std::string& ext = contours_ext;
      const std::string contours = base + ".contours" + ext;
      write_atomically(dir / contours, *out.contours);
      results.push_back(contours);
      bytes += out.contours->size();
      bundle.push_back({stem + "_slices" + ext, dir / contours});
      entry["contours"] = contours;
    }
    entry["report"] = out.report;
    in_faces += entry["input_faces"].get<std::uint64_t>();
    out_faces += entry["output_faces"].get<std::uint64_t>();
    listed.push_back(std::move(entry));
    done_work += work;
    if (cancel && *cancel) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled");
  }
  nlohmann::ordered_json report;
  report["input"] = {
      {"format", parts.front().in_mm ? "3mf" : "zip"}, {"parts", n}, {"faces", in_faces}};
  report["output"] = {{"parts", n}, {"faces", out_faces}};
  report["parts"] = std::move(listed);
  const std::string report_text =
      report.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
  write_atomically(dir / "report.json", report_text);
  results.push_back("report.json");
  bytes += report_text.size();
  bundle.push_back({"report.json", dir / "report.json"});
  // libzip writes ".result.zip.tmp" through its own temporary file; the rename makes it whole.
  const fs::path tmp = dir / ".result.zip.tmp";
  api::write_zip_of_files(tmp, bundle);
  fs::rename(tmp, dir / "result.zip");
  results.push_back("result.zip");
  bytes += fs::file_size(dir / "result.zip");
  report["seconds"] = {
      {"total", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()}};
  return report;
}

bool part_file_name(const std::string& file) {
  if (file.rfind("part", 0) != 0) return false;
  std::size_t i = 4;
  while (i < file.size() && file[i] >= '0' && file[i] <= '9') ++i;
  if (i == 4 || i > 10 || file[4] == '0') return false;
  const std::string rest = file.substr(i);
  return rest == ".stl" || rest == ".3mf" || rest == ".contours.json" || rest == ".contours.svg" ||
         rest == ".contours.cli";
}

nlohmann::ordered_json parts_json(const nlohmann::ordered_json& report, const std::string& self) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  if (!report.contains("parts") || !report["parts"].is_array()) return out;
  for (const auto& p : report["parts"]) {
    nlohmann::ordered_json j;
    j["name"] = p.value("name", "");
    j["input_faces"] = p.value("input_faces", 0ull);
    j["faces"] = p.value("output_faces", 0ull);
    nlohmann::ordered_json links;
    if (p.contains("result")) links["result"] = self + "/" + p["result"].get<std::string>();
    if (p.contains("contours")) links["contours"] = self + "/" + p["contours"].get<std::string>();
    j["links"] = std::move(links);
    out.push_back(std::move(j));
  }
  return out;
}

std::string part_of_file(const nlohmann::ordered_json& report, const std::string& file) {
  if (!report.contains("parts") || !report["parts"].is_array()) return {};
  for (const auto& p : report["parts"])
    if (p.value("result", "") == file || p.value("contours", "") == file)
      return base_name(p.value("name", ""));
  return {};
}

}  // namespace stlrefine::server
