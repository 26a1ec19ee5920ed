// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 19 items 1-3 (round 5) against the daemon on an ephemeral loopback port: a job gives
// the outputs a synchronous refine gives (a multi-object 3MF in, part_refined.3mf out with
// its objects and unit), and its progress over several objects never stalls.

#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "api/params.h"
#include "api/plan.h"
#include "api/zip.h"
#include "core/io/mesh_formats.h"
#include "core/mesh/build_mesh.h"
#include "in_process_daemon.h"
#include "job_parts_fixtures.h"
#include "server/daemon.h"
#include "server/job_progress.h"
#include "test_stl.h"
#include "test_zip.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
using Json = nlohmann::json;

TEST(JobParts, AMultiObject3mfJobGivesPartRefined3mfWithItsObjectsAndUnit) {
  const auto dir = fresh_job_dir("3mf");
  InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  const std::string body =
      form_file("bracket.3mf", three_mf({{"left", box(10)}, {"right", box(10, 30)}}));
  httplib::Headers accept = {{"Accept", "model/3mf"}};
  auto r = c.Post("/v1/jobs?levels=1&scheme=butterfly", accept, body, form_type().c_str());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const Json job = wait_job(c, r->get_header_value("Location"));
  ASSERT_EQ(job["state"], "done") << job.dump();
  EXPECT_EQ(job["report"]["output"]["format"], "3mf");
  EXPECT_EQ(job["report"]["output"]["objects"], 2);
  ASSERT_EQ(job["links"]["result"], r->get_header_value("Location") + "/result.3mf");
  auto file = c.Get(job["links"]["result"].get<std::string>().c_str());
  ASSERT_TRUE(file);
  ASSERT_EQ(file->status, 200);
  EXPECT_EQ(file->get_header_value("Content-Type"), "model/3mf");
  EXPECT_EQ(file->get_header_value("Content-Disposition"),
            "attachment; filename=\"bracket_refined.3mf\"");
  const MeshInput out = read_mesh(bytes_of(file->body));
  EXPECT_EQ(out.format, MeshFormat::ThreeMf);
  ASSERT_EQ(out.parts.size(), 2u);
  EXPECT_EQ(out.parts[0].name, "left");
  EXPECT_EQ(out.parts[1].name, "right");
  ASSERT_TRUE(out.unit);
  EXPECT_EQ(out.unit->name, "millimeter");
  // There is no STL to ask for.
  auto stl = c.Get((r->get_header_value("Location") + "/result.stl").c_str());
  ASSERT_TRUE(stl);
  EXPECT_EQ(stl->status, 404);

  // mesh_format=3mf says the same without the header; a refine + slice job keeps refusing it.
  auto q = c.Post("/v1/jobs?levels=1&mesh_format=3mf", three_mf({{"one", box(5)}}), "model/3mf");
  ASSERT_TRUE(q);
  ASSERT_EQ(q->status, 202) << q->body;
  EXPECT_EQ(wait_job(c, q->get_header_value("Location"))["links"].value("result", ""),
            q->get_header_value("Location") + "/result.3mf");
  auto sliced = c.Post("/v1/jobs?levels=1&mesh_format=3mf&slice=0.5", three_mf({{"one", box(5)}}),
                       "model/3mf");
  ASSERT_TRUE(sliced);
  EXPECT_EQ(sliced->status, 400);
  EXPECT_EQ(Json::parse(sliced->body)["field"], "mesh_format");
}

// Refined to STL, a 3MF's objects are the job's parts: one STL each, in mm.
TEST(JobParts, A3mfOfSeveralObjectsRefinedToStlGivesOneResultPerObject) {
  const auto dir = fresh_job_dir("3mf-parts");
  InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  // In metres: 10 mm cubes.
  const std::string file = three_mf({{"left", box(0.01f)}, {"", box(0.01f, 0.03f)}}, "meter");
  auto r = c.Post("/v1/jobs?levels=1", form_file("pair.3mf", file), form_type().c_str());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const Json job = wait_job(c, r->get_header_value("Location"));
  ASSERT_EQ(job["state"], "done") << job.dump();
  ASSERT_EQ(job["parts"].size(), 2u) << job.dump();
  EXPECT_EQ(job["parts"][0]["name"], "left");
  EXPECT_EQ(job["parts"][1]["name"], "object 2");  // the reader names an unnamed object
  EXPECT_EQ(job["report"]["input"]["format"], "3mf");
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(job["parts"][k]["faces"], 48);
    auto stl = c.Get(job["parts"][k]["links"]["result"].get<std::string>().c_str());
    ASSERT_TRUE(stl);
    ASSERT_EQ(stl->status, 200);
    const std::vector<Triangle> tris = read_binary_stl(stl->body);
    ASSERT_EQ(tris.size(), 48u);
    float lo = 1e9f, hi = -1e9f;
    for (const Triangle& t : tris)
      for (const Corner& p : t) lo = std::min(lo, p[0]), hi = std::max(hi, p[0]);
    EXPECT_NEAR(hi - lo, 10.0f, 1e-3f) << k;  // mm, not 0.01
    EXPECT_NEAR(lo, k == 0 ? 0.0f : 30.0f, 1e-3f) << k;
    EXPECT_EQ(job["report"]["parts"][k]["report"]["warnings"].size(), 0u) << job.dump();
  }
  EXPECT_EQ(c.Get((r->get_header_value("Location") + "/part1.stl").c_str())
                ->get_header_value("Content-Disposition"),
            "attachment; filename=\"left_refined.stl\"");
}

// refine_3mf reports object i's fraction f as (i + f) / n and ends each object with "done":
// the job's fraction keeps rising through every object (it stalled at the first "done").
TEST(JobParts, ProgressRisesThroughEveryObjectOfA3mf) {
  const std::string file = three_mf({{"a", box(10)}, {"b", box(10, 30)}, {"c", box(10, 60)}});
  api::RefineRequest request = api::parse_refine_params({{"levels", "2"}}, {});
  server::JobProgress progress(api::plan_refine(request, bytes_of(file)));
  double last = progress.fraction();
  for (int object = 0; object < 3; ++object) {
    for (const double f : {0.25, 0.5, 1.0}) {
      progress.on_core((object + f) / 3, f < 1 ? "level 1/2" : "done");
      EXPECT_GT(progress.fraction(), last) << "object " << object << " at " << f;
      last = progress.fraction();
    }
  }
  progress.enter(server::JobProgress::Stage::Write);
  EXPECT_GT(progress.fraction(), last);
  EXPECT_LT(progress.fraction(), 1.0);
}

// A zip of parts: one job, each part refined and sliced on its own, with its name, its
// report entry and its files; result.zip bundles them under the parts' names.
TEST(JobParts, AZipOfMeshFilesIsOneJobWithOneResultPerPart) {
  const auto dir = fresh_job_dir("zip");
  InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  const std::string bracket = stl_of(box(10)), lid = stl_of(box(6, 20));
  const std::string knob = three_mf({{"knob", box(4)}});
  const std::string zip = raw_zip({{"parts/", ""},
                                   {"parts/bracket.stl", bracket},
                                   {"parts/lid.STL", lid},
                                   {"knob.3mf", knob},
                                   {"__MACOSX/parts/._lid.STL", "resource fork"}});
  auto r = c.Post("/v1/jobs?levels=1&slice=1&slice_format=cli", form_file("batch.zip", zip),
                  form_type().c_str());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string self = r->get_header_value("Location");
  // Progress over all parts: never backwards, under 1 until done.
  double last = 0;
  Json job;
  for (const auto until = std::chrono::steady_clock::now() + 60s;
       std::chrono::steady_clock::now() < until; std::this_thread::sleep_for(5ms)) {
    auto g = c.Get(self.c_str());
    ASSERT_TRUE(g);
    job = Json::parse(g->body);
    const double p = job["progress"];
    EXPECT_GE(p, last) << job.dump();
    last = p;
    if (job["state"] != "queued" && job["state"] != "running") break;
    EXPECT_LT(p, 1.0);
  }
  ASSERT_EQ(job["state"], "done") << job.dump();
  ASSERT_EQ(job["parts"].size(), 3u) << job.dump();
  const std::vector<std::string> names = {"parts/bracket.stl", "parts/lid.STL", "knob.3mf"};
  const std::vector<std::string> stems = {"bracket", "lid", "knob"};
  const std::vector<std::string> inputs = {bracket, lid, knob};
  for (std::size_t k = 0; k < 3; ++k) {
    const Json& part = job["parts"][k];
    EXPECT_EQ(part["name"], names[k]);
    EXPECT_EQ(part["input_faces"], 12);
    EXPECT_EQ(part["faces"], 48);  // one level: 4 times
    auto mesh = c.Get(part["links"]["result"].get<std::string>().c_str());
    ASSERT_TRUE(mesh);
    ASSERT_EQ(mesh->status, 200) << part.dump();
    EXPECT_EQ(mesh->get_header_value("Content-Disposition"),
              cat("attachment; filename=\"", stems[k], "_refined.stl\""));
    EXPECT_EQ(mesh->body.size(), 84u + 50u * 48u);
    // The same bytes as the part refined alone.
    auto alone = c.Post("/v1/refine?levels=1", inputs[k], "application/octet-stream");
    ASSERT_TRUE(alone);
    EXPECT_EQ(alone->body, mesh->body) << names[k];
    auto contours = c.Get(part["links"]["contours"].get<std::string>().c_str());
    ASSERT_TRUE(contours);
    ASSERT_EQ(contours->status, 200);
    EXPECT_EQ(contours->get_header_value("Content-Disposition"),
              cat("attachment; filename=\"", stems[k], "_slices.cli\""));
    EXPECT_NE(contours->body.find(cat("$$LABEL/1,", stems[k])), std::string::npos);
  }
  EXPECT_EQ(job["report"]["parts"].size(), 3u);
  EXPECT_EQ(job["report"]["output"]["faces"], 3 * 48);
  ASSERT_EQ(job["links"]["result"], self + "/result.zip");
  auto all = c.Get((self + "/result.zip").c_str());
  ASSERT_TRUE(all);
  ASSERT_EQ(all->status, 200);
  EXPECT_EQ(all->get_header_value("Content-Type"), "application/zip");
  EXPECT_EQ(all->get_header_value("Content-Disposition"),
            "attachment; filename=\"batch_refined.zip\"");
  std::map<std::string, std::string> files = unzip(all->body);
  for (const std::string& stem : stems) {
    EXPECT_EQ(files.count(stem + "_refined.stl"), 1u) << stem;
    EXPECT_EQ(files.count(stem + "_slices.cli"), 1u) << stem;
  }
  EXPECT_EQ(files.count("report.json"), 1u);
  auto bracket_mesh = c.Get(job["parts"][0]["links"]["result"].get<std::string>().c_str());
  EXPECT_EQ(files["bracket_refined.stl"], bracket_mesh->body);
  // Not a file of this job.
  for (const char* bad : {"part0.stl", "part4.stl", "part1.txt", "part01.stl"}) {
    auto none = c.Get((self + "/").append(bad).c_str());
    ASSERT_TRUE(none);
    EXPECT_EQ(none->status, 404) << bad;
  }
}

// Hostile zips are refused at submit with a 4xx naming the entry; nothing is written
// outside (or inside) the data directory for them.
TEST(JobParts, HostileZipsAreRefusedNamingTheEntry) {
  const auto dir = fresh_job_dir("hostile");
  server::DaemonConfig config = jobs_config(dir);
  config.max_body_bytes = 32 << 20;
  InProcessDaemon d(config);
  httplib::Client c = d.client();
  const std::string part = stl_of(box(10));
  std::vector<RawZipEntry> many;
  for (int i = 0; i < 10000; ++i) many.push_back({cat("p", std::to_string(i), ".stl"), "x"});
  // Zeros deflate about 1000:1.
  const std::string zeros(20 << 20, '\0');
  const std::string bomb = api::make_zip({{"bomb.stl", zeros, true}});
  struct Case {
    std::string what, zip, reason, entry;
    int status;
  };
  const std::vector<Case> cases = {
      {"traversal", raw_zip({{"ok.stl", part}, {"../evil.stl", part}}), "unsafe_name",
       "../evil.stl", 422},
      {"absolute", raw_zip({{"/etc/evil.stl", part}}), "unsafe_name", "/etc/evil.stl", 422},
      {"duplicate", raw_zip({{"a.stl", part}, {"a.stl", part}}), "duplicate_name", "a.stl", 422},
      {"encrypted", raw_zip({{"secret.stl", part, true}}), "encrypted", "secret.stl", 422},
      {"nested", raw_zip({{"inner.stl", raw_zip({{"x.stl", part}})}}), "nested_archive",
       "inner.stl", 422},
      {"not a mesh", raw_zip({{"a.stl", part}, {"README.txt", "hello"}}), "not_a_mesh",
       "README.txt", 422},
      {"10k entries", raw_zip(many), "too_many_entries", "", 422},
      {"declared too large", raw_zip({{"huge.stl", "abc", false, 200u << 20}}), "archive_too_large",
       "huge.stl", 422},
      {"ratio", bomb, "compression_ratio", "bomb.stl", 422},
      {"empty", raw_zip({{"dir/", ""}}), "no_parts", "", 422},
  };
  for (const Case& k : cases) {
    auto r = c.Post("/v1/jobs?levels=1", k.zip, "application/zip");
    ASSERT_TRUE(r) << k.what;
    EXPECT_EQ(r->status, k.status) << k.what << ": " << r->body;
    const Json p = Json::parse(r->body);
    EXPECT_EQ(p.value("field", ""), "file") << k.what << ": " << r->body;
    if (!k.reason.empty()) {
      EXPECT_EQ(p.value("reason", ""), k.reason) << k.what;
    }
    if (!k.entry.empty()) {
      EXPECT_EQ(p.value("entry", ""), k.entry) << k.what << ": " << r->body;
      EXPECT_NE(p.value("detail", "").find(k.entry), std::string::npos) << k.what;
    }
  }
  // A part that is not a mesh fails naming its entry: at submit when its shape says so, else
  // when it runs.
  auto bad = c.Post("/v1/jobs?levels=1",
                    raw_zip({{"good.stl", part}, {"bad.stl", std::string(84, 'x') + "short"}}),
                    "application/zip");
  ASSERT_TRUE(bad);
  std::string detail;
  if (bad->status == 202) {
    const Json job = wait_job(c, bad->get_header_value("Location"));
    EXPECT_EQ(job["state"], "failed");
    detail = job["problem"].value("detail", "");
    EXPECT_EQ(job["problem"].value("entry", ""), "bad.stl") << job.dump();
    std::filesystem::remove_all(dir / job["id"].get<std::string>());
  } else {
    EXPECT_EQ(bad->status, 422) << bad->body;
    detail = Json::parse(bad->body).value("detail", "");
  }
  EXPECT_NE(detail.find("bad.stl"), std::string::npos) << detail;
  // No job was made for any of them, and nothing named after an entry exists.
  std::size_t jobs = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find("evil"), std::string::npos) << e.path();
    if (e.path().filename() == "job.json") ++jobs;
  }
  EXPECT_EQ(jobs, 0u);
  EXPECT_FALSE(std::filesystem::exists(dir.parent_path() / "evil.stl"));
  // The daemon still serves.
  auto health = c.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

}  // namespace
}  // namespace stlrefine::test

namespace stlrefine::test {
namespace {

// The parts a zip inflates to are reserved in the memory budget before anything is
// inflated: beyond it a 422 (reason memory_budget), never an allocation the budget did not
// allow.
TEST(JobParts, AZipInflatingPastTheMemoryBudgetIsRefusedBeforeInflating) {
  const auto dir = fresh_job_dir("zip-memory");
  server::DaemonConfig config = jobs_config(dir);
  config.memory_budget = std::uint64_t{128} << 20;  // 64 MiB for work beside the daemon's 64
  InProcessDaemon d(config);
  httplib::Client c = d.client();
  // 1 MiB of noise claiming to inflate to 80 MiB (80:1 passes the ratio check).
  std::string noise(1 << 20, '\0');
  std::uint32_t x = 12345;
  for (char& ch : noise) ch = static_cast<char>((x = x * 1103515245u + 12345u) >> 24);
  auto r = c.Post("/v1/jobs?levels=1", raw_zip({{"big.stl", noise, false, 80u << 20}}),
                  "application/zip");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 422) << r->body;
  const Json p = Json::parse(r->body);
  EXPECT_EQ(p.value("reason", ""), "memory_budget") << r->body;
  EXPECT_EQ(p.value("field", ""), "file");
}

}  // namespace
}  // namespace stlrefine::test

namespace stlrefine::test {
namespace {

// result.zip's names of a done parts job (a test failure when the job did not end done).
std::vector<std::string> result_zip_names(httplib::Client& c, const std::string& self) {
  const Json job = wait_job(c, self);
  EXPECT_EQ(job["state"], "done") << job.dump();
  auto all = c.Get((self + "/result.zip").c_str());
  EXPECT_TRUE(all && all->status == 200);
  std::vector<std::string> names;
  if (!all || all->status != 200) return names;
  for (const auto& [name, bytes] : unzip(all->body)) names.push_back(name);
  return names;
}

// Parts whose names make the same name in result.zip (a/p.stl and b/p.stl make p-2, and so
// does p-2.stl; P.stl and p.stl are one file on Windows and macOS): each gets a free name
// and the job ends done (zip_file_add refused the second "p-2_refined.stl": Internal).
TEST(JobParts, PartsWhoseNamesCollideInResultZipGetDistinctNames) {
  const auto dir = fresh_job_dir("zip-collide");
  InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  const std::string part = stl_of(box(5));
  auto r =
      c.Post("/v1/jobs?levels=1",
             raw_zip({{"a/p.stl", part}, {"b/p.stl", part}, {"p-2.stl", part}, {"P.stl", part}}),
             "application/zip");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  std::vector<std::string> names = result_zip_names(c, r->get_header_value("Location"));
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"P-3_refined.stl", "p-2-2_refined.stl",
                                             "p-2_refined.stl", "p_refined.stl", "report.json"}));
  // A 3MF's objects named p, p and p-2, likewise.
  const std::string file = three_mf({{"p", box(5)}, {"p", box(5, 10)}, {"p-2", box(5, 20)}});
  r = c.Post("/v1/jobs?levels=1", file, "model/3mf");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  names = result_zip_names(c, r->get_header_value("Location"));
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"p-2-2_refined.stl", "p-2_refined.stl",
                                             "p_refined.stl", "report.json"}));
}

// A 3MF's object names are free text: in result.zip they keep only the characters a
// download's filename keeps, and at most 100 bytes of them (no "..\..\", "C:", newline or
// 300-byte entry name reaches an extractor; the 3MF reader keeps names up to 4 KB).
TEST(JobParts, ObjectNamesAreMadeSafeInResultZip) {
  const auto dir = fresh_job_dir("zip-names");
  InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  const std::string file = three_mf({{"..\\..\\Windows\\evil", box(5)},
                                     {"C:evil", box(5, 10)},
                                     {"two\nlines", box(5, 20)},
                                     {std::string(300, 'x'), box(5, 30)}});
  auto r = c.Post("/v1/jobs?levels=1", file, "model/3mf");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::vector<std::string> names = result_zip_names(c, r->get_header_value("Location"));
  ASSERT_EQ(names.size(), 5u);
  for (const std::string& name : names) {
    EXPECT_EQ(name.find_first_of("\\/:\n"), std::string::npos) << name;
    EXPECT_NE(name.front(), '.') << name;
    EXPECT_LE(name.size(), 100u + std::string("_refined.stl").size()) << name;
  }
  EXPECT_NE(std::find(names.begin(), names.end(), "_.._Windows_evil_refined.stl"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "C_evil_refined.stl"), names.end());
  EXPECT_NE(std::find_if(names.begin(), names.end(),
                         [](const std::string& n) { return n.rfind("two", 0) == 0; }),
            names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), std::string(100, 'x') + "_refined.stl"),
            names.end())
      << ::testing::PrintToString(names);
}

}  // namespace
}  // namespace stlrefine::test

namespace stlrefine::test {
namespace {

// A 3MF refined to STL is read at submit (its objects may be parts): that reading is
// reserved in the memory budget first, as a zip's parts are, not done on an HTTP worker
// outside it. A package whose model inflates past the budget is refused before it is read.
TEST(JobParts, A3mfReadPastTheMemoryBudgetIsRefusedBeforeReading) {
  const auto dir = fresh_job_dir("3mf-memory");
  server::DaemonConfig config = jobs_config(dir);
  config.memory_budget = std::uint64_t{128} << 20;  // 64 MiB for work beside the daemon's 64
  InProcessDaemon d(config);
  httplib::Client c = d.client();
  std::string noise(1 << 20, '\0');
  std::uint32_t x = 54321;
  for (char& ch : noise) ch = static_cast<char>((x = x * 1103515245u + 12345u) >> 24);
  auto r = c.Post("/v1/jobs?levels=1", raw_zip({{"3D/3dmodel.model", noise, false, 80u << 20}}),
                  "model/3mf");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 422) << r->body;
  const Json p = Json::parse(r->body);
  EXPECT_EQ(p.value("reason", ""), "memory_budget") << r->body;
  EXPECT_EQ(p.value("field", ""), "file");
  // A 3MF that fits is read and planned as before, its reservation given back.
  auto ok = c.Post("/v1/jobs?levels=1", three_mf({{"a", box(5)}, {"b", box(5, 10)}}), "model/3mf");
  ASSERT_TRUE(ok);
  ASSERT_EQ(ok->status, 202) << ok->body;
  EXPECT_EQ(wait_job(c, ok->get_header_value("Location"))["state"], "done");
}

}  // namespace
}  // namespace stlrefine::test
