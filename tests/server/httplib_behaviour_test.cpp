// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// What Debian's cpp-httplib 0.11.4 does on its own, on a bare httplib::Server: the facts
// server/daemon.cpp's hardening rests on. If a library update changes one of them, this
// file says which assumption to revisit.

#include <gtest/gtest.h>
#include <httplib.h>
#include <sys/socket.h>
#include <zlib.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>

#include "http_test_client.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;

class BareServer {
 public:
  explicit BareServer(const std::function<void(httplib::Server&)>& setup) {
    std::signal(SIGPIPE, SIG_IGN);
    svr_.set_read_timeout(2, 0);
    // One request per connection, so a test's read ends when the server closes; the
    // keep-alive test sets its own count.
    svr_.set_keep_alive_max_count(1);
    setup(svr_);
    port_ = svr_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { svr_.listen_after_bind(); });
    while (!svr_.is_running()) std::this_thread::sleep_for(1ms);
  }
  ~BareServer() {
    svr_.stop();
    thread_.join();
  }
  int port() const { return port_; }

 private:
  httplib::Server svr_;
  std::thread thread_;
  int port_ = 0;
};

std::string chunked(const std::string& body) {
  char size[16];
  std::snprintf(size, sizeof size, "%zx", body.size());
  return std::string(size) + "\r\n" + body + "\r\n0\r\n\r\n";
}

std::string gzip(const std::string& data) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, Z_BEST_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out(deflateBound(&z, data.size()), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

TEST(Httplib0114, PreRoutingHandlerRunsBeforeTheBodyIsRead) {
  std::atomic<long> body_seen{-1};
  BareServer server([&](httplib::Server& svr) {
    svr.set_pre_routing_handler([&](const httplib::Request& req, httplib::Response& res) {
      body_seen = static_cast<long>(req.body.size());
      res.status = 415;
      return httplib::Server::HandlerResponse::Handled;
    });
  });
  // Headers announce 100000 bytes but none are sent: an answer proves nothing was awaited.
  RawConnection c(server.port());
  c.send("POST /x HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n");
  const auto responses = parse_responses(c.read_all(2s));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 415);
  EXPECT_EQ(body_seen.load(), 0);
}

TEST(Httplib0114, ChunkedBodySkipsThePayloadLimit) {
  std::atomic<long> body_seen{-1};
  BareServer server([&](httplib::Server& svr) {
    svr.set_payload_max_length(16);
    svr.Post("/x", [&](const httplib::Request& req, httplib::Response&) {
      body_seen = static_cast<long>(req.body.size());
    });
  });
  const auto responses = parse_responses(
      exchange(server.port(), post_text("/x", "model/stl", chunked(std::string(1000, 'a')),
                                        "Transfer-Encoding: chunked\r\n", false)));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 200);
  EXPECT_EQ(body_seen.load(), 1000);  // 1000 > 16: the limit was not applied
}

// Such a body ends when the client half-closes (FIN). The handler gets it all, past the
// limit; the answer is then never written: 0.11.4 finds the half-closed peer "not alive".
TEST(Httplib0114, BodyWithoutContentLengthSkipsThePayloadLimit) {
  std::atomic<long> body_seen{-1};
  BareServer server([&](httplib::Server& svr) {
    svr.set_payload_max_length(16);
    svr.Post("/x", [&](const httplib::Request& req, httplib::Response&) {
      body_seen = static_cast<long>(req.body.size());
    });
  });
  RawConnection c(server.port());
  c.send(post_text("/x", "model/stl", std::string(1000, 'a'), {}, false));
  c.shutdown_write();
  const auto responses = parse_responses(c.read_all(3s));
  EXPECT_TRUE(c.closed());
  EXPECT_EQ(body_seen.load(), 1000);
  EXPECT_EQ(responses.size(), 0u);
}

TEST(Httplib0114, ContentLengthOverTheLimitIs413WithAnEmptyBody) {
  std::atomic<bool> handled{false};
  BareServer server([&](httplib::Server& svr) {
    svr.set_payload_max_length(16);
    svr.Post("/x", [&](const httplib::Request&, httplib::Response&) { handled = true; });
  });
  const auto responses = parse_responses(
      exchange(server.port(), post_text("/x", "model/stl", std::string(1000, 'a'))));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 413);
  EXPECT_TRUE(responses[0].body.empty());  // hence our error handler
  EXPECT_FALSE(handled.load());
}

TEST(Httplib0114, GzipBodyIsInflatedAndTheLimitAppliesToTheCompressedSize) {
  std::atomic<long> body_seen{-1};
  BareServer server([&](httplib::Server& svr) {
    svr.set_payload_max_length(4096);
    svr.Post("/x", [&](const httplib::Request& req, httplib::Response&) {
      body_seen = static_cast<long>(req.body.size());
    });
  });
  const std::string inflated(1 << 20, '\0');
  const std::string compressed = gzip(inflated);
  ASSERT_LT(compressed.size(), 4096u);
  const auto responses = parse_responses(exchange(
      server.port(), post_text("/x", "model/stl", compressed, "Content-Encoding: gzip\r\n")));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 200);
  EXPECT_EQ(body_seen.load(), 1 << 20);  // 256 x the limit reached the handler
}

TEST(Httplib0114, ThrowingHandlerLeaksWhatInAHeaderWithoutAnExceptionHandler) {
  BareServer server([](httplib::Server& svr) {
    svr.Get("/x", [](const httplib::Request&, httplib::Response&) {
      throw std::runtime_error("secret-4711");
    });
  });
  const std::string raw = exchange(server.port(), "GET /x HTTP/1.1\r\nHost: x\r\n\r\n");
  const auto responses = parse_responses(raw);
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 500);
  EXPECT_EQ(responses[0].header("exception_what"), "secret-4711");
}

TEST(Httplib0114, ExceptionHandlerReplacesTheLeak) {
  BareServer server([](httplib::Server& svr) {
    svr.Get("/x", [](const httplib::Request&, httplib::Response&) {
      throw std::runtime_error("secret-4711");
    });
    svr.set_exception_handler([](const httplib::Request&, httplib::Response& res,
                                 std::exception_ptr) { res.status = 500; });
  });
  const std::string raw = exchange(server.port(), "GET /x HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(raw.find("secret-4711"), std::string::npos);
  ASSERT_EQ(parse_responses(raw).size(), 1u);
  EXPECT_EQ(parse_responses(raw)[0].status, 500);
}

TEST(Httplib0114, ErrorHandlerRunsForEvery4xxIncludingTheHandlers) {
  std::atomic<int> calls{0};
  BareServer server([&](httplib::Server& svr) {
    svr.Get("/x", [](const httplib::Request&, httplib::Response& res) {
      res.status = 422;
      res.set_content("mine", "text/plain");
    });
    // The plain Handler overload always counts as Handled, and would replace "mine".
    svr.set_error_handler(
        httplib::Server::HandlerWithResponse([&](const httplib::Request&, httplib::Response& res) {
          ++calls;
          if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
          res.set_content("filled", "text/plain");
          return httplib::Server::HandlerResponse::Handled;
        }));
  });
  auto responses = parse_responses(exchange(server.port(), "GET /x HTTP/1.1\r\nHost: x\r\n\r\n"));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].body, "mine");
  EXPECT_EQ(calls.load(), 1);
  responses = parse_responses(exchange(server.port(), "GET /y HTTP/1.1\r\nHost: x\r\n\r\n"));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 404);
  EXPECT_EQ(responses[0].body, "filled");
}

// A pre-routing refusal leaves the body unread. Bytes already buffered by the library are
// dropped with the request, but bytes still in the socket are parsed as the next request on
// a keep-alive connection: here a "body" that is a GET, sent a moment after the headers,
// gets executed and answered.
TEST(Httplib0114, KeepAliveReadsAnUnreadBodyAsTheNextRequest) {
  auto setup = [](httplib::Server& svr) {
    svr.set_pre_routing_handler([](const httplib::Request& req, httplib::Response& res) {
      if (req.method != "POST") return httplib::Server::HandlerResponse::Unhandled;
      res.status = 415;
      return httplib::Server::HandlerResponse::Handled;
    });
    svr.Get("/smuggled", [](const httplib::Request&, httplib::Response& res) {
      res.set_content("ran", "text/plain");
    });
    svr.set_keep_alive_timeout(1);
  };
  const std::string body = "GET /smuggled HTTP/1.1\r\nHost: x\r\n\r\n";
  const std::string request = post_text("/x", "text/plain", body);
  const std::string head = request.substr(0, request.size() - body.size());
  auto send_in_two_parts = [&](int port) {
    RawConnection c(port);
    c.send(head);
    std::this_thread::sleep_for(200ms);  // the server has read the head by now
    c.send(body);
    return parse_responses(c.read_all(3s));
  };
  {
    BareServer server([&](httplib::Server& svr) {
      setup(svr);
      svr.set_keep_alive_max_count(5);  // the library's default
    });
    const auto responses = send_in_two_parts(server.port());
    ASSERT_EQ(responses.size(), 2u);
    EXPECT_EQ(responses[0].status, 415);
    EXPECT_EQ(responses[1].body, "ran");
  }
  {  // keep_alive_max_count(1): one response, then the connection closes
    BareServer server(setup);
    const auto responses = send_in_two_parts(server.port());
    ASSERT_EQ(responses.size(), 1u);
    EXPECT_EQ(responses[0].status, 415);
    EXPECT_EQ(responses[0].header("connection"), "close");
  }
}

TEST(Httplib0114, ExpectContinueHandlerCanAnswerInsteadOf100) {
  BareServer server([](httplib::Server& svr) {
    svr.set_expect_100_continue_handler([](const httplib::Request&, httplib::Response& res) {
      res.status = 413;
      res.set_content("too big", "text/plain");
      return 413;
    });
    svr.set_keep_alive_max_count(1);
  });
  RawConnection c(server.port());
  c.send("POST /x HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\nExpect: 100-continue\r\n\r\n");
  const auto responses = parse_responses(c.read_all(2s));
  ASSERT_EQ(responses.size(), 1u);
  EXPECT_EQ(responses[0].status, 413);
  // The body is written, but without a Content-Length (the path skips it): only a client
  // that reads to the close gets it. Hence the daemon sets Content-Length there itself.
  EXPECT_FALSE(responses[0].has_header("content-length"));
  EXPECT_EQ(responses[0].body, "too big");
}

// The default socket options set SO_REUSEPORT: a second server binds a port already in
// use, and the kernel splits the connections between the two.
TEST(Httplib0114, DefaultSocketOptionsLetASecondServerBindTheSamePort) {
  BareServer first([](httplib::Server&) {});
  httplib::Server second;
  EXPECT_TRUE(second.bind_to_port("127.0.0.1", first.port()));
  httplib::Server strict;
  strict.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  EXPECT_FALSE(strict.bind_to_port("127.0.0.1", first.port()));
}

}  // namespace
}  // namespace stlrefine::test
