// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/compute_routes.h"

#include <malloc.h>

#include <chrono>
#include <new>
#include <optional>
#include <span>
#include <stdexcept>
#include <utility>

#include "api/archive.h"
#include "api/pipeline.h"
#include "api/plan.h"
#include "api/zip.h"
#include "core/error.h"
#include "core/io/mesh_formats.h"
#include "core/io/stl.h"
#include "server/admission.h"
#include "server/http_upload.h"
#include "slicer/writers.h"

namespace stlrefine::server {

void serve_compute(const RouteContext& ctx, const HttpRequest& req, CheckedRequest checked, int fd,
                   std::shared_ptr<MemoryBudget::Reservation> reservation, HttpAnswer& res) {
  // The file (a raw body, or the `file` part of a multipart form) and its name.
  Upload upload;
  if (std::optional<api::Problem> bad = read_upload(req, upload)) return ctx.respond(res, *bad);
  const std::string_view raw_body = upload.bytes;
  // A zip of mesh files has one result per part: a job's (POST /v1/jobs), not one answer.
  if (api::is_part_archive(
          std::span(reinterpret_cast<const std::uint8_t*>(raw_body.data()), raw_body.size()))) {
    api::Problem p = api::problem_from_error(
        Error(ErrorCode::MalformedStl, "archive_needs_job",
              "a zip of mesh files is refined part by part as one job: POST it to /v1/jobs "
              "(each part gets its own result, and result.zip bundles them)")
            .with_field("file"));
    return ctx.respond(res, p);
  }
  const std::string stem = download_stem(upload.name);
  if (ctx.config.test_hook) ctx.config.test_hook(checked.route->path);
  if (ctx.config.test_faults) {
    const std::string fault = req.header("X-Stlrefine-Test-Fault");
    if (fault == "throw") throw std::runtime_error("test fault secret-4711 in " + req.path);
    // What a failed allocation throws. Not a real huge allocation: under AddressSanitizer
    // (the asan preset) operator new reports and aborts instead of throwing.
    if (fault == "oom") throw std::bad_alloc();
  }
  std::shared_ptr<RequestWatch::Ticket> ticket;
  // What a computation freed goes back to the kernel before its reservation does: small
  // blocks (the adaptive hierarchies' chunks, stencil patches) otherwise stay in the
  // threads' malloc arenas, and a daemon that ran 577 MiB requests one after another under a
  // 640 MiB budget held 1.36 GB.
  struct TrimAfter {
    ~TrimAfter() { ::malloc_trim(0); }
  } trim_after;
  try {
    // The plan: the parameters precheck resolved before the upload (a refinement's scheme
    // made there), completed with the body's shape (sniffed once, here) and the predicted
    // faces and memory.
    const auto body =
        std::span(reinterpret_cast<const std::uint8_t*>(raw_body.data()), raw_body.size());
    std::optional<api::RefinePlan> refine_plan;
    std::optional<api::SlicePlan> slice_plan;
    std::optional<api::InfoPlan> info_plan;
    // The contours carry the file's name (SVG title, CLI $$LABEL, JSON name).
    if (checked.refine && checked.refine->request.slice)
      checked.refine->request.slice->writer.label = stem;
    if (checked.slice) checked.slice->slice.writer.label = stem;
    // Accept: model/3mf chooses 3MF when the query does not name a mesh_format.
    if (checked.refine && !checked.refine->request.mesh_format_given &&
        req.header("Accept").find("model/3mf") != std::string::npos &&
        !checked.refine->request.slice)
      checked.refine->request.mesh_format = MeshFormat::ThreeMf;
    if (checked.refine)
      refine_plan = api::plan_body(std::move(*checked.refine), body);
    else if (checked.slice)
      slice_plan = api::plan_slice(std::move(*checked.slice), body);
    else
      info_plan = api::plan_info(std::move(*checked.info), body);

    std::optional<ComputeSlots::Lease> lease = ctx.slots.try_acquire();
    if (!lease || ctx.stopping) return ctx.respond(res, ctx.busy_problem(ctx.stopping));

    // Memory, before any work: the prediction must fit what one request may have (422) and
    // next to the running requests (503). decide() reserved the body; grow that.
    if (!reservation) {
      std::optional<MemoryBudget::Reservation> r = ctx.memory.try_reserve(0);
      reservation = std::make_shared<MemoryBudget::Reservation>(std::move(*r));
    }
    const ReserveFn reserve = [&reservation](std::uint64_t bytes) {
      return reservation->grow_to(bytes);
    };
    const BusyFn busy = [&ctx](std::uint64_t bytes) { return ctx.memory_busy_problem(bytes); };
    const std::optional<api::Problem> refused =
        refine_plan ? admit(*refine_plan, ctx.memory.capacity(), reserve, busy)
                    : admit(slice_plan ? slice_plan->memory : info_plan->memory,
                            ctx.memory.capacity(), reserve, busy);
    if (refused) return ctx.respond(res, *refused);
    // Once computed, the reservation shrinks to the body and the answer, which stay in
    // memory until the answer is sent and the connection closed.
    auto keep_answer = [&](std::uint64_t answer_bytes) {
      reservation->shrink_to(req.body.size() + answer_bytes);
    };

    // Cancelled when the client hangs up, when the deadline passes (or on a second SIGTERM).
    ticket = ctx.watch.watch(fd, ctx.config.request_deadline);
    const std::atomic<bool>* cancel = &ticket->cancel;

    // Large answers are handed to the front end as they are, not copied: a refined STL can
    // be a GiB.
    auto provide = [&res](std::string bytes, const char* type) {
      auto data = std::make_shared<const std::string>(std::move(bytes));
      res.large.body = *data;
      res.large.keep = std::move(data);
      res.set_header("Content-Type", type);
    };
    if (refine_plan) {
      const auto started = std::chrono::steady_clock::now();
      // The reservation grows with the refinement (an adaptive hierarchy's size is known
      // only as it is made); it stops the moment it would pass the budget.
      // Refine + slice answers one zip, made in memory; an STL answer is made from the
      // refined mesh as it is sent.
      // report=zip: the result and report.json in one zip, made in memory too.
      const bool zip_answer = refine_plan->request.slice || refine_plan->request.report_in_zip;
      api::RefinedMesh refined =
          zip_answer
              ? api::RefinedMesh{api::run_refine(body, *refine_plan, {}, cancel, reserve), {}}
              : api::run_refine_to_mesh(body, *refine_plan, {}, cancel, reserve);
      api::RefineOutcome& out = refined.outcome;
      ctx.metrics.refinement(
          refine_plan->request.refine.scheme, "done",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(),
          out.report["input"].value("faces", 0ull), out.report["output"].value("faces", 0ull));
      // The report header is compact ASCII JSON (no CR/LF can reach a header).
      const std::string report =
          out.report.dump(-1, ' ', true, nlohmann::json::error_handler_t::replace);
      if (out.contours) {
        // Refine + slice: one zip with the refined STL, the contours and the report.
        const slicer::SliceFormat format = refine_plan->request.slice->format;
        std::string zip = api::make_zip({{"refined.stl", out.stl, false},
                                         {std::string("slices") + slicer::file_extension(format),
                                          *out.contours, format != slicer::SliceFormat::CliBinary},
                                         {"report.json", report, true}});
        lease.reset();
        keep_answer(zip.size());
        res.set_header(kReportHeader, report);
        provide(std::move(zip), kZipContentType);
      } else if (zip_answer) {
        const bool three_mf = refine_plan->request.mesh_format == MeshFormat::ThreeMf;
        std::string zip = api::make_zip({{three_mf ? "refined.3mf" : "refined.stl", out.stl, false},
                                         {"report.json", report, true}});
        out.stl = std::string();
        lease.reset();
        keep_answer(zip.size());
        res.set_header(kReportHeader, report);
        provide(std::move(zip), kZipContentType);
      } else if (refined.stream()) {
        // 84 + 50 n bytes, known now, made on the event loop piece by piece from the float
        // positions and corners (12 bytes a vertex and a face, not 50 a face): the mesh goes.
        auto stl = std::make_shared<const BinaryStl>(std::move(refined.mesh));
        lease.reset();
        keep_answer(stl->memory_bytes());
        res.set_header(kReportHeader, report);
        res.set_header("Content-Type", kStlContentType);
        res.large.made = [stl = stl.get()](std::uint64_t offset, std::span<char> bytes) {
          stl->read(offset, bytes);
        };
        res.large.made_length = stl->size();
        res.large.keep = std::move(stl);
      } else {
        lease.reset();
        keep_answer(out.stl.size());
        res.set_header(kReportHeader, report);
        const bool three_mf = refine_plan->request.mesh_format == MeshFormat::ThreeMf;
        provide(std::move(out.stl), three_mf ? k3mfContentType : kStlContentType);
      }
      // part.stl -> part_refined.stl (or .zip: named by what is sent).
      res.set_header(
          "Content-Disposition",
          content_disposition(stem, "_refined" + extension_for(res.header("Content-Type"))));
    } else if (slice_plan) {
      api::SliceOutcome out = api::run_slice(body, *slice_plan, {}, cancel);
      lease.reset();
      keep_answer(out.contours.size());
      const std::string report =
          out.report.dump(-1, ' ', true, nlohmann::json::error_handler_t::replace);
      res.set_header(kReportHeader, report);
      const slicer::SliceFormat format = slice_plan->request.slice.format;
      if (slice_plan->request.report_in_zip) {
        std::string zip = api::make_zip({{std::string("slices") + slicer::file_extension(format),
                                          out.contours, format != slicer::SliceFormat::CliBinary},
                                         {"report.json", report, true}});
        out.contours = std::string();
        keep_answer(zip.size());
        provide(std::move(zip), kZipContentType);
      } else {
        provide(std::move(out.contours), slicer::media_type(format));
      }
      res.set_header("Content-Disposition",
                     content_disposition(
                         stem, std::string("_slices") + (slice_plan->request.report_in_zip
                                                             ? std::string(".zip")
                                                             : slicer::file_extension(format))));
    } else {
      const nlohmann::ordered_json report = api::run_info(body, *info_plan);
      lease.reset();
      keep_answer(0);
      res.set_content(report.dump(2, ' ', true, nlohmann::json::error_handler_t::replace) + "\n",
                      kJsonContentType);
    }
    res.status = api::http::kOk;
  } catch (const MemoryBudgetError& e) {
    res.headers.erase(kReportHeader);
    res.headers.erase("Content-Disposition");
    res.headers.erase("Content-Type");
    res.large = Answer();
    ctx.respond(res, memory_problem(e, ctx.memory.capacity(), [&ctx](std::uint64_t bytes) {
                  return ctx.memory_busy_problem(bytes);
                }));
  } catch (const Error& e) {
    res.headers.erase(kReportHeader);
    res.headers.erase("Content-Disposition");
    res.headers.erase("Content-Type");
    res.large = Answer();
    if (e.code() == ErrorCode::Cancelled && ticket &&
        ticket->reason() == RequestWatch::Reason::Deadline)
      return ctx.respond(res, deadline_problem(ctx.config.request_deadline));
    ctx.respond(res, api::problem_from_error(e));
  }
}

}  // namespace stlrefine::server
