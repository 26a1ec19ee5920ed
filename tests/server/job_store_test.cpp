// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The job store itself (server/jobs.h), without HTTP: unpredictable ids, jobs owned by
// their tenant, a full disk, leftovers of a crash, a cancel racing a job's end, and jobs
// cancelled by a shutdown (issue 16, items 2, 7 and 8).

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <bitset>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "api/memory_model.h"
#include "api/params.h"
#include "server/compute_slots.h"
#include "server/jobs.h"
#include "test_stl.h"

namespace stlrefine::server {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using Json = nlohmann::json;
using Lookup = JobStore::Lookup;
using Status = SubmitResult::Status;

const std::string kKeyOne = "0123456789abcdef-key-one";
const std::string kKeyTwo = "fedcba9876543210-key-two";

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-jobstore-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

// A fresh data directory, removed at the end of the test (declared before the stores in
// it, so that they are gone first).
struct DataDir {
  explicit DataDir(const std::string& name) : path(fresh_dir(name)) {}
  ~DataDir() {
    std::error_code ignored;
    fs::remove_all(path, ignored);
  }
  DataDir(const DataDir&) = delete;
  DataDir& operator=(const DataDir&) = delete;
  const fs::path path;
};

JobsConfig config_for(const fs::path& dir, const std::string& instance = "replica-a") {
  JobsConfig config;
  config.data_dir = dir;
  config.instance = instance;
  config.max_queued = 64;
  config.runners = 1;
  config.min_free_bytes = 0;
  return config;
}

api::RefineRequest request_for(const std::string& query) {
  return api::parse_refine_params(api::parse_query(query), api::RequestLimits{});
}

const std::string& octahedron() {
  static const std::string bytes = test::binary_stl(test::octahedron_triangles());
  return bytes;
}

const std::string& fandisk() {
  static const std::string bytes =
      test::read_file(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl");
  return bytes;
}

// Submits and expects it accepted; the job's id.
std::string submit(JobStore& store, const std::string& query, const std::string& body,
                   const std::string& owner = "") {
  SubmitResult r = store.submit(request_for(query), query, body, owner, 1 << 20);
  EXPECT_EQ(r.status, Status::Accepted);
  return r.job ? r.job->id : std::string();
}

bool is_finished(JobState s) {
  return s == JobState::Done || s == JobState::Failed || s == JobState::Cancelled;
}

JobView wait_finished(const JobStore& store, const std::string& id, const std::string& owner,
                      std::chrono::seconds timeout = 60s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  JobView job;
  while (std::chrono::steady_clock::now() < deadline) {
    if (store.find(id, owner, &job) != Lookup::Unknown && is_finished(job.state)) return job;
    std::this_thread::sleep_for(5ms);
  }
  ADD_FAILURE() << "job " << id << " did not finish; stage " << job.stage;
  return job;
}

// Waits until the job computes (past its compute slot and memory).
void wait_computing(const JobStore& store, const std::string& id) {
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  JobView job;
  while (std::chrono::steady_clock::now() < deadline) {
    ASSERT_EQ(store.find(id, "", &job), Lookup::Found);
    if (job.stage.rfind("level", 0) == 0) return;
    ASSERT_FALSE(is_finished(job.state)) << job.stage;
    std::this_thread::sleep_for(5ms);
  }
  FAIL() << "job " << id << " never computed";
}

Json job_file(const fs::path& dir, const std::string& id) {
  return Json::parse(test::read_file(dir / id / "job.json"));
}

void backdate(const fs::path& path, std::chrono::seconds age) {
  fs::last_write_time(path, fs::file_time_type::clock::now() - age);
}

std::set<std::string> entries(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// std::mt19937_64's output function, inverted: the state word behind an output.
std::uint64_t untemper(std::uint64_t z) {
  std::uint64_t y = z ^ (z >> 43);
  y ^= (y << 37) & 0xfff7eee000000000ull;
  std::uint64_t x = y;
  for (int i = 0; i < 4; ++i) x = y ^ ((x << 17) & 0x71d67fffeda60000ull);
  std::uint64_t w = x;
  for (int i = 0; i < 3; ++i) w = x ^ ((w >> 29) & 0x5555555555555555ull);
  return w;
}

std::uint64_t temper(std::uint64_t y) {
  y ^= (y >> 29) & 0x5555555555555555ull;
  y ^= (y << 17) & 0x71d67fffeda60000ull;
  y ^= (y << 37) & 0xfff7eee000000000ull;
  return y ^ (y >> 43);
}

// The attack of issue 16: 312 consecutive outputs of a std::mt19937_64 give its state, and
// so its next output.
std::uint64_t predict_next(const std::vector<std::uint64_t>& outputs) {
  constexpr std::size_t n = 312, m = 156;
  const std::size_t k = outputs.size() - n;  // the window: outputs[k .. k + n)
  const std::uint64_t a = untemper(outputs[k]), b = untemper(outputs[k + 1]),
                      c = untemper(outputs[k + m]);
  const std::uint64_t y = (a & 0xffffffff80000000ull) | (b & 0x7fffffffull);
  return temper(c ^ (y >> 1) ^ ((y & 1) ? 0xb5026f5aa96619e9ull : 0));
}

std::uint64_t hex64(const std::string& text) {
  return std::stoull(text, nullptr, 16);
}

TEST(JobIds, Are128BitsOfUrlSafeTextAndDistinct) {
  const DataDir data_dir("ids");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  auto held = slots.try_acquire();  // jobs stay queued
  JobsConfig config = config_for(dir);
  config.max_queued = 400;
  JobStore store(config, slots);
  std::set<std::string> ids;
  std::bitset<128> ones, zeros;
  for (int i = 0; i < 300; ++i) {
    const std::string id = submit(store, "scheme=lsf&levels=1", octahedron());
    ASSERT_EQ(id.size(), 32u) << id;
    for (std::size_t d = 0; d < id.size(); ++d) {
      const char c = id[d];
      ASSERT_TRUE((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f')) << id;
      const int v = c <= '9' ? c - '0' : c - 'a' + 10;
      for (int b = 0; b < 4; ++b) (v >> b & 1 ? ones : zeros).set(4 * d + b);
    }
    EXPECT_TRUE(ids.insert(id).second) << "id repeated: " << id;
  }
  // Every one of the 128 bits varies (a fixed or missing half would not).
  EXPECT_TRUE(ones.all() && zeros.all()) << ones << "\n" << zeros;
}

TEST(JobIds, CannotBePredictedFromEarlierIds) {
  // The predictor works: on a std::mt19937_64 (today's id generator) it gets the next
  // output right from the 312 before it.
  std::mt19937_64 engine(std::random_device{}());
  engine.discard(1000);
  std::vector<std::uint64_t> outputs(312);
  for (auto& o : outputs) o = engine();
  ASSERT_EQ(predict_next(outputs), engine());

  // Against the store: 156 ids (312 64-bit halves) and a guess at the 157th, for either
  // order in which an id could print its two halves.
  const DataDir data_dir("predict");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  auto held = slots.try_acquire();
  JobsConfig config = config_for(dir);
  config.max_queued = 200;
  JobStore store(config, slots);
  std::vector<std::string> ids;
  for (int i = 0; i < 156; ++i) {
    ids.push_back(submit(store, "scheme=lsf&levels=1", octahedron()));
    ASSERT_EQ(ids.back().size(), 32u);
  }
  const std::string next = submit(store, "scheme=lsf&levels=1", octahedron());
  ASSERT_EQ(next.size(), 32u);
  for (const bool swapped : {false, true}) {
    std::vector<std::uint64_t> outputs;
    for (const std::string& id : ids) {
      outputs.push_back(hex64(id.substr(swapped ? 16 : 0, 16)));
      outputs.push_back(hex64(id.substr(swapped ? 0 : 16, 16)));
    }
    const std::uint64_t first = predict_next(outputs);
    outputs.push_back(first);
    const std::uint64_t second = predict_next(outputs);
    const std::uint64_t guess[2] = {swapped ? second : first, swapped ? first : second};
    EXPECT_FALSE(hex64(next.substr(0, 16)) == guess[0] && hex64(next.substr(16)) == guess[1])
        << "the next job id was predicted from the 156 before it: " << next;
  }
}

TEST(JobIds, MalformedIdsAreUnknownAndNeverReachAPath) {
  const DataDir data_dir("malformed");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  JobStore store(config_for(dir), slots);
  const std::string id = submit(store, "scheme=butterfly&levels=1", octahedron());
  ASSERT_EQ(wait_finished(store, id, "").state, JobState::Done);
  // A directory with a valid job.json under a name that is not an id, inside and outside
  // the data directory.
  for (const fs::path& planted : {dir / "not-an-id", dir.parent_path() / "outside-jobstore"}) {
    fs::create_directories(planted);
    fs::copy_file(dir / id / "job.json", planted / "job.json",
                  fs::copy_options::overwrite_existing);
  }
  std::string upper = id;
  for (char& c : upper) c = static_cast<char>(std::toupper(c));
  const std::vector<std::string> bad = {"",
                                        "not-an-id",
                                        "../outside-jobstore",
                                        "../" + fs::path(dir).filename().string() + "/" + id,
                                        upper,
                                        id.substr(1),
                                        id + "0",
                                        id.substr(0, 22),
                                        id.substr(0, 31) + "/",
                                        id.substr(0, 31) + "g",
                                        std::string(32, '.'),
                                        "AAAAAAAAAAAAAAAAAAAAAA"};
  for (const std::string& s : bad) {
    JobView out;
    out.id = "untouched";
    EXPECT_EQ(store.find(s, "", &out), Lookup::Unknown) << s;
    EXPECT_EQ(store.cancel(s, "", &out), Lookup::Unknown) << s;
    EXPECT_EQ(out.id, "untouched");
  }
  JobView still;
  EXPECT_EQ(store.find(id, "", &still), Lookup::Found);
  EXPECT_FALSE(still.expired);
  fs::remove_all(dir.parent_path() / "outside-jobstore");
}

TEST(JobTenants, AnotherOwnerGetsUnknownForFindAndCancelAlsoAfterARestart) {
  const DataDir data_dir("tenants");
  const fs::path& dir = data_dir.path;
  std::string done_id, queued_id, one, two;
  {
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    one = store.tenant_of(kKeyOne);
    two = store.tenant_of(kKeyTwo);
    done_id = submit(store, "scheme=butterfly&levels=1", octahedron(), one);
    ASSERT_EQ(wait_finished(store, done_id, one).state, JobState::Done);

    for (const std::string& other : {two, std::string()}) {
      JobView out;
      out.id = "untouched";
      EXPECT_EQ(store.find(done_id, other, &out), Lookup::Unknown);
      EXPECT_EQ(store.cancel(done_id, other, &out), Lookup::Unknown);
      EXPECT_EQ(out.id, "untouched");  // nothing of it is told
    }
    JobView mine;
    ASSERT_EQ(store.find(done_id, one, &mine), Lookup::Found);
    EXPECT_FALSE(mine.expired);  // the other tenant's DELETE deleted nothing
    EXPECT_EQ(mine.results.size(), 2u);
    EXPECT_TRUE(fs::exists(dir / done_id / "result.stl"));

    // A queued job: the other tenant cannot cancel it either.
    auto held = slots.try_acquire();
    queued_id = submit(store, "scheme=butterfly&levels=1", octahedron(), one);
    EXPECT_EQ(store.cancel(queued_id, two, nullptr), Lookup::Unknown);
    held.reset();
    EXPECT_EQ(wait_finished(store, queued_id, one).state, JobState::Done);
    EXPECT_EQ(job_file(dir, done_id)["tenant"], one);
  }
  // After a restart, and through another replica reading the job from disk.
  ComputeSlots slots(1);
  JobStore again(config_for(dir), slots);
  JobStore replica(config_for(dir, "replica-b"), slots);
  EXPECT_EQ(again.tenant_of(kKeyOne), one);
  EXPECT_EQ(replica.tenant_of(kKeyOne), one);
  for (JobStore* store : {&again, &replica}) {
    for (const std::string& id : {done_id, queued_id}) {
      JobView out;
      EXPECT_EQ(store->find(id, two, &out), Lookup::Unknown);
      EXPECT_EQ(store->find(id, "", &out), Lookup::Unknown);
      EXPECT_EQ(store->cancel(id, two, &out), Lookup::Unknown);
      ASSERT_EQ(store->find(id, one, &out), Lookup::Found);
      EXPECT_EQ(out.state, JobState::Done);
      EXPECT_FALSE(out.expired);
    }
  }
  EXPECT_FALSE(fs::exists(dir / done_id / "delete"));  // the replica left no note either
  EXPECT_TRUE(fs::exists(dir / done_id / "result.stl"));
}

TEST(JobTenants, TenantIdsAreKeyedStableAcrossRestartsAndTheKeyIsNeverStored) {
  const DataDir data_dir("tenant-key");
  const fs::path& dir = data_dir.path;
  std::string one, two, id;
  {
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    one = store.tenant_of(kKeyOne);
    two = store.tenant_of(kKeyTwo);
    EXPECT_EQ(store.tenant_of(kKeyOne), one);
    EXPECT_NE(one, two);
    EXPECT_NE(store.tenant_of(kKeyOne + "x"), one);
    EXPECT_EQ(one.size(), 32u);
    EXPECT_EQ(one.find_first_not_of("0123456789abcdef"), std::string::npos) << one;
    id = submit(store, "scheme=butterfly&levels=1", octahedron(), one);
    ASSERT_EQ(wait_finished(store, id, one).state, JobState::Done);
  }
  // The secret: 32 bytes, owner-only.
  const fs::path secret = dir / ".tenant-key";
  ASSERT_TRUE(fs::exists(secret));
  EXPECT_EQ(fs::file_size(secret), 32u);
  struct stat st {};
  ASSERT_EQ(::stat(secret.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // job.json names the tenant by its id; no file anywhere holds the key.
  EXPECT_EQ(job_file(dir, id)["tenant"], one);
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string bytes = test::read_file(e.path());
    EXPECT_EQ(bytes.find(kKeyOne), std::string::npos) << e.path();
    EXPECT_EQ(bytes.find("key-one"), std::string::npos) << e.path();
  }
  {
    // The same after a restart: owners still match.
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    EXPECT_EQ(store.tenant_of(kKeyOne), one);
    EXPECT_EQ(store.tenant_of(kKeyTwo), two);
    EXPECT_EQ(store.find(id, one, nullptr), Lookup::Found);
  }
  {
    // A keyed hash: another data directory (another secret) gives other ids.
    const DataDir elsewhere("tenant-key-2");
    ComputeSlots slots(1);
    JobStore store(config_for(elsewhere.path), slots);
    EXPECT_NE(store.tenant_of(kKeyOne), one);
  }
  // A damaged secret stops the store instead of silently orphaning every tenant's jobs.
  std::ofstream(secret, std::ios::trunc) << "short";
  ComputeSlots slots(1);
  EXPECT_THROW(JobStore(config_for(dir), slots), std::runtime_error);
}

TEST(JobStore, ACancelAnsweredFoundAlwaysEndsCancelledEvenAsTheJobFinishes) {
  const DataDir data_dir("race");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  JobStore store(config_for(dir), slots);
  int found = 0, late_found = 0, too_late = 0;
  for (int i = 0; i < 50; ++i) {
    const std::string id = submit(store, "scheme=butterfly&levels=3", octahedron());
    ASSERT_FALSE(id.empty());
    // Cancel right as the job finishes: once its stage is "writing" (the computation has
    // ended; it writes its files and marks itself done); every fifth time a little before,
    // every fifth once it is done. (A running job's progress never reads 1.)
    JobView seen;
    bool computed = false;
    const auto deadline = std::chrono::steady_clock::now() + 30s;
    while (std::chrono::steady_clock::now() < deadline) {
      ASSERT_EQ(store.find(id, "", &seen), Lookup::Found);
      if (is_finished(seen.state)) break;
      if (i % 5 == 4) continue;
      const bool writing = seen.stage == "writing";
      if (seen.state == JobState::Running && (i % 5 == 3 ? seen.progress >= 0.5 : writing)) {
        computed = writing;
        break;
      }
    }
    JobView answer;
    const Lookup cancelled = store.cancel(id, "", &answer);
    const JobView end = wait_finished(store, id, "");
    if (cancelled == Lookup::Found) {
      ++found;
      late_found += computed;
      EXPECT_EQ(end.state, JobState::Cancelled) << "run " << i << ": a cancel answered Found, "
                                                << "and the job ended " << to_string(end.state);
      EXPECT_TRUE(end.results.empty());
      EXPECT_FALSE(fs::exists(dir / id / "result.stl")) << "run " << i;
      ASSERT_TRUE(end.problem.has_value());
      EXPECT_EQ((*end.problem)["type"], "urn:stlrefine:problem:cancelled");
    } else {
      // It came too late, and says so: the job had finished, its results are deleted.
      ++too_late;
      EXPECT_EQ(cancelled, Lookup::TooLate) << "run " << i;
      EXPECT_TRUE(is_finished(answer.state));
      EXPECT_TRUE(answer.expired);
      EXPECT_EQ(store.find(id, "", nullptr), Lookup::Expired);
      EXPECT_FALSE(fs::exists(dir / id / "result.stl"));
    }
  }
  std::cout << "cancel answered Found " << found << " times (" << late_found
            << " after the refinement had ended), TooLate " << too_late << " times\n";
  // The race was run: cancels landed after the computation had ended; and those after the
  // end said they came too late.
  EXPECT_GE(late_found, 10);
  EXPECT_GE(too_late, 10);
}

TEST(JobStore, JobsCancelledByAShutdownSaySo) {
  const DataDir data_dir("shutdown-cancel");
  const fs::path& dir = data_dir.path;
  std::string graced, stopped;
  {
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    // 12.9k faces to 3.3M: seconds of work, cancelled at shutdown after a 50 ms grace.
    graced = submit(store, "scheme=butterfly&levels=4", fandisk());
    wait_computing(store, graced);
    store.shutdown(50ms);
  }
  const Json g = job_file(dir, graced);
  EXPECT_EQ(g["state"], "cancelled") << g.dump();
  EXPECT_EQ(g["problem"]["type"], "urn:stlrefine:problem:shutting-down") << g.dump();
  const std::string detail = g["problem"]["detail"];
  EXPECT_NE(detail.find("shutdown grace period"), std::string::npos) << detail;
  EXPECT_EQ(detail.find("client"), std::string::npos) << detail;
  {
    // A second SIGTERM: cancelled at once.
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    stopped = submit(store, "scheme=butterfly&levels=4", fandisk());
    wait_computing(store, stopped);
    store.cancel_running();
    const JobView job = wait_finished(store, stopped, "", 10s);
    EXPECT_EQ(job.state, JobState::Cancelled);
    ASSERT_TRUE(job.problem.has_value());
    EXPECT_EQ((*job.problem)["type"], "urn:stlrefine:problem:shutting-down");
    const std::string text = (*job.problem)["detail"];
    EXPECT_NE(text.find("at once"), std::string::npos) << text;
    EXPECT_EQ(text.find("client"), std::string::npos) << text;
  }
  EXPECT_EQ(job_file(dir, stopped)["problem"]["type"], "urn:stlrefine:problem:shutting-down");
}

TEST(JobStore, IsRefusedWithNoSpaceWhenTheDiskCannotHoldIt) {
  const DataDir data_dir("no-space");
  const fs::path& dir = data_dir.path;
  std::atomic<std::uint64_t> free{0};
  JobsConfig config = config_for(dir);
  config.min_free_bytes = 1000;
  config.free_bytes = [&] { return free.load(); };
  ComputeSlots slots(1);
  JobStore store(config, slots);
  const std::uint64_t input = octahedron().size(), predicted = 10'000;
  const std::string query = "scheme=butterfly&levels=1";
  const auto try_submit = [&] {
    return store.submit(request_for(query), query, octahedron(), "", predicted);
  };

  free = input + predicted + 1000 - 1;
  const SubmitResult refused = try_submit();
  ASSERT_EQ(refused.status, Status::NoSpace);
  EXPECT_FALSE(refused.job);
  EXPECT_EQ(refused.needed_bytes, input + predicted + 1000);
  EXPECT_EQ(refused.free_bytes, input + predicted + 1000 - 1);
  EXPECT_EQ(entries(dir), std::set<std::string>{".tenant-key"});  // nothing was written
  const api::Problem p = no_space_problem(refused);
  EXPECT_EQ(p.status, 507);
  EXPECT_EQ(p.slug, "insufficient-storage");
  EXPECT_EQ(p.extensions["needed_bytes"], input + predicted + 1000);

  // Just enough: accepted. While it waits, its predicted results stay promised: the same
  // job again does not fit in the same free space.
  free = input + predicted + 1000;
  auto held = slots.try_acquire();
  const SubmitResult first = try_submit();
  ASSERT_EQ(first.status, Status::Accepted);
  const SubmitResult second = try_submit();
  ASSERT_EQ(second.status, Status::NoSpace);
  EXPECT_EQ(second.needed_bytes, input + 2 * predicted + 1000);
  held.reset();
  EXPECT_EQ(wait_finished(store, first.job->id, "").state, JobState::Done);
  EXPECT_EQ(try_submit().status, Status::Accepted);  // its promise ended with it
}

TEST(JobStore, PredictedResultBytesBoundTheFilesAJobWrites) {
  const DataDir data_dir("predicted-bytes");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  JobStore store(config_for(dir), slots);
  for (const char* text : {"scheme=butterfly&levels=3", "scheme=loop&levels=2&slice=0.1",
                           "scheme=sqrt3&levels=2&slice=0.2&slice_format=svg"}) {
    const std::string query = text;
    const api::RefineRequest request = request_for(query);
    const auto bytes =
        std::span(reinterpret_cast<const std::uint8_t*>(octahedron().data()), octahedron().size());
    const api::MemoryEstimate estimate = api::estimate_refine_memory(
        bytes, api::stl_shape(bytes), request, api::ResultSink::JobFiles);
    const std::uint64_t predicted = predicted_result_bytes(request, estimate);
    EXPECT_GE(predicted, 84 + 50 * estimate.output_faces);
    const std::string id = submit(store, query, octahedron());
    const JobView job = wait_finished(store, id, "");
    ASSERT_EQ(job.state, JobState::Done) << query;
    std::uint64_t written = 0;
    for (const std::string& name : job.results) written += fs::file_size(dir / id / name);
    EXPECT_LE(written, predicted) << query;
  }
}

TEST(JobStore, AResultWriteWithoutSpaceFailsTheJobSayingSo) {
  const DataDir data_dir("enospc");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  JobStore store(config_for(dir), slots);
  auto held = slots.try_acquire();
  const std::string id = submit(store, "scheme=butterfly&levels=2", octahedron());
  // The result's temporary file leads to /dev/full: its write fails with ENOSPC.
  fs::create_symlink("/dev/full", dir / id / ".result.stl.tmp");
  held.reset();
  const JobView job = wait_finished(store, id, "");
  EXPECT_EQ(job.state, JobState::Failed);
  ASSERT_TRUE(job.problem.has_value());
  EXPECT_EQ((*job.problem)["status"], 507) << job.problem->dump();
  EXPECT_EQ((*job.problem)["type"], "urn:stlrefine:problem:insufficient-storage");
  EXPECT_NE((*job.problem)["detail"].get<std::string>().find("no space left on the device"),
            std::string::npos);
  EXPECT_TRUE(job.results.empty());
  // Its directory keeps job.json (saying failed) and nothing else: no result, no
  // temporary file, no input.
  EXPECT_EQ(entries(dir / id), std::set<std::string>{"job.json"});
  EXPECT_EQ(job_file(dir, id)["state"], "failed");
}

TEST(JobStore, ASubmitWhoseWritesFailForWantOfSpaceLeavesNoDirectory) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  // In a child process: files there may not grow past 4 KiB (EFBIG, like a full quota),
  // so a 50 KiB upload cannot be written.
  const auto child = [] {
    const fs::path dir = fresh_dir("efbig-" + std::to_string(::getpid()));
    int code = 0;
    {
      ComputeSlots slots(1);
      JobStore store(config_for(dir), slots);
      std::signal(SIGXFSZ, SIG_IGN);
      const rlimit limit{4096, 4096};
      if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) std::_Exit(10);
      std::vector<test::Triangle> many;
      for (int i = 0; i < 1000; ++i) many.push_back(test::octahedron_triangles()[i % 8]);
      const std::string big = test::binary_stl(many);
      const SubmitResult r = store.submit(request_for("levels=1"), "levels=1", big, "", 1 << 20);
      if (r.status != Status::NoSpace)
        code = 11;
      else if (entries(dir) != std::set<std::string>{".tenant-key"})
        code = 12;
    }
    fs::remove_all(dir);
    std::_Exit(code);
  };
  EXPECT_EXIT(child(), testing::ExitedWithCode(0), "");
}

TEST(JobStore, LeftoversOfACrashAreRemovedAtStartAndByTheJanitor) {
  const DataDir data_dir("leftovers");
  const fs::path& dir = data_dir.path;
  std::string done;
  {
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    done = submit(store, "scheme=butterfly&levels=1", octahedron());
    ASSERT_EQ(wait_finished(store, done, "").state, JobState::Done);
  }
  const auto make_dir = [&](const std::string& id) {
    fs::create_directories(dir / id);
    return dir / id;
  };
  const auto write = [](const fs::path& path, std::size_t bytes) {
    std::ofstream(path, std::ios::binary) << std::string(bytes, 'x');
  };
  // A job directory without job.json, a minute old: a crash between mkdir and job.json.
  const fs::path partial_old = make_dir("00000000000000000000000000000001");
  write(partial_old / ".input.stl.tmp", 1000);
  backdate(partial_old / ".input.stl.tmp", 120s);
  backdate(partial_old, 120s);
  // One just made: perhaps another replica's submit in progress; kept for now.
  const fs::path partial_new = make_dir("00000000000000000000000000000002");
  write(partial_new / ".input.stl.tmp", 1000);
  // A SIGKILL during a result write of this instance's job.
  write(dir / done / ".result.stl.tmp", 5000);
  // A job that was running here: its result was renamed into place, job.json not updated.
  const fs::path interrupted = make_dir("00000000000000000000000000000003");
  std::ofstream(interrupted / "job.json")
      << R"({"owner":"replica-a","state":"running","scheme":"butterfly","created_ms":1})";
  write(interrupted / "result.stl", 3000);
  write(interrupted / ".report.json.tmp", 10);
  // One another replica accepted a cancel for while this one was down: cancelled, as
  // that replica answered.
  const fs::path noted = make_dir("00000000000000000000000000000005");
  std::ofstream(noted / "job.json")
      << R"({"owner":"replica-a","state":"running","scheme":"butterfly","created_ms":1})";
  std::ofstream(noted / "cancel") << "cancel\n";
  // Another replica's running job: its fresh temporary file may be written right now.
  const fs::path other = make_dir("00000000000000000000000000000004");
  std::ofstream(other / "job.json")
      << R"({"owner":"replica-b","state":"running","scheme":"butterfly","created_ms":1})";
  write(other / ".result.stl.tmp", 2000);
  write(other / ".contours.json.tmp", 2000);
  backdate(other / ".contours.json.tmp", 120s);
  write(dir / ".tenant-key.0011223344556677.tmp", 32);
  backdate(dir / ".tenant-key.0011223344556677.tmp", 120s);

  ComputeSlots slots(1);
  JobStore store(config_for(dir), slots);
  EXPECT_FALSE(fs::exists(partial_old));
  EXPECT_TRUE(fs::exists(partial_new / ".input.stl.tmp"));
  EXPECT_FALSE(fs::exists(dir / done / ".result.stl.tmp"));
  EXPECT_TRUE(fs::exists(dir / done / "result.stl"));
  EXPECT_EQ(entries(interrupted), std::set<std::string>{"job.json"});
  JobView job;
  ASSERT_EQ(store.find("00000000000000000000000000000003", "", &job), Lookup::Found);
  EXPECT_EQ(job.state, JobState::Failed);
  ASSERT_EQ(store.find("00000000000000000000000000000005", "", &job), Lookup::Found);
  EXPECT_EQ(job.state, JobState::Cancelled);
  EXPECT_TRUE(fs::exists(other / ".result.stl.tmp"));
  EXPECT_FALSE(fs::exists(other / ".contours.json.tmp"));
  EXPECT_FALSE(fs::exists(dir / ".tenant-key.0011223344556677.tmp"));

  // The janitor: the same once they are a minute old.
  backdate(partial_new / ".input.stl.tmp", 120s);
  backdate(partial_new, 120s);
  backdate(other / ".result.stl.tmp", 120s);
  write(dir / done / ".job.json.tmp", 100);
  backdate(dir / done / ".job.json.tmp", 120s);
  store.expire_now();
  EXPECT_FALSE(fs::exists(partial_new));
  EXPECT_FALSE(fs::exists(other / ".result.stl.tmp"));
  EXPECT_TRUE(fs::exists(other / "job.json"));
  EXPECT_FALSE(fs::exists(dir / done / ".job.json.tmp"));
  EXPECT_EQ(store.find(done, "", nullptr), Lookup::Found);
}

TEST(JobStore, TemporaryFilesStillPresentCountAgainstTheDiskBudget) {
  const DataDir data_dir("tmp-budget");
  const fs::path& dir = data_dir.path;
  std::string id;
  std::uint64_t results = 0;
  {
    ComputeSlots slots(1);
    JobStore store(config_for(dir), slots);
    id = submit(store, "scheme=butterfly&levels=1", octahedron());
    const JobView job = wait_finished(store, id, "");
    ASSERT_EQ(job.state, JobState::Done);
    for (const std::string& name : job.results) results += fs::file_size(dir / id / name);
  }
  JobsConfig config = config_for(dir);
  config.disk_budget_bytes = results + 500;
  ComputeSlots slots(1);
  JobStore store(config, slots);
  store.expire_now();
  ASSERT_EQ(store.find(id, "", nullptr), Lookup::Found);  // within the budget
  // A write in progress (or interrupted less than a minute ago) takes 1000 bytes more.
  std::ofstream(dir / id / ".result.stl.tmp", std::ios::binary) << std::string(1000, 'x');
  store.expire_now();
  EXPECT_EQ(store.find(id, "", nullptr), Lookup::Expired);
}

TEST(JobStore, ADeleteThroughAnotherReplicaOfAFinishedJobIsTooLateAndDeletesIt) {
  const DataDir data_dir("replica-delete");
  const fs::path& dir = data_dir.path;
  ComputeSlots slots(1);
  JobStore owner(config_for(dir), slots);
  JobStore replica(config_for(dir, "replica-b"), slots);
  const std::string tenant = owner.tenant_of(kKeyOne);
  const std::string id = submit(owner, "scheme=butterfly&levels=1", octahedron(), tenant);
  ASSERT_EQ(wait_finished(owner, id, tenant).state, JobState::Done);
  JobView out;
  EXPECT_EQ(replica.cancel(id, tenant, &out), Lookup::TooLate);
  EXPECT_EQ(out.state, JobState::Done);
  owner.expire_now();  // what its janitor does within a minute
  EXPECT_EQ(owner.find(id, tenant, nullptr), Lookup::Expired);
  EXPECT_EQ(replica.find(id, tenant, nullptr), Lookup::Expired);
  EXPECT_FALSE(fs::exists(dir / id / "result.stl"));
}

}  // namespace
}  // namespace stlrefine::server
