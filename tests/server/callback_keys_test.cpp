// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 19 item 5 (round 5): each tenant's callbacks are signed with its own key (derived
// from the server's secret and its tenant id), over "timestamp.body", so one tenant cannot
// verify or forge what another receives, and a receiver can refuse replays; the operator
// prints a tenant's key with `stlrefined --print-callback-key`.

#include <gtest/gtest.h>
#include <httplib.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "in_process_daemon.h"
#include "job_parts_fixtures.h"
#include "server/job_callbacks.h"
#include "subprocess.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
using Json = nlohmann::json;

std::string hmac_hex(const std::string& key, const std::string& message) {
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()),
       reinterpret_cast<const unsigned char*>(message.data()), message.size(), mac, &size);
  std::string out;
  char hex[3];
  for (unsigned int i = 0; i < size; ++i) {
    std::snprintf(hex, sizeof hex, "%02x", mac[i]);
    out += hex;
  }
  return out;
}

struct Delivery {
  std::string body, signature, timestamp;
};

TEST(CallbackKeys, EachTenantsCallbacksAreSignedWithItsOwnKeyOverTimestampAndBody) {
  httplib::Server receiver;
  std::mutex mutex;
  std::map<std::string, Delivery> received;  // by path: /a, /b
  receiver.Post(R"(/(a|b))", [&](const httplib::Request& req, httplib::Response& res) {
    std::lock_guard lock(mutex);
    received[req.path] = {req.body, req.get_header_value("X-Stlrefine-Signature"),
                          req.get_header_value("X-Stlrefine-Timestamp")};
    res.status = 204;
  });
  const int port = receiver.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { receiver.listen_after_bind(); });

  const auto dir = fresh_job_dir("callback-keys");
  server::DaemonConfig config = jobs_config(dir);
  const std::string secret = "the-servers-callback-secret";
  const std::string key_a = "tenant-a-api-key-0123456789", key_b = "tenant-b-api-key-9876543210";
  config.api_keys = {key_a, key_b};
  config.jobs.callbacks.secret = secret;
  config.jobs.callbacks.allow = {cat("127.0.0.1:", std::to_string(port))};
  {
    InProcessDaemon d(config);
    httplib::Client c = d.client();
    const std::string base = cat("http://127.0.0.1:", std::to_string(port));
    for (const auto& [key, path] : {std::pair{key_a, "/a"}, std::pair{key_b, "/b"}}) {
      httplib::Headers auth = {{"Authorization", cat("Bearer ", key)}};
      auto r = c.Post(cat("/v1/jobs?levels=1&callback_url=", base, path).c_str(), auth,
                      stl_of(box(10)), "model/stl");
      ASSERT_TRUE(r);
      ASSERT_EQ(r->status, 202) << r->body;
    }
    const auto until = std::chrono::steady_clock::now() + 30s;
    while (std::chrono::steady_clock::now() < until) {
      {
        std::lock_guard lock(mutex);
        if (received.size() == 2) break;
      }
      std::this_thread::sleep_for(20ms);
    }
  }
  receiver.stop();
  serving.join();
  ASSERT_EQ(received.size(), 2u);

  // The operator's command prints the keys the daemon signed with.
  std::map<std::string, std::string> printed;
  for (const auto& [key, path] : {std::pair{key_a, "/a"}, std::pair{key_b, "/b"}}) {
    const ProcessResult p = run_process({STLREFINED, "--data-dir", dir.string(),
                                         "--callback-secret", secret, "--print-callback-key", key});
    ASSERT_EQ(p.exit_code, 0) << p.err;
    ASSERT_EQ(p.out.size(), 65u) << p.out;  // 64 hex digits and a newline
    printed[path] = p.out.substr(0, 64);
    EXPECT_EQ(printed[path], server::callback_key_of_api_key(dir, secret, key));
  }
  EXPECT_NE(printed["/a"], printed["/b"]);
  for (const auto& [path, d] : received) {
    const std::string other = path == "/a" ? "/b" : "/a";
    const std::string signed_text = d.timestamp + "." + d.body;
    EXPECT_EQ(d.signature, cat("sha256=", hmac_hex(printed[path], signed_text))) << path;
    // Neither the other tenant's key nor the server's secret itself verifies it, nor the
    // body alone (the old scheme), nor another time.
    EXPECT_NE(d.signature, cat("sha256=", hmac_hex(printed[other], signed_text))) << path;
    EXPECT_NE(d.signature, cat("sha256=", hmac_hex(secret, signed_text))) << path;
    EXPECT_NE(d.signature, cat("sha256=", hmac_hex(printed[path], d.body))) << path;
    EXPECT_NE(d.signature, cat("sha256=", hmac_hex(printed[path], cat("1.", d.body)))) << path;
    EXPECT_NEAR(std::stod(d.timestamp), static_cast<double>(std::time(nullptr)), 60.0);
    EXPECT_EQ(Json::parse(d.body)["state"], "done");
  }
}

TEST(CallbackKeys, PrintCallbackKeyNeedsASecretAndReadsTheKeyFromStdinWithADash) {
  const auto dir = fresh_job_dir("print-key");
  const ProcessResult none =
      run_process({STLREFINED, "--data-dir", dir.string(), "--print-callback-key", "k"});
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_NE(none.err.find("--callback-secret"), std::string::npos) << none.err;
  // stdin is /dev/null in run_process: "-" reads an empty key, the keyless tenant's.
  const ProcessResult keyless =
      run_process({STLREFINED, "--data-dir", dir.string(), "--callback-secret", "s",
                   "--print-callback-key", "-"});
  ASSERT_EQ(keyless.exit_code, 0) << keyless.err;
  EXPECT_EQ(keyless.out, server::callback_key_of_api_key(dir, "s", "") + "\n");
}

}  // namespace
}  // namespace stlrefine::test
