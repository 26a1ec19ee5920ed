// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The daemon on an ephemeral loopback port, in process (cpp-httplib's own ServerTest
// pattern): every hardening case answers the right status with a problem+json body, and a
// good request right after it still gets byte-identical output.

#include "server/daemon.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "api/params.h"
#include "api/pipeline.h"
#include "http_test_client.h"
#include "server/front_end.h"
#include "test_stl.h"

namespace stlrefine::server {
namespace {

using namespace std::chrono_literals;
using test::RawResponse;

constexpr std::size_t kMaxBody = 256 * 1024;
constexpr std::uint64_t kMaxFaces = 100'000;
constexpr const char* kGoodTarget = "/v1/refine?scheme=butterfly&levels=2&crease_angle=35";

class DaemonTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::signal(SIGPIPE, SIG_IGN);
    DaemonConfig config;
    config.compute_slots = 2;
    config.http_threads = 8;
    config.max_body_bytes = kMaxBody;
    config.max_faces = kMaxFaces;
    config.read_timeout = 2s;
    config.write_timeout = 5s;
    config.retry_after_seconds = 3;
    config.test_hook = [](std::string_view route) {
      if (throw_in_handler_.exchange(false))
        throw std::runtime_error("secret-4711 in " + std::string(route));
    };
    daemon_ = std::make_unique<Daemon>(config);
    port_ = daemon_->bind("127.0.0.1", 0);
    thread_ = std::thread([] { daemon_->run(); });

    httplib::Client client("127.0.0.1", port_);
    for (int i = 0; i < 200; ++i) {
      if (auto r = client.Get("/healthz"); r && r->status == 200) break;
      std::this_thread::sleep_for(10ms);
    }
    input_ = test::binary_stl(test::octahedron_triangles());
    const RawResponse first = request(test::post_text(kGoodTarget, "model/stl", input_));
    ASSERT_EQ(first.status, 200) << first.body;
    reference_ = first.body;
  }

  static void TearDownTestSuite() {
    daemon_->stop();
    thread_.join();
    daemon_.reset();
  }

  //! Sends raw bytes on a fresh connection; expects exactly one response, then a close.
  static RawResponse request(std::string_view raw) {
    test::RawConnection c(port_);
    c.send(raw);
    const std::string answer = c.read_all(5s);
    EXPECT_TRUE(c.closed()) << "the server kept the connection open";
    const std::vector<RawResponse> responses = test::parse_responses(answer);
    EXPECT_EQ(responses.size(), 1u) << answer.substr(0, 400);
    return responses.empty() ? RawResponse{} : responses.front();
  }

  //! A problem+json answer with this status and type; returns the body.
  static nlohmann::json expect_problem(const RawResponse& r, int status, const std::string& slug) {
    EXPECT_EQ(r.status, status) << r.body;
    EXPECT_EQ(r.header("content-type"), "application/problem+json");
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(r.body);
    } catch (const std::exception& e) {
      ADD_FAILURE() << "not JSON: " << r.body;
      return j;
    }
    EXPECT_EQ(j.value("type", ""), "urn:stlrefine:problem:" + slug) << r.body;
    EXPECT_EQ(j.value("status", 0), status);
    EXPECT_TRUE(j.contains("title"));
    EXPECT_TRUE(j.contains("detail"));
    return j;
  }

  static void expect_good_request_still_works() {
    const RawResponse r = request(test::post_text(kGoodTarget, "model/stl", input_));
    EXPECT_EQ(r.status, 200);
    EXPECT_TRUE(r.body == reference_) << "output differs from the first good request";
  }

  static std::string refine_target(const std::string& query) { return "/v1/refine?" + query; }

  static inline std::unique_ptr<Daemon> daemon_;
  static inline std::thread thread_;
  static inline int port_ = 0;
  static inline std::string input_, reference_;
  static inline std::atomic<bool> throw_in_handler_{false};
};

// --- success paths

TEST_F(DaemonTest, AStreamedStlAnswerIsTheBytesRunRefineWrites) {
  // 8 * 4^6 faces: 1.6 MB of STL, made from the mesh and sent in several pieces.
  const std::string query = "scheme=butterfly&levels=6";
  const RawResponse r = request(test::post_text(refine_target(query), "model/stl", input_));
  ASSERT_EQ(r.status, 200) << r.body;
  const auto bytes = std::span(reinterpret_cast<const std::uint8_t*>(input_.data()), input_.size());
  const api::RefineOutcome expected =
      api::run_refine(bytes, api::parse_refine_params(api::parse_query(query), {}));
  ASSERT_GT(expected.stl.size(), 4 * FrontEnd::kMadePiece);
  EXPECT_EQ(r.header("content-length"), std::to_string(expected.stl.size()));
  EXPECT_TRUE(r.body == expected.stl) << "the streamed answer differs from write_stl's bytes";
}

TEST_F(DaemonTest, RefineAnswersBinaryStlWithTheReportHeader) {
  httplib::Client client("127.0.0.1", port_);
  auto r = client.Post(kGoodTarget, input_, "model/stl");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), "model/stl");
  const auto input = test::octahedron_triangles();
  const auto output = test::read_binary_stl(r->body);
  EXPECT_EQ(output.size(), input.size() * 16);  // 4^levels
  EXPECT_TRUE(test::corners_preserved(input, output));
  EXPECT_EQ(r->body, reference_);

  const auto report = nlohmann::json::parse(r->get_header_value("X-Stlrefine-Report"));
  EXPECT_EQ(report.at("scheme"), "butterfly");
  EXPECT_EQ(report.at("levels"), 2);
  EXPECT_EQ(report.at("input").at("faces"), 8);
  EXPECT_EQ(report.at("output").at("faces"), 128);
  EXPECT_EQ(report.at("max_input_displacement"), 0.0);
  EXPECT_TRUE(report.contains("ingest"));
}

TEST_F(DaemonTest, OctetStreamAndMediaTypeParametersAreAccepted) {
  EXPECT_EQ(request(test::post_text(kGoodTarget, "application/octet-stream", input_)).body,
            reference_);
  EXPECT_EQ(request(test::post_text(kGoodTarget, "Model/STL; charset=binary", input_)).body,
            reference_);
}

TEST_F(DaemonTest, InfoAnswersTheJsonReport) {
  httplib::Client client("127.0.0.1", port_);
  auto r = client.Post("/v1/info?crease_angle=80", input_, "model/stl");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
  const auto j = nlohmann::json::parse(r->body);
  EXPECT_EQ(j.at("mesh").at("faces"), 8);
  EXPECT_EQ(j.at("mesh").at("watertight"), true);
  EXPECT_EQ(j.at("features").at("crease_angle_deg"), 80.0);
  EXPECT_EQ(j.at("features").at("sharp_edges"), 0);
}

TEST_F(DaemonTest, HealthAndReadiness) {
  RawResponse r = request("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(nlohmann::json::parse(r.body).at("status"), "ok");
  r = request("GET /readyz HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(nlohmann::json::parse(r.body).at("compute_slots"), 2);
  r = request("HEAD /healthz HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(r.status, 200);
}

// --- 400: parameters

TEST_F(DaemonTest, BadParametersNameTheField) {
  struct Case {
    std::string query, field, reason;
  };
  const Case cases[] = {
      {"scheme=catmull-clark", "scheme", "unknown_scheme"},
      {"levels=9", "levels", "out_of_range"},
      {"levels=abc", "levels", "not_a_number"},
      {"levels=2x", "levels", "not_a_number"},
      {"levels=", "levels", "not_a_number"},
      {"crease_angle=nan", "crease_angle", "not_a_number"},
      {"crease_angle=1e400", "crease_angle", "out_of_range"},
      {"crease_angle=200", "crease_angle", "out_of_range"},
      {"colour=red", "colour", "unknown_parameter"},
      {"threads=4", "threads", "unknown_parameter"},
      {"levels=1&levels=2", "levels", "duplicate_parameter"},
      {"max_faces=100001", "max_faces", "above_server_cap"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.query);
    const auto j =
        expect_problem(request(test::post_text(refine_target(c.query), "model/stl", input_)), 400,
                       "invalid-parameter");
    EXPECT_EQ(j.value("field", ""), c.field);
    EXPECT_EQ(j.value("reason", ""), c.reason);
  }
  const auto j = expect_problem(request(test::post_text("/v1/info?levels=2", "model/stl", input_)),
                                400, "invalid-parameter");
  EXPECT_EQ(j.value("field", ""), "levels");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, BadParametersAreRejectedBeforeTheUpload) {
  // Asked first (Expect: 100-continue): refused before a byte of the body is sent.
  test::RawConnection c(port_);
  c.send(
      "POST /v1/refine?levels=abc HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
      "Expect: 100-continue\r\nContent-Length: 60000\r\n\r\n");
  const auto responses = test::parse_responses(c.read_all(2s));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 400);
  EXPECT_TRUE(c.closed());
  expect_good_request_still_works();
}

TEST_F(DaemonTest, ARefusedSmallBodyIsDrainedSoTheClientReadsTheAnswer) {
  // Sent without asking (what curl does below 1 MiB): the server reads and drops the body
  // before answering, so closing never resets the connection under the client's upload.
  for (int i = 0; i < 20; ++i) {
    test::RawConnection c(port_);
    ASSERT_TRUE(c.send(
        test::post_text("/v1/refine?levels=abc", "model/stl", std::string(200 * 1024, 'x'))));
    const auto responses = test::parse_responses(c.read_all(5s));
    ASSERT_EQ(responses.size(), 1u);
    EXPECT_EQ(responses[0].status, 400);
    EXPECT_TRUE(c.closed());
  }
  // Announced but never sent: answered once the read times out, not never.
  test::RawConnection c(port_);
  c.send(
      "POST /v1/refine?levels=abc HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
      "Content-Length: 60000\r\n\r\n");
  const auto late = test::parse_responses(c.read_all(5s));
  EXPECT_TRUE(c.closed());
  ASSERT_EQ(late.size(), 1u);
  EXPECT_EQ(late[0].status, 400);
  expect_good_request_still_works();
}

TEST_F(DaemonTest, WrongContentTypeIs415) {
  for (const char* type : {"text/plain", "application/json", "model/stl-ascii", ""}) {
    SCOPED_TRACE(type);
    const auto j = expect_problem(request(test::post_text(kGoodTarget, type, input_)), 415,
                                  "unsupported-media-type");
    EXPECT_EQ(j.value("field", ""), "Content-Type");
  }
  expect_good_request_still_works();
}

TEST_F(DaemonTest, CurlsDefaultContentTypeIsReadAsRawStl) {
  // `curl --data-binary @part.stl URL` sends application/x-www-form-urlencoded.
  const auto r = request(test::post_text(kGoodTarget, "application/x-www-form-urlencoded", input_));
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.header("content-type"), "model/stl");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, AnyContentEncodingIs415) {
  // httplib 0.11.4 would inflate gzip with no limit on the inflated size.
  for (const char* encoding : {"gzip", "br", "deflate", "identity"}) {
    SCOPED_TRACE(encoding);
    const auto j = expect_problem(
        request(test::post_text(kGoodTarget, "model/stl", input_,
                                "Content-Encoding: " + std::string(encoding) + "\r\n")),
        415, "unsupported-media-type");
    EXPECT_EQ(j.value("field", ""), "Content-Encoding");
  }
  expect_good_request_still_works();
}

TEST_F(DaemonTest, ChunkedTransferEncodingIs411) {
  char size[16];
  std::snprintf(size, sizeof size, "%zx", input_.size());
  const std::string chunked = std::string(size) + "\r\n" + input_ + "\r\n0\r\n\r\n";
  expect_problem(request(test::post_text(kGoodTarget, "model/stl", chunked,
                                         "Transfer-Encoding: chunked\r\n", false)),
                 411, "length-required");
  // Both headers at once is the classic smuggling shape: still 411.
  expect_problem(request(test::post_text(kGoodTarget, "model/stl", chunked,
                                         "Transfer-Encoding: chunked\r\n", true)),
                 411, "length-required");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, MissingContentLengthIs411) {
  test::RawConnection c(port_);
  // Not half-closed: 0.11.4 writes nothing to a peer that has (Httplib0114 tests).
  c.send(test::post_text(kGoodTarget, "model/stl", input_, {}, false));
  const auto responses = test::parse_responses(c.read_all(5s));
  ASSERT_EQ(responses.size(), 1u);
  expect_problem(responses[0], 411, "length-required");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, MalformedContentLengthIs400) {
  expect_problem(request("POST /v1/refine HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
                         "Content-Length: 12abc\r\n\r\n"),
                 400, "bad-request");
  expect_problem(request("POST /v1/refine HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
                         "Content-Length: 4\r\nContent-Length: 5\r\n\r\nabcd"),
                 400, "bad-request");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, BodyOverTheCapIs413WithoutReadingIt) {
  // Announced only: the answer comes at once, the gigabyte is never awaited.
  const auto j =
      expect_problem(request("POST /v1/refine HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
                             "Content-Length: 1000000000000\r\n\r\n"),
                     413, "payload-too-large");
  EXPECT_EQ(j.value("max_body_bytes", 0u), kMaxBody);
  // Sent for real, one byte over.
  const std::string big(kMaxBody + 1, 'x');
  expect_problem(request(test::post_text(kGoodTarget, "model/stl", big)), 413, "payload-too-large");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, ExpectContinueIsAnsweredByTheSameChecks) {
  {  // refused before the upload: no 100 Continue, the final answer instead
    test::RawConnection c(port_);
    c.send(test::post_text(kGoodTarget, "text/plain", "", "Expect: 100-continue\r\n", false));
    const auto responses = test::parse_responses(c.read_all(2s));
    ASSERT_GE(responses.size(), 1u);
    EXPECT_EQ(responses[0].status, 411);  // no Content-Length either: framing first
  }
  {
    test::RawConnection c(port_);
    c.send("POST " + std::string(kGoodTarget) +
           " HTTP/1.1\r\nHost: x\r\nContent-Type: text/plain\r\nContent-Length: " +
           std::to_string(input_.size()) + "\r\nExpect: 100-continue\r\n\r\n");
    const auto responses = test::parse_responses(c.read_all(2s));
    ASSERT_EQ(responses.size(), 1u);
    expect_problem(responses[0], 415, "unsupported-media-type");
    EXPECT_EQ(responses[0].header("content-length"), std::to_string(responses[0].body.size()));
  }
  {  // accepted: 100 Continue, then the body, then 200
    test::RawConnection c(port_);
    c.send("POST " + std::string(kGoodTarget) +
           " HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\nContent-Length: " +
           std::to_string(input_.size()) + "\r\nExpect: 100-continue\r\n\r\n");
    const std::string interim = c.read_until("\r\n\r\n", 2s);
    EXPECT_EQ(interim.rfind("HTTP/1.1 100 Continue", 0), 0u) << interim;
    c.send(input_);
    const auto responses = test::parse_responses(c.read_all(5s));
    ASSERT_EQ(responses.size(), 1u);
    EXPECT_EQ(responses[0].status, 200);
    EXPECT_TRUE(responses[0].body == reference_);
  }
}

// --- connection handling

TEST_F(DaemonTest, OneRequestPerConnection) {
  // Pipelined requests: only the first is answered, then the connection closes.
  test::RawConnection c(port_);
  c.send("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\nGET /readyz HTTP/1.1\r\nHost: x\r\n\r\n");
  const auto responses = test::parse_responses(c.read_all(2s));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].header("connection"), "close");
  EXPECT_TRUE(c.closed());
}

TEST_F(DaemonTest, AnUnreadBodyIsNeverReadAsTheNextRequest) {
  // A refused POST whose body is itself a request: it must not be executed.
  const std::string smuggled = "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n";
  for (const std::string& extra : {std::string("Content-Encoding: gzip\r\n"), std::string()}) {
    const std::string type = extra.empty() ? "text/plain" : "model/stl";
    test::RawConnection c(port_);
    c.send(test::post_text(kGoodTarget, type, smuggled, extra));
    const auto responses = test::parse_responses(c.read_all(2s));
    ASSERT_EQ(responses.size(), 1u);
    EXPECT_EQ(responses[0].status, 415);
  }
}

TEST_F(DaemonTest, GarbageRequestLineIs400ProblemJson) {
  expect_problem(request("BREW /pot HTCPCP/1.0\r\n\r\n"), 400, "bad-request");
  expect_problem(request("GET /" + std::string(9000, 'a') + " HTTP/1.1\r\n\r\n"), 414,
                 "uri-too-long");
  expect_good_request_still_works();
}

// --- 422: the file or the request cannot be processed

TEST_F(DaemonTest, MalformedStlNamesTheByteOffset) {
  auto tris = test::octahedron_triangles();
  tris[1][0][1] = std::numeric_limits<float>::quiet_NaN();
  auto j =
      expect_problem(request(test::post_text(kGoodTarget, "model/stl", test::binary_stl(tris))),
                     422, "malformed-stl");
  EXPECT_EQ(j.value("byte_offset", 0u), 84u + 50u + 12u + 4u);
  EXPECT_EQ(j.value("reason", ""), "non_finite");

  const std::string truncated = input_.substr(0, input_.size() - 7);
  j = expect_problem(request(test::post_text(kGoodTarget, "model/stl", truncated)), 422,
                     "malformed-stl");
  EXPECT_TRUE(j.contains("byte_offset"));

  std::string ascii = test::ascii_stl(test::octahedron_triangles());
  ascii.replace(ascii.find("vertex 1"), 8, "vertex zz");
  j = expect_problem(request(test::post_text("/v1/info", "model/stl", ascii)), 422,
                     "malformed-stl");
  EXPECT_TRUE(j.contains("line"));

  j = expect_problem(request(test::post_text(kGoodTarget, "model/stl", "")), 422, "malformed-stl");
  EXPECT_EQ(j.value("reason", ""), "too_small");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, FaceBudgetIs422WithThePrediction) {
  // 8 faces * 4^8 = 524288 > the server's 100000.
  auto j = expect_problem(request(test::post_text(refine_target("levels=8"), "model/stl", input_)),
                          422, "budget-exceeded");
  EXPECT_EQ(j.value("predicted_faces", 0u), 524288u);
  EXPECT_EQ(j.value("max_faces", 0u), kMaxFaces);
  EXPECT_EQ(j.value("field", ""), "max_faces");
  // A request may lower the cap: 8 * 4^2 = 128 > 100.
  j = expect_problem(
      request(test::post_text(refine_target("levels=2&max_faces=100"), "model/stl", input_)), 422,
      "budget-exceeded");
  EXPECT_EQ(j.value("predicted_faces", 0u), 128u);
  EXPECT_EQ(j.value("max_faces", 0u), 100u);
  expect_good_request_still_works();
}

TEST_F(DaemonTest, SharedMalformedFilesAre200Or422NeverWorse) {
  const std::filesystem::path dir = std::filesystem::path(STLREFINE_TEST_DATA_DIR) / "malformed";
  if (!std::filesystem::is_directory(dir)) GTEST_SKIP() << dir << " is absent";
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".stl") continue;
    SCOPED_TRACE(entry.path().filename().string());
    ++files;
    std::ifstream in(entry.path(), std::ios::binary);
    std::stringstream bytes;
    bytes << in.rdbuf();
    const RawResponse r =
        request(test::post_text(refine_target("levels=1"), "model/stl", bytes.str()));
    if (r.status == 200) {
      const auto report = nlohmann::json::parse(r.header("x-stlrefine-report"));
      EXPECT_EQ(test::read_binary_stl(r.body).size(),
                4 * report.at("input").at("faces").get<std::size_t>());
    } else {
      ASSERT_EQ(r.status, 422) << r.body;
      const auto j = nlohmann::json::parse(r.body);
      const std::string type = j.value("type", "");
      if (type == "urn:stlrefine:problem:malformed-stl")
        EXPECT_TRUE(j.contains("byte_offset") || j.contains("line")) << r.body;
      else
        EXPECT_EQ(type, "urn:stlrefine:problem:not-triangle-mesh") << r.body;
    }
  }
  EXPECT_GT(files, 0);
  expect_good_request_still_works();
}

// --- 404 / 405

TEST_F(DaemonTest, UnknownRouteIs404) {
  expect_problem(request("GET /nope HTTP/1.1\r\nHost: x\r\n\r\n"), 404, "not-found");
  expect_problem(request("GET /v1/refine/extra HTTP/1.1\r\nHost: x\r\n\r\n"), 404, "not-found");
  // A POST to nowhere is refused before its body is read.
  expect_problem(request(test::post_text("/v2/refine", "model/stl", input_)), 404, "not-found");
  expect_good_request_still_works();
}

TEST_F(DaemonTest, WrongMethodIs405WithAllow) {
  RawResponse r = request("GET /v1/refine HTTP/1.1\r\nHost: x\r\n\r\n");
  expect_problem(r, 405, "method-not-allowed");
  EXPECT_EQ(r.header("allow"), "POST");
  r = request(test::post_text("/healthz", "model/stl", input_));
  expect_problem(r, 405, "method-not-allowed");
  EXPECT_EQ(r.header("allow"), "GET, HEAD");
  r = request("DELETE /v1/info HTTP/1.1\r\nHost: x\r\n\r\n");
  expect_problem(r, 405, "method-not-allowed");
  expect_good_request_still_works();
}

// --- 503 / 500

TEST_F(DaemonTest, FullComputeSlotsAnswer503AtOnce) {
  {
    std::vector<ComputeSlots::Lease> held;
    while (auto lease = daemon_->compute_slots().try_acquire()) held.push_back(std::move(*lease));
    ASSERT_EQ(held.size(), 2u);

    const auto start = std::chrono::steady_clock::now();
    RawResponse r = request(test::post_text(kGoodTarget, "model/stl", input_));
    EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);
    auto j = expect_problem(r, 503, "busy");
    EXPECT_EQ(r.header("retry-after"), "3");
    EXPECT_EQ(j.value("compute_slots", 0), 2);

    expect_problem(request(test::post_text("/v1/info", "model/stl", input_)), 503, "busy");
    r = request("GET /readyz HTTP/1.1\r\nHost: x\r\n\r\n");
    expect_problem(r, 503, "busy");
    EXPECT_EQ(r.header("retry-after"), "3");
    EXPECT_EQ(request("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").status, 200);
  }
  EXPECT_EQ(request("GET /readyz HTTP/1.1\r\nHost: x\r\n\r\n").status, 200);
  expect_good_request_still_works();
}

TEST_F(DaemonTest, ConcurrentRequestsGet200Or503) {
  std::vector<std::thread> clients;
  std::atomic<int> ok{0}, busy{0}, other{0};
  for (int t = 0; t < 6; ++t) {
    clients.emplace_back([&] {
      for (int i = 0; i < 3; ++i) {
        const std::string raw =
            test::exchange(port_, test::post_text(kGoodTarget, "model/stl", input_));
        const auto responses = test::parse_responses(raw);
        if (responses.size() == 1 && responses[0].status == 200 && responses[0].body == reference_)
          ++ok;
        else if (responses.size() == 1 && responses[0].status == 503)
          ++busy;
        else
          ++other;
      }
    });
  }
  for (auto& c : clients) c.join();
  EXPECT_GT(ok.load(), 0);
  EXPECT_EQ(other.load(), 0);
  EXPECT_EQ(ok + busy, 18);
  EXPECT_EQ(daemon_->compute_slots().available(), 2u);
}

TEST_F(DaemonTest, ThrowingHandlerIsAGeneric500) {
  throw_in_handler_ = true;
  const std::string raw = test::exchange(port_, test::post_text(kGoodTarget, "model/stl", input_));
  throw_in_handler_ = false;
  EXPECT_EQ(raw.find("secret-4711"), std::string::npos) << raw;
  EXPECT_EQ(raw.find("EXCEPTION_WHAT"), std::string::npos) << raw;
  const auto responses = test::parse_responses(raw);
  ASSERT_EQ(responses.size(), 1u);
  const auto j = expect_problem(responses[0], 500, "internal");
  EXPECT_EQ(j.value("detail", ""), "an internal error occurred");
  EXPECT_FALSE(responses[0].has_header("x-stlrefine-report"));
  expect_good_request_still_works();
}

}  // namespace
}  // namespace stlrefine::server
