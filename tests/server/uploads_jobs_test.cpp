// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 19 items 3 and 4 against the daemon on an ephemeral loopback port: multipart
// uploads and their limits, the upload's name on every download and in the contours, the
// job list, honest progress, server-sent events and signed callbacks.

#include <gtest/gtest.h>
#include <httplib.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <array>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "http_test_client.h"
#include "in_process_daemon.h"
#include "server/daemon.h"
#include "server/http.h"
#include "server/http_upload.h"
#include "server/job_callbacks.h"
#include "test_stl.h"

namespace stlrefine::server {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr const char* kBoundary = "----stlrefine-test-boundary";

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-uploads-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

DaemonConfig config_with_jobs(const fs::path& dir) {
  DaemonConfig config;
  config.compute_slots = 2;
  config.http_threads = 8;
  config.max_faces = 4'000'000;
  config.jobs.data_dir = dir;
  config.jobs.max_queued = 8;
  config.shutdown_grace = 5s;
  return config;
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

struct Part {
  std::string name;      // the form field
  std::string filename;  // empty: a plain field
  std::string content;
};

std::string form(const std::vector<Part>& parts, bool close = true) {
  std::string body;
  for (const Part& p : parts) {
    body.append("--").append(kBoundary).append("\r\n");
    body.append("Content-Disposition: form-data; name=\"").append(p.name).append("\"");
    if (!p.filename.empty()) body.append("; filename=\"").append(p.filename).append("\"");
    body.append("\r\nContent-Type: application/octet-stream\r\n\r\n");
    body.append(p.content).append("\r\n");
  }
  if (close) body.append("--").append(kBoundary).append("--\r\n");
  return body;
}

std::string form_type() {
  return std::string("multipart/form-data; boundary=") + kBoundary;
}

httplib::Result post_form(httplib::Client& c, const std::string& target, const std::string& body) {
  return c.Post(target.c_str(), body, form_type().c_str());
}

std::string problem_field(const httplib::Result& r) {
  return Json::parse(r->body).value("field", "");
}

Json wait_done(httplib::Client& c, const std::string& location) {
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  Json job;
  while (std::chrono::steady_clock::now() < deadline) {
    auto r = c.Get(location.c_str());
    if (r && r->status == 200) {
      job = Json::parse(r->body);
      const std::string state = job["state"];
      if (state == "done" || state == "failed" || state == "cancelled") return job;
    }
    std::this_thread::sleep_for(20ms);
  }
  ADD_FAILURE() << "job did not end: " << job.dump();
  return job;
}

TEST(Uploads, MultipartGivesTheBytesOfARawBodyAndTheNameOnTheDownload) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto raw = c.Post("/v1/refine?scheme=butterfly&levels=1", octahedron(), "model/stl");
  ASSERT_TRUE(raw);
  ASSERT_EQ(raw->status, 200);
  EXPECT_EQ(raw->get_header_value("Content-Disposition"),
            "attachment; filename=\"part_refined.stl\"");
  auto multi = post_form(c, "/v1/refine?scheme=butterfly&levels=1",
                         form({{"file", "housing.stl", octahedron()}}));
  ASSERT_TRUE(multi);
  ASSERT_EQ(multi->status, 200) << multi->body;
  EXPECT_EQ(multi->body, raw->body);
  EXPECT_EQ(multi->get_header_value("Content-Disposition"),
            "attachment; filename=\"housing_refined.stl\"");

  // Refine + slice: the zip is named by what is sent.
  auto zip = post_form(c, "/v1/refine?levels=1&slice=0.5&slice_format=cli",
                       form({{"file", "housing.stl", octahedron()}}));
  ASSERT_TRUE(zip);
  ASSERT_EQ(zip->status, 200) << zip->body;
  EXPECT_EQ(zip->get_header_value("Content-Disposition"),
            "attachment; filename=\"housing_refined.zip\"");

  // A raw body names itself with Content-Disposition.
  auto named = c.Post("/v1/refine?levels=1",
                      {{"Content-Disposition", "attachment; filename=\"bracket v2.stl\""}},
                      octahedron(), "model/stl");
  ASSERT_TRUE(named);
  EXPECT_EQ(named->get_header_value("Content-Disposition"),
            "attachment; filename=\"bracket v2_refined.stl\"");

  // Or with filename= in the query; a form's own name wins over it.
  auto by_query = c.Post("/v1/refine?levels=1&filename=clip.stl", octahedron(), "model/stl");
  ASSERT_TRUE(by_query);
  ASSERT_EQ(by_query->status, 200) << by_query->body;
  EXPECT_EQ(by_query->get_header_value("Content-Disposition"),
            "attachment; filename=\"clip_refined.stl\"");
  auto form_wins = post_form(c, "/v1/refine?levels=1&filename=clip.stl",
                             form({{"file", "housing.stl", octahedron()}}));
  ASSERT_TRUE(form_wins);
  EXPECT_EQ(form_wins->get_header_value("Content-Disposition"),
            "attachment; filename=\"housing_refined.stl\"");
  auto twice =
      c.Post("/v1/refine?levels=1&filename=a.stl&filename=b.stl", octahedron(), "model/stl");
  ASSERT_TRUE(twice);
  EXPECT_EQ(twice->status, 400);
  EXPECT_EQ(problem_field(twice), "filename");

  // Slices: the name on the file and as the contours' label.
  auto cli = post_form(c, "/v1/slice?layer_height=0.25&format=cli",
                       form({{"file", "housing.stl", octahedron()}}));
  ASSERT_TRUE(cli);
  ASSERT_EQ(cli->status, 200) << cli->body;
  EXPECT_EQ(cli->get_header_value("Content-Disposition"),
            "attachment; filename=\"housing_slices.cli\"");
  EXPECT_NE(cli->body.find("$$LABEL/1,housing\n"), std::string::npos) << cli->body.substr(0, 200);
  auto svg = post_form(c, "/v1/slice?layer_height=0.25&format=svg",
                       form({{"file", "housing.stl", octahedron()}}));
  ASSERT_TRUE(svg);
  EXPECT_NE(svg->body.find("<title>housing: "), std::string::npos);

  // info takes a form too.
  auto info = post_form(c, "/v1/info", form({{"file", "housing.stl", octahedron()}}));
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, 200) << info->body;
}

TEST(Uploads, MalformedFormsAre400NamingTheField) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  const std::string target = "/v1/refine?levels=1";

  auto none = post_form(c, target, form({{"other", "", "x"}}));
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 400);
  EXPECT_EQ(problem_field(none), "other");  // a form field is not a parameter

  auto missing = post_form(c, target, form({}));
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 400);
  EXPECT_EQ(problem_field(missing), "file");

  auto two = post_form(c, target, form({{"file", "a.stl", octahedron()}, {"file", "b.stl", "x"}}));
  ASSERT_TRUE(two);
  EXPECT_EQ(two->status, 400);
  EXPECT_EQ(problem_field(two), "file");
  EXPECT_NE(two->body.find("more than one"), std::string::npos);

  auto second_file = post_form(
      c, target, form({{"file", "a.stl", octahedron()}, {"extra", "b.stl", octahedron()}}));
  ASSERT_TRUE(second_file);
  EXPECT_EQ(second_file->status, 400);
  EXPECT_EQ(problem_field(second_file), "extra");

  // A boundary that never closes: refused at once (the body is Content-Length framed).
  const auto start = std::chrono::steady_clock::now();
  auto open = post_form(c, target, form({{"file", "a.stl", octahedron()}}, false));
  ASSERT_TRUE(open);
  EXPECT_EQ(open->status, 400);
  EXPECT_EQ(Json::parse(open->body)["reason"], "unterminated_multipart");
  EXPECT_LT(std::chrono::steady_clock::now() - start, 5s);
  std::string cut = form({{"file", "a.stl", octahedron()}});
  cut.resize(cut.size() / 2);
  auto truncated = post_form(c, target, cut);
  ASSERT_TRUE(truncated);
  EXPECT_EQ(truncated->status, 400);

  // No boundary: refused before the upload.
  auto no_boundary =
      c.Post(target.c_str(), form({{"file", "a.stl", octahedron()}}), "multipart/form-data");
  ASSERT_TRUE(no_boundary);
  EXPECT_EQ(no_boundary->status, 400);
  EXPECT_EQ(problem_field(no_boundary), "Content-Type");
  const std::string raw_no_boundary = test::exchange(
      d.port(), test::post_text(target, "multipart/form-data; charset=x", std::string(100, 'x'),
                                "Expect: 100-continue\r\n", true));
  EXPECT_EQ(raw_no_boundary.rfind("HTTP/1.1 400", 0), 0u) << raw_no_boundary.substr(0, 200);

  // The multipart overhead counts against the same payload limit.
  DaemonConfig small;
  small.compute_slots = 1;
  small.max_body_bytes = octahedron().size() + 10;
  test::InProcessDaemon s(small);
  httplib::Client sc = s.client();
  auto raw_fits = sc.Post(target.c_str(), octahedron(), "model/stl");
  ASSERT_TRUE(raw_fits);
  EXPECT_EQ(raw_fits->status, 200);
  auto too_large = post_form(sc, target, form({{"file", "a.stl", octahedron()}}));
  ASSERT_TRUE(too_large);
  EXPECT_EQ(too_large->status, 413);
}

TEST(Uploads, HostileNamesAreSanitisedNeverReflected) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  const std::vector<std::string> hostile = {
      "../../etc/passwd.stl",
      "C:\\Users\\x\\evil\";rm -rf.stl",
      std::string("a\rb\nc") + "\".stl",
      std::string(1 << 20, 'n') + ".stl",
      "\xc3\xa9t\xc3\xa9 part.stl",
      "\xff\xfe\x80 bad utf8.stl",
      "%0d%0aSet-Cookie: x.stl",
  };
  for (const std::string& name : hostile) {
    // Quotes and CR/LF inside a part's quoted name would break our own form: escaped as a
    // browser does, except the raw bytes we want to reach the parser.
    std::string quoted;
    for (char ch : name) {
      if (ch == '"')
        quoted += "\\\"";
      else
        quoted += ch;
    }
    std::string body = std::string("--") + kBoundary +
                       "\r\nContent-Disposition: form-data; name=\"file\"; filename=\"" + quoted +
                       "\"\r\n\r\n" + octahedron() + "\r\n--" + kBoundary + "--\r\n";
    // Read raw: httplib's client percent-decodes header values.
    const std::vector<test::RawResponse> answers = test::parse_responses(
        test::exchange(d.port(), test::post_text("/v1/refine?levels=1", form_type(), body), 30s));
    ASSERT_EQ(answers.size(), 1u) << name.substr(0, 40);
    const test::RawResponse* r = &answers[0];
    if (name.find_first_of("\r\n") != std::string::npos) {
      // A CR or LF ends the part's header line: the form is malformed, or the name is cut.
      EXPECT_TRUE(r->status == 400 || r->status == 200) << r->status;
      if (r->status != 200) continue;
    }
    ASSERT_EQ(r->status, 200) << name.substr(0, 40) << ": " << r->body.substr(0, 300);
    const std::string cd = r->header("content-disposition");
    EXPECT_LT(cd.size(), 1000u);
    EXPECT_EQ(cd.rfind("attachment; filename=\"", 0), 0u) << cd;
    const std::size_t open = cd.find('"');
    const std::size_t close = cd.find('"', open + 1);
    ASSERT_NE(close, std::string::npos) << cd;
    const std::string ascii = cd.substr(open + 1, close - open - 1);
    EXPECT_EQ(ascii.find_first_of("/\\\"\r\n;%"), std::string::npos) << ascii;
    for (char ch : cd) EXPECT_TRUE(ch >= 0x20 && ch < 0x7f) << cd;
    EXPECT_TRUE(ascii.ends_with("_refined.stl")) << ascii;
    // After the quoted name: only the RFC 6266 extended form, when the name is not ASCII.
    const std::string rest = cd.substr(close + 1);
    EXPECT_TRUE(rest.empty() || rest.rfind("; filename*=UTF-8''", 0) == 0) << rest;
  }
  // UTF-8 survives in filename*.
  const std::vector<test::RawResponse> utf8 = test::parse_responses(test::exchange(
      d.port(), test::post_text("/v1/refine?levels=1", form_type(),
                                form({{"file", "\xc3\xa9t\xc3\xa9.stl", octahedron()}}))));
  ASSERT_EQ(utf8.size(), 1u);
  EXPECT_EQ(utf8[0].header("content-disposition"),
            "attachment; filename=\"_t__refined.stl\"; filename*=UTF-8''%C3%A9t%C3%A9_refined.stl");
}

TEST(Uploads, MangledFormsNeverCrashAndNeverReadOutsideTheBody) {
  // Every cut and a few thousand random byte edits of a valid form: read_upload answers a
  // 400 or a file that lies inside the body, never more (run under the asan preset too).
  const std::string valid = form({{"file", "part.stl", octahedron()}});
  std::mt19937 random(19);
  auto check = [](const std::string& body) {
    HttpRequest req;
    req.method = "POST";
    req.target = "/v1/refine";
    req.headers.emplace("Content-Type", form_type());
    req.body = body;
    Upload upload;
    const std::optional<api::Problem> problem = read_upload(req, upload);
    if (problem) {
      EXPECT_EQ(problem->status, 400);
      EXPECT_FALSE(problem->field.empty());
      return;
    }
    EXPECT_GE(upload.bytes.data(), body.data());
    EXPECT_LE(upload.bytes.data() + upload.bytes.size(), body.data() + body.size());
  };
  for (std::size_t cut = 0; cut < valid.size(); cut += 7) check(valid.substr(0, cut));
  for (int i = 0; i < 3000; ++i) {
    std::string body = valid;
    const int edits = 1 + static_cast<int>(random() % 4);
    for (int e = 0; e < edits; ++e) {
      // Mostly near the framing (the first and last 200 bytes), where the parser looks.
      const std::size_t at = random() % 2 ? random() % 200 : body.size() - 1 - random() % 200;
      body[at] = "\r\n-\"; =ab"[random() % 10];
    }
    check(body);
  }
}

TEST(JobsList, CallersJobsNewestFirstPagedAndFiltered) {
  const fs::path dir = fresh_dir("list");
  DaemonConfig config = config_with_jobs(dir);
  config.api_keys = {"0123456789abcdef-key-one", "fedcba9876543210-key-two"};
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  const httplib::Headers one = {{"Authorization", "Bearer 0123456789abcdef-key-one"}};
  const httplib::Headers two = {{"Authorization", "Bearer fedcba9876543210-key-two"}};
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    std::string name = std::to_string(i);
    name.insert(0, 1, 'p').append(".stl");
    auto r =
        c.Post("/v1/jobs?levels=1", one, form({{"file", name, octahedron()}}), form_type().c_str());
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202) << r->body;
    ids.push_back(Json::parse(r->body)["id"]);
    std::this_thread::sleep_for(5ms);  // distinct creation times
  }
  auto other = c.Post("/v1/jobs?levels=1", two, octahedron(), "model/stl");
  ASSERT_TRUE(other);
  ASSERT_EQ(other->status, 202);
  httplib::Client c1 = d.client();
  c1.set_default_headers(one);
  for (const std::string& id : ids) wait_done(c1, "/v1/jobs/" + id);

  auto page1 = c.Get("/v1/jobs?limit=2", one);
  ASSERT_TRUE(page1);
  ASSERT_EQ(page1->status, 200) << page1->body;
  const Json p1 = Json::parse(page1->body);
  ASSERT_EQ(p1["jobs"].size(), 2u);
  EXPECT_EQ(p1["jobs"][0]["id"], ids[2]);
  EXPECT_EQ(p1["jobs"][1]["id"], ids[1]);
  EXPECT_EQ(p1["jobs"][0]["name"], "p2.stl");
  ASSERT_TRUE(p1["links"].contains("next"));
  auto page2 = c.Get(p1["links"]["next"].get<std::string>().c_str(), one);
  ASSERT_TRUE(page2);
  const Json p2 = Json::parse(page2->body);
  ASSERT_EQ(p2["jobs"].size(), 1u);
  EXPECT_EQ(p2["jobs"][0]["id"], ids[0]);
  EXPECT_FALSE(p2["links"].contains("next"));

  // Tenant-scoped: the other key sees only its own job.
  auto theirs = c.Get("/v1/jobs", two);
  ASSERT_TRUE(theirs);
  const Json t = Json::parse(theirs->body);
  ASSERT_EQ(t["jobs"].size(), 1u);
  EXPECT_EQ(t["jobs"][0]["id"], Json::parse(other->body)["id"]);

  auto done = c.Get("/v1/jobs?state=done&limit=100", one);
  ASSERT_TRUE(done);
  EXPECT_EQ(Json::parse(done->body)["jobs"].size(), 3u);
  auto queued = c.Get("/v1/jobs?state=queued", one);
  ASSERT_TRUE(queued);
  EXPECT_EQ(Json::parse(queued->body)["jobs"].size(), 0u);

  for (const auto& [query, field] :
       std::vector<std::pair<std::string, std::string>>{{"limit=0", "limit"},
                                                        {"limit=101", "limit"},
                                                        {"limit=ten", "limit"},
                                                        {"state=finished", "state"},
                                                        {"cursor=abc", "cursor"},
                                                        {"cursor=1-zz", "cursor"},
                                                        {"limit=1&limit=2", "limit"},
                                                        {"sort=asc", "sort"}}) {
    auto r = c.Get(("/v1/jobs?" + query).c_str(), one);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << query;
    EXPECT_EQ(problem_field(r), field) << query << " " << r->body;
  }
  auto unauthorized = c.Get("/v1/jobs");
  ASSERT_TRUE(unauthorized);
  EXPECT_EQ(unauthorized->status, 401);
}

TEST(JobsProgress, NeverGoesBackwardsAndDoneMeansTheResultDownloads) {
  const fs::path dir = fresh_dir("progress");
  test::InProcessDaemon d(config_with_jobs(dir));
  httplib::Client c = d.client();
  auto r = post_form(c, "/v1/jobs?scheme=butterfly&levels=3&slice=0.02&slice_format=cli",
                     form({{"file", "fandisk.stl", fandisk()}}));
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string location = r->get_header_value("Location");
  double last = 0;
  std::set<std::string> stages;
  int running_samples = 0;
  const auto deadline = std::chrono::steady_clock::now() + 120s;
  Json job;
  while (std::chrono::steady_clock::now() < deadline) {
    auto g = c.Get(location.c_str());
    ASSERT_TRUE(g);
    job = Json::parse(g->body);
    const double progress = job["progress"];
    EXPECT_GE(progress, last) << job.dump();
    last = progress;
    const std::string state = job["state"], stage = job["stage"];
    EXPECT_NE(stage, "done");
    stages.insert(stage);
    if (state == "running") {
      ++running_samples;
      EXPECT_LT(progress, 1.0);
    }
    if (state == "done") {
      // done means downloadable, at once.
      auto stl = c.Get((location + "/result.stl").c_str());
      ASSERT_TRUE(stl);
      EXPECT_EQ(stl->status, 200);
      EXPECT_EQ(stl->get_header_value("Content-Disposition"),
                "attachment; filename=\"fandisk_refined.stl\"");
      auto cli = c.Get((location + "/contours.cli").c_str());
      ASSERT_TRUE(cli);
      EXPECT_EQ(cli->status, 200);
      EXPECT_EQ(cli->get_header_value("Content-Disposition"),
                "attachment; filename=\"fandisk_slices.cli\"");
      EXPECT_NE(cli->body.find("$$LABEL/1,fandisk\n"), std::string::npos);
      break;
    }
    ASSERT_TRUE(state == "queued" || state == "running") << job.dump();
    std::this_thread::sleep_for(5ms);
  }
  ASSERT_EQ(job["state"], "done") << job.dump();
  EXPECT_EQ(job["progress"], 1.0);
  EXPECT_EQ(job["eta_seconds"], 0);
  EXPECT_EQ(job["name"], "fandisk.stl");
  EXPECT_GE(running_samples, 3);
  EXPECT_TRUE(stages.count("slicing") || stages.count("writing")) << Json(stages).dump();
}

// The events of a stream: (name, data) pairs.
std::vector<std::pair<std::string, std::string>> parse_events(const std::string& text) {
  std::vector<std::pair<std::string, std::string>> events;
  std::string name, data;
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t eol = text.find('\n', at);
    if (eol == std::string::npos) break;
    const std::string line = text.substr(at, eol - at);
    at = eol + 1;
    if (line.empty()) {
      if (!name.empty() || !data.empty()) events.emplace_back(name, data);
      name.clear();
      data.clear();
    } else if (line.rfind("event: ", 0) == 0) {
      name = line.substr(7);
    } else if (line.rfind("data: ", 0) == 0) {
      data = line.substr(6);
    }
  }
  return events;
}

TEST(JobEvents, StreamProgressThenTheFinalJobAndEnd) {
  const fs::path dir = fresh_dir("events");
  test::InProcessDaemon d(config_with_jobs(dir));
  httplib::Client c = d.client();
  auto r = post_form(c, "/v1/jobs?scheme=butterfly&levels=3&slice=0.05&slice_format=svg",
                     form({{"file", "fandisk.stl", fandisk()}}));
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202);
  const std::string location = r->get_header_value("Location");
  test::RawConnection conn(d.port());
  ASSERT_TRUE(conn.send("GET " + location + "/events HTTP/1.1\r\nHost: x\r\n\r\n"));
  const std::string all = conn.read_all(120s);
  EXPECT_TRUE(conn.closed());  // the stream ends when the job does
  const std::size_t head_end = all.find("\r\n\r\n");
  ASSERT_NE(head_end, std::string::npos);
  const std::string head = all.substr(0, head_end);
  EXPECT_EQ(head.rfind("HTTP/1.1 200", 0), 0u) << head;
  EXPECT_NE(head.find("Content-Type: text/event-stream"), std::string::npos) << head;
  EXPECT_EQ(head.find("Content-Length"), std::string::npos) << head;
  const auto events = parse_events(all.substr(head_end + 4));
  ASSERT_GE(events.size(), 2u) << all;
  double last = 0;
  for (std::size_t i = 0; i + 1 < events.size(); ++i) {
    EXPECT_EQ(events[i].first, "progress");
    const Json j = Json::parse(events[i].second);
    EXPECT_GE(j["progress"].get<double>(), last);
    last = j["progress"];
    EXPECT_NE(j["state"], "done");
  }
  EXPECT_EQ(events.back().first, "end");
  const Json final_job = Json::parse(events.back().second);
  EXPECT_EQ(final_job["state"], "done");
  EXPECT_EQ(final_job["name"], "fandisk.stl");
  auto svg = c.Get((location + "/contours.svg").c_str());
  ASSERT_TRUE(svg);
  EXPECT_EQ(svg->status, 200);

  // A job already ended: one end event at once. An unknown job: 404.
  test::RawConnection again(d.port());
  ASSERT_TRUE(again.send("GET " + location + "/events HTTP/1.1\r\nHost: x\r\n\r\n"));
  const std::string once = again.read_all(10s);
  const auto one_event = parse_events(once.substr(once.find("\r\n\r\n") + 4));
  ASSERT_EQ(one_event.size(), 1u) << once;
  EXPECT_EQ(one_event[0].first, "end");
  auto unknown = c.Get("/v1/jobs/0123456789abcdef0123456789abcdef/events");
  ASSERT_TRUE(unknown);
  EXPECT_EQ(unknown->status, 404);
}

TEST(JobEvents, StreamsHoldNoWorker) {
  // One HTTP worker: event streams waiting on a long job (and a client that never reads)
  // leave it free for every other request.
  const fs::path dir = fresh_dir("events-workers");
  DaemonConfig config = config_with_jobs(dir);
  config.http_threads = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = c.Post("/v1/jobs?scheme=butterfly&levels=4", fandisk(), "model/stl");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202);
  const std::string location = r->get_header_value("Location");
  std::vector<std::unique_ptr<test::RawConnection>> streams;
  for (int i = 0; i < 4; ++i) {
    streams.push_back(std::make_unique<test::RawConnection>(d.port()));
    ASSERT_TRUE(streams.back()->send("GET " + location + "/events HTTP/1.1\r\nHost: x\r\n\r\n"));
  }
  std::this_thread::sleep_for(300ms);
  for (int i = 0; i < 5; ++i) {
    const auto start = std::chrono::steady_clock::now();
    auto g = c.Get(location.c_str());
    ASSERT_TRUE(g);
    EXPECT_EQ(g->status, 200);
    EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);
  }
  // Every stream still gets its end.
  for (auto& s : streams) {
    const std::string text = s->read_all(120s);
    EXPECT_NE(text.find("event: end"), std::string::npos) << text.substr(0, 300);
  }
}

std::string percent_encoded(const std::string& text) {
  std::string out;
  char hex[4];
  for (unsigned char ch : text) {
    if (std::isalnum(ch) || ch == '/' || ch == ':' || ch == '.' || ch == '-') {
      out.push_back(static_cast<char>(ch));
    } else {
      std::snprintf(hex, sizeof hex, "%%%02X", ch);
      out += hex;
    }
  }
  return out;
}

std::string hmac_hex(const std::string& key, const std::string& body) {
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()),
       reinterpret_cast<const unsigned char*>(body.data()), body.size(), mac, &size);
  std::string out;
  char hex[3];
  for (unsigned int i = 0; i < size; ++i) {
    std::snprintf(hex, sizeof hex, "%02x", mac[i]);
    out += hex;
  }
  return out;
}

TEST(JobCallbacks, SignedPostRetriedUntilAcceptedOnlyToAllowedHosts) {
  // The receiver: refuses the first delivery (500), accepts the second.
  httplib::Server receiver;
  std::mutex mutex;
  std::vector<std::array<std::string, 3>> received;  // body, signature, timestamp
  receiver.Post("/hook", [&](const httplib::Request& req, httplib::Response& res) {
    std::lock_guard lock(mutex);
    received.push_back({req.body, req.get_header_value("X-Stlrefine-Signature"),
                        req.get_header_value("X-Stlrefine-Timestamp")});
    res.status = received.size() == 1 ? 500 : 204;
  });
  const int port = receiver.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { receiver.listen_after_bind(); });

  const fs::path dir = fresh_dir("callbacks");
  DaemonConfig config = config_with_jobs(dir);
  const std::string secret = "callback-secret-for-the-test";
  config.jobs.callbacks.secret = secret;
  config.jobs.callbacks.allow = {"127.0.0.1:" + std::to_string(port), "localhost"};
  config.jobs.callbacks.backoff = 50ms;
  {
    test::InProcessDaemon d(config);
    httplib::Client c = d.client();
    const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/hook";
    auto r = c.Post(("/v1/jobs?levels=1&callback_url=" + url).c_str(), octahedron(), "model/stl");
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202) << r->body;
    EXPECT_EQ(Json::parse(r->body)["callback_url"], url);
    const Json done = wait_done(c, r->get_header_value("Location"));
    EXPECT_EQ(done["state"], "done");
    const auto until = std::chrono::steady_clock::now() + 20s;
    while (std::chrono::steady_clock::now() < until) {
      {
        std::lock_guard lock(mutex);
        if (received.size() >= 2) break;
      }
      std::this_thread::sleep_for(20ms);
    }
    {
      std::lock_guard lock(mutex);
      ASSERT_EQ(received.size(), 2u);  // refused once, then delivered; not again
      // Signed under the tenant's key (the keyless tenant here), over "timestamp.body".
      const std::string key = callback_key_of_api_key(dir, secret, "");
      EXPECT_EQ(key, hmac_hex(secret, ""));  // the keyless daemon's one tenant id: ""
      for (const auto& [body, signature, timestamp] : received) {
        EXPECT_EQ(signature, "sha256=" + hmac_hex(key, timestamp + "." + body));
        EXPECT_NEAR(std::stod(timestamp), static_cast<double>(std::time(nullptr)), 30.0);
        const Json j = Json::parse(body);
        EXPECT_EQ(j["id"], done["id"]);
        EXPECT_EQ(j["state"], "done");
      }
    }

    // Refused at submit, naming callback_url: not on the list, another port, a name that
    // resolves to loopback (allowed only as an address), not http, credentials, twice.
    for (const std::string& bad : std::vector<std::string>{
             "http://127.0.0.1:" + std::to_string(port + 1) + "/hook",
             "http://localhost:" + std::to_string(port) + "/hook", "http://169.254.169.254/latest",
             "ftp://127.0.0.1:" + std::to_string(port) + "/",
             "http://u:p@127.0.0.1:" + std::to_string(port) + "/", "not a url"}) {
      auto refused = c.Post(("/v1/jobs?levels=1&callback_url=" + percent_encoded(bad)).c_str(),
                            octahedron(), "model/stl");
      ASSERT_TRUE(refused);
      EXPECT_EQ(refused->status, 400) << bad << " " << refused->body;
      EXPECT_EQ(problem_field(refused), "callback_url") << bad;
    }
    auto twice = c.Post(("/v1/jobs?levels=1&callback_url=" + url + "&callback_url=" + url).c_str(),
                        octahedron(), "model/stl");
    ASSERT_TRUE(twice);
    EXPECT_EQ(twice->status, 400);
  }
  // A server without a secret or an allow-list takes no callback.
  {
    test::InProcessDaemon plain(config_with_jobs(fresh_dir("no-callbacks")));
    httplib::Client c = plain.client();
    auto r =
        c.Post(("/v1/jobs?levels=1&callback_url=http://127.0.0.1:" + std::to_string(port) + "/hook")
                   .c_str(),
               octahedron(), "model/stl");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400);
    EXPECT_EQ(problem_field(r), "callback_url");
  }
  receiver.stop();
  serving.join();
}

}  // namespace
}  // namespace stlrefine::server
