// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The seams the split of server/ made: a route handler called with a library-neutral
// HttpRequest (its body in it) and no socket, the checks before the body resolving the
// parameters once, the framing of an HttpAnswer, and the head parser on its own.

#include <gtest/gtest.h>

#include <cstdint>
#include <nlohmann/json.hpp>
#include <span>
#include <string>

#include "api/params.h"
#include "api/problem.h"
#include "server/compute_routes.h"
#include "server/daemon.h"
#include "server/http.h"
#include "server/http_adapter.h"
#include "server/request_head.h"
#include "server/route_context.h"
#include "tests/server/test_stl.h"

namespace stlrefine::server {
namespace {

// A daemon's resources without the daemon: no socket, no thread but the request watch's.
struct Resources {
  DaemonConfig config;
  api::RequestLimits limits{.max_faces = 1'000'000,
                            .default_max_faces = 0,
                            .max_slice_points = 1'000'000,
                            .accept_threads = false};
  ComputeSlots slots{1};
  MemoryBudget memory{std::uint64_t{1} << 30, kDaemonReserve};
  RequestWatch watch;
  Metrics metrics;
  std::atomic<bool> stopping{false};
  RouteContext ctx{config, limits, slots, memory, watch, metrics, nullptr, stopping};
};

HttpRequest post(const std::string& target, const std::string& body) {
  HttpRequest req;
  req.method = "POST";
  req.target = target;
  req.path = target.substr(0, target.find('?'));
  req.version = "HTTP/1.1";
  req.headers.emplace("Content-Type", "model/stl");
  req.headers.emplace("Content-Length", std::to_string(body.size()));
  req.body = body;
  return req;
}

// The checks before the body, then the compute handler with no socket (fd -1) and no
// reservation made before (one is made).
HttpAnswer checked_and_served(Resources& r, const HttpRequest& req) {
  CheckedRequest checked;
  EXPECT_FALSE(r.ctx.precheck(req, checked));
  // Resolved before the body: a refinement's scheme is made there, the one it runs with.
  EXPECT_TRUE(checked.refine ? checked.refine->scheme != nullptr : checked.info.has_value());
  HttpAnswer res;
  serve_compute(r.ctx, req, std::move(checked), -1, nullptr, res);
  return res;
}

TEST(Handler, ARefineIsAnsweredWithoutASocketAndItsStlIsMadeAsItIsRead) {
  Resources r;
  const std::string stl = test::binary_stl(test::octahedron_triangles());
  HttpAnswer res = checked_and_served(r, post("/v1/refine?scheme=butterfly&levels=1", stl));
  EXPECT_EQ(res.status, api::http::kOk);
  EXPECT_EQ(res.header("Content-Type"), "model/stl");
  const auto report = nlohmann::json::parse(res.header("X-Stlrefine-Report"));
  EXPECT_EQ(report["input"]["faces"], 8);
  EXPECT_EQ(report["output"]["faces"], 32);  // one split4 level
  ASSERT_TRUE(res.large.made);
  ASSERT_EQ(res.large.made_length, 84u + 50u * 32u);
  std::string bytes(res.large.made_length, '\0');
  res.large.made(0, std::span(bytes.data(), bytes.size()));
  EXPECT_EQ(test::read_binary_stl(bytes).size(), 32u);
  // The slot was taken and given back; the reservation shrank to the body and the answer.
  EXPECT_EQ(r.slots.available(), 1u);
}

TEST(Handler, InfoIsAnsweredFromTheCheckedParameters) {
  Resources r;
  const std::string stl = test::binary_stl(test::octahedron_triangles());
  const HttpAnswer res = checked_and_served(r, post("/v1/info", stl));
  EXPECT_EQ(res.status, api::http::kOk);
  EXPECT_EQ(nlohmann::json::parse(res.body)["mesh"]["faces"], 8);
}

TEST(Handler, TheChecksBeforeTheBodyNameTheParameterAndTheFraming) {
  Resources r;
  CheckedRequest checked;
  const auto bad = r.ctx.precheck(post("/v1/refine?levels=99", "x"), checked);
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, api::http::kBadRequest);
  EXPECT_EQ(bad->field, "levels");

  HttpRequest chunked = post("/v1/refine", "");
  chunked.headers.erase("Content-Length");
  chunked.headers.emplace("transfer-encoding", "chunked");  // names compare without case
  const auto refused = r.ctx.precheck(chunked, checked);
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, api::http::kLengthRequired);

  // Every slot taken: 503 busy before the upload, and again after it (check_capacity).
  auto lease = r.slots.try_acquire();
  const auto busy = r.ctx.precheck(post("/v1/refine?levels=1", "x"), checked);
  ASSERT_TRUE(busy);
  EXPECT_EQ(busy->status, api::http::kServiceUnavailable);
  EXPECT_TRUE(r.ctx.check_capacity(*checked.route));
}

TEST(Handler, AnAnswerIsFramedWithItsLengthAndOneRange) {
  HttpRequest get;
  get.method = "GET";
  get.target = get.path = "/x";
  get.headers.emplace("Range", "bytes=2-4");
  HttpAnswer res;
  res.set_content("0123456789", "text/plain");
  res.set_header("X-Request-Id", "abc");
  const Answer ranged = frame_answer(get, std::move(res), true, {});
  EXPECT_EQ(ranged.head,
            "HTTP/1.1 206 Partial Content\r\nAccept-Ranges: bytes\r\n"
            "Content-Range: bytes 2-4/10\r\nContent-Type: text/plain\r\nX-Request-Id: abc\r\n"
            "Content-Length: 3\r\nConnection: close\r\n\r\n234");

  get.method = "HEAD";
  HttpAnswer whole;
  whole.set_content("0123456789", "text/plain");
  const Answer head_only = frame_answer(get, std::move(whole), false, {});
  EXPECT_EQ(head_only.head,
            "HTTP/1.1 200 OK\r\nContent-Type: text/plain\r\nContent-Length: 10\r\n"
            "Connection: close\r\n\r\n");
}

TEST(Handler, TheHeadParserRefusesABareLineFeed) {
  RequestHead head;
  EXPECT_FALSE(parse_head("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n", head));
  EXPECT_EQ(head.target, "/healthz");
  ASSERT_TRUE(head.find("host"));
  RequestHead bad;
  const auto error = parse_head("GET /healthz HTTP/1.1\r\nHost: x\ny: z\r\n\r\n", bad);
  ASSERT_TRUE(error);
  EXPECT_EQ(error->status, api::http::kBadRequest);
}

}  // namespace
}  // namespace stlrefine::server
