// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// The job store's runners: a queued job waits for a compute slot and its memory, runs from
// the plan made when it was submitted, and writes its results by atomic rename.
#include <malloc.h>

#include <algorithm>
#include <limits>
#include <thread>

#include "api/pipeline.h"
#include "core/error.h"
#include "core/io/stl.h"
#include "server/admission.h"
#include "server/job_parts.h"
#include "server/job_progress.h"
#include "server/job_record.h"
#include "server/thread_priority.h"
#include "slicer/writers.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using namespace job_files;

void JobStore::run_jobs() {
  lower_thread_priority(config_.runner_nice);
  if (redis_) return run_queue_jobs();
  for (;;) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock lock(mutex_);
      work_.wait(lock, [&] { return !queue_.empty() || stopping_; });
      if (stopping_) return;
      job = queue_.front();
      queue_.pop_front();
      ++running_;
      job->state = JobState::Running;
      job->stage = "waiting for a compute slot";
    }
    run_one(job);
    std::lock_guard lock(mutex_);
    --running_;
    work_.notify_all();  // shutdown() waits for running_ == 0
  }
}

void JobStore::run_one(const std::shared_ptr<Job>& job) {
  const auto cancelled = [&] { return job->cancel || cancel_all_ || cancel_noted(*job); };
  // Jobs share the compute slots with the synchronous routes: wait for one, polling so a
  // cancel or shutdown is seen.
  std::optional<ComputeSlots::Lease> lease;
  while (!(lease = slots_.try_acquire()) && !cancelled())
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (!lease && redis_ && hand_back(*job)) return;
  {
    std::lock_guard lock(mutex_);
    job->started = Clock::now();
    job->stage = "starting";
    if (!redis_) persist_or_log(*job);
  }
  // Queue mode: a call to Redis, not under the store's lock (only this thread writes these
  // fields now).
  if (redis_) persist_or_log(*job);
  // Done: results written; Cancelled: stopped by a cancel (which one is decided below,
  // under the lock); Failed: `problem`.
  JobState state = JobState::Failed;
  std::optional<api::Problem> problem;
  nlohmann::ordered_json report;
  std::vector<std::string> results;
  std::uint64_t bytes = 0;
  std::optional<MemoryBudget::Reservation> memory;
  std::shared_ptr<RequestWatch::Ticket> ticket;
  struct Refused {
    api::Problem problem;
  };
  try {
    if (!lease) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled before it started");
    const std::string input = read_file(job->dir / kInputFile);
    const auto input_bytes =
        std::span(reinterpret_cast<const std::uint8_t*>(input.data()), input.size());
    // Planned when it was submitted (parsed, validated, its scheme made, its body's shape
    // sniffed, its faces and memory predicted): nothing is planned again.
    const api::RefinePlan& plan = job->plan;
    if (config_.memory) {
      // Its predicted peak, before any work (the face budget first); it waits for that like
      // for a slot.
      const ReserveFn reserve = [&](std::uint64_t peak) {
        if ((memory = config_.memory->try_reserve(peak))) return true;
        {
          std::lock_guard lock(mutex_);
          job->stage = "waiting for memory";
        }
        while (!(memory = config_.memory->try_reserve(peak)) && !cancelled())
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        if (!memory) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled before it started");
        return true;
      };
      if (std::optional<api::Problem> refused =
              admit(plan, config_.memory->capacity(), reserve, job_busy_problem))
        throw Refused{*refused};
    }
    {
      // The deadline counts from here; DELETE and shutdown raise the same flag.
      std::lock_guard lock(mutex_);
      ticket = watch_.watch(-1, config_.deadline);
      job->ticket = ticket;
      if (job->cancel)
        ticket->raise(job->cancel_reason == CancelReason::Client ? RequestWatch::Reason::Cancelled
                                                                 : RequestWatch::Reason::Shutdown);
    }
    // One fraction over every stage, never backwards (job_progress.h).
    JobProgress tracker(plan);
    const auto publish = [&] {
      std::lock_guard lock(mutex_);
      job->progress = tracker.fraction();
      job->stage = tracker.stage();
    };
    tracker.enter(JobProgress::Stage::Ingest);
    publish();
    auto progress = [&](double fraction, std::string_view stage) {
      cancel_noted(*job);  // from another replica
      tracker.on_core(fraction, stage);
      publish();
    };
    // The reservation grows with the refinement. Memory held by other work may come back:
    // wait for it a while (cancellable), then give up rather than hold half a hierarchy.
    auto grow = [&](std::uint64_t needed) {
      if (!memory) return true;  // no budget configured
      if (needed > config_.memory->capacity()) return false;
      const auto until = std::chrono::steady_clock::now() + kGrowWait;
      while (!memory->grow_to(needed)) {
        if (std::chrono::steady_clock::now() > until || ticket->cancel) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      return true;
    };
    // A zip of mesh files, or a 3MF's objects refined to STL: each part on its own
    // (job_parts.h). A zip's content was checked against the body limit at submit.
    const std::optional<std::vector<api::ArchivePart>> parts = job_parts(
        input_bytes, plan.request, job_archive_limits(std::numeric_limits<std::uint64_t>::max()));
    if (parts) {
      const auto publish_parts = [&](double fraction, const std::string& stage) {
        cancel_noted(*job);  // from another replica
        std::lock_guard lock(mutex_);
        job->progress = std::max(job->progress, std::min(fraction, 0.995));
        job->stage = stage;
      };
      report = run_parts_job(plan, *parts, job->dir, &ticket->cancel, grow, publish_parts, results,
                             bytes);
    } else {
      api::RefinedMesh refined =
          api::run_refine_to_mesh(input_bytes, plan, progress, &ticket->cancel, grow);
      const api::RefineOutcome& out = refined.outcome;
      report = out.report;
      tracker.enter(JobProgress::Stage::Write);
      publish();
      // Each file is listed once it is whole, so a failure below removes exactly those.
      if (refined.stream()) {  // binary: made as it is written, never whole in memory
        const auto start = std::chrono::steady_clock::now();
        write_atomically(job->dir / "result.stl",
                         [&](const ByteSink& sink) { write_binary_stl(refined.mesh, sink); });
        bytes += binary_stl_size(refined.mesh.num_faces());
        // The report's write time is the streamed write's (run_refine's included its own).
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        report["seconds"]["write"] = seconds;
        report["seconds"]["total"] = report["seconds"]["total"].get<double>() + seconds;
      } else {
        write_atomically(job->dir / job_result_name(plan.request), out.stl);
        bytes += out.stl.size();
      }
      results.push_back(job_result_name(plan.request));
      if (out.contours) {
        const std::string name =
            std::string("contours") + slicer::file_extension(plan.request.slice->format);
        write_atomically(job->dir / name, *out.contours);
        results.push_back(name);
        bytes += out.contours->size();
      }
      const std::string report_text =
          report.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
      write_atomically(job->dir / "report.json", report_text);
      results.push_back("report.json");
      bytes += report_text.size();
    }
    state = JobState::Done;
  } catch (const Refused& r) {
    problem = r.problem;
  } catch (const api::ArchiveError& e) {
    if (e.code() == ErrorCode::Cancelled || job->cancel || cancel_all_)
      state = JobState::Cancelled;
    else
      problem = archive_problem(e);
  } catch (const MemoryBudgetError& e) {
    if (job->cancel || cancel_all_) {
      state = JobState::Cancelled;
    } else {
      problem = config_.memory ? memory_problem(e, config_.memory->capacity(), job_busy_problem)
                               : api::problem_from_error(e);
    }
  } catch (const Error& e) {
    if (e.code() == ErrorCode::Cancelled || job->cancel || cancel_all_)
      state = JobState::Cancelled;
    else
      problem = api::problem_from_error(e);
  } catch (const std::system_error& e) {
    if (no_space(e.code())) {
      log_line("job " + job->id + " failed: " + e.what());
      problem = no_space_result_problem();
    } else {
      log_line("job " + job->id + " failed: " + e.what());
      problem = api::internal_error();
    }
  } catch (const std::exception& e) {
    log_line("job " + job->id + " failed: " + e.what());
    problem = api::internal_error();
  }
  lease.reset();
  ::malloc_trim(0);  // what the refinement freed goes back before its reservation does
  memory.reset();
  std::error_code ignored;
  if (!redis_) fs::remove(job->dir / kInputFile, ignored);  // queue mode: once recorded
  // Called under mutex_ (job->superseded is written under it).
  const auto discard = [&] {
    // A run whose lease lapsed wrote under the names the run that took it over writes (and
    // may have recorded): those files are not its to remove.
    if (!job->superseded)
      for (const std::string& name : results) fs::remove(job->dir / name, ignored);
    results.clear();
    bytes = 0;
  };
  if (state != JobState::Done) {  // a write that failed half-way
    std::lock_guard lock(mutex_);
    discard();
  }

  JobView done;
  {
    // Another replica's cancel note is either here now, or it finds the job finished.
    DirLock dir_lock(job->dir);
    // Queue mode: the seal script, before the store's lock is taken.
    const bool cancel_came = cancel_arrived(*job);
    std::lock_guard lock(mutex_);
    if (cancel_came) request_cancel(*job, CancelReason::Client);
    const CancelReason why = job->cancel_reason;
    if (why == CancelReason::Client) {
      // A cancel answered Found before this point: it wins, even over finished work.
      const bool discarded = state == JobState::Done;
      discard();
      state = JobState::Cancelled;
      problem = cancel_problem(why, discarded);
    } else if (state == JobState::Cancelled) {
      if (ticket && ticket->reason() == RequestWatch::Reason::Deadline) {
        state = JobState::Failed;
        problem = deadline_problem(config_.deadline);
      } else {
        problem = cancel_problem(why != CancelReason::None ? why : shutdown_reason_, false);
      }
    }
    job->ticket.reset();
    job->state = state;
    job->finished = Clock::now();
    job->progress = state == JobState::Done ? 1.0 : job->progress;
    // `state` alone says done; the stage of a failed or cancelled job says so too.
    job->stage = state == JobState::Done ? "finished" : to_string(state);
    job->report = std::move(report);
    if (problem) job->problem = api::to_json(*problem);
    job->results = results;
    job->result_bytes = bytes;
    release_disk(*job);
    std::optional<std::error_code> unrecorded;
    try {
      persist(*job);
    } catch (const std::exception& e) {
      log_line("job " + job->id + ": cannot record its state: " + e.what());
      const auto* error = dynamic_cast<const std::system_error*>(&e);
      unrecorded = error ? error->code() : std::error_code();
    }
    if (unrecorded && state == JobState::Done) {
      // Results nobody can find after a restart, and that replicas see running forever:
      // rather a failed job (job.json's last write was "starting").
      discard();
      job->state = JobState::Failed;
      job->stage = to_string(JobState::Failed);
      job->problem =
          api::to_json(no_space(*unrecorded) ? no_space_result_problem() : api::internal_error());
      job->results.clear();
      job->result_bytes = 0;
      persist_or_log(*job);
    }
    done = view(*job);
  }
  if (redis_) {
    // Queue mode: told (callback, metrics) only once its end is recorded in Redis, and only
    // by the run that recorded it; a run handed back or taken over runs again elsewhere.
    if (done.state == JobState::Cancelled && hand_back(*job)) return;
    {
      std::lock_guard lock(mutex_);
      if (job->superseded) return;
    }
    try {
      auto c = redis_->pool().take();
      if (!finish_queued(*c, *job)) return;
    } catch (const std::exception& e) {
      log_line("job " + job->id + ": cannot record its end (" + e.what() +
               "); it runs again once its lease lapses");
      return;
    }
    fs::remove(job->dir / kInputFile, ignored);
  }
  if (on_finished_)
    on_finished_(done, std::chrono::duration<double>(done.finished - done.started).count());
  notify_ended(done);
  janitor_wake_.notify_one();  // the disk budget may now be exceeded
}

}  // namespace stlrefine::server
