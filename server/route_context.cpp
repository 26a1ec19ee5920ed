// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/route_context.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <string_view>

#include "api/plan.h"
#include "core/error.h"
#include "server/http_upload.h"

namespace stlrefine::server {

namespace {

// "model/STL ; charset=x" -> "model/stl".
std::string media_type(const std::string& content_type) {
  std::string_view v = content_type;
  v = v.substr(0, v.find(';'));
  while (!v.empty() && (v.back() == ' ' || v.back() == '\t')) v.remove_suffix(1);
  while (!v.empty() && (v.front() == ' ' || v.front() == '\t')) v.remove_prefix(1);
  std::string out(v);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// Constant-time comparison: the time taken does not reveal how many bytes matched.
bool same_secret(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::max(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(x ^ y);
  }
  return diff == 0;
}

// The key of "Authorization: Bearer KEY", or nothing.
// The scheme name is case-insensitive (RFC 9110 11.1): "bearer KEY" too.
std::optional<std::string_view> bearer_token(std::string_view header) {
  constexpr std::string_view kBearer = "bearer ";
  if (header.size() <= kBearer.size()) return std::nullopt;
  for (std::size_t i = 0; i < kBearer.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(header[i])) != kBearer[i]) return std::nullopt;
  return header.substr(kBearer.size());
}

// The API key the request presents: "Authorization: Bearer KEY" or "X-Api-Key: KEY" (what
// API gateways and many HTTP clients send). Both given and different: no key, so that a
// proxy's key cannot be shadowed by a client's.
std::optional<std::string> presented_key(const HttpRequest& req) {
  const std::string authorization = req.header("Authorization");
  const std::string api_key = req.header("X-Api-Key");
  const std::optional<std::string_view> bearer = bearer_token(authorization);
  if (!authorization.empty() && !bearer) return std::nullopt;
  if (bearer && !api_key.empty() && *bearer != api_key) return std::nullopt;
  if (bearer) return std::string(*bearer);
  if (!api_key.empty()) return api_key;
  return std::nullopt;
}

}  // namespace

void send_problem(HttpAnswer& res, const api::Problem& problem) {
  res.status = problem.status;
  res.set_content(api::problem_body(problem), api::kProblemContentType);
}

std::optional<api::Problem> RouteContext::precheck(const HttpRequest& req,
                                                   CheckedRequest& checked) const {
  const Route* route = find_route(req.path);
  checked = CheckedRequest{route, std::nullopt, std::nullopt, std::nullopt};
  if (!route) return api::not_found("not-found", "no route " + shortened(req.path));
  if (!method_allowed(*route, req.method)) {
    api::Problem p = api::method_not_allowed(
        "method-not-allowed",
        req.method + " is not allowed on " + route->path + " (allowed: " + route->allow + ")");
    p.extensions["allow"] = route->allow;
    return p;
  }
  if (!authorized(req)) {
    api::Problem p = api::unauthorized(
        "unauthorized",
        "this server needs an API key: Authorization: Bearer <key> or X-Api-Key: <key>");
    p.extensions["www_authenticate"] = "Bearer";
    return p;
  }
  if ((route->kind == RouteKind::Submit || route->kind == RouteKind::JobItem) && !jobs)
    return api::not_found("jobs-disabled",
                          "jobs are not enabled on this server (start it with --data-dir DIR)");
  if (!has_body(*route, req.method)) {
    // The library reads a DELETE body (a chunked one without any limit) and leaves a GET
    // body unread; neither route takes one.
    // get_header_value returns a copy: keep it alive while the view is used.
    const std::string length_header = req.header("Content-Length");
    std::string_view length = length_header;
    while (length.size() > 1 && length.front() == '0') length.remove_prefix(1);
    if (req.has_header("Transfer-Encoding") || (!length.empty() && length != "0")) {
      api::Problem p = api::bad_request("bad-request",
                                        req.method + " " + route->path + " takes no request body");
      p.field = req.has_header("Transfer-Encoding") ? "Transfer-Encoding" : "Content-Length";
      return p;
    }
    return std::nullopt;
  }

  // Body framing. Only Content-Length bodies are accepted: 0.11.4 applies its payload limit
  // to nothing else.
  if (req.has_header("Transfer-Encoding"))
    return api::length_required("length-required",
                                "Transfer-Encoding (" + shortened(req.header("Transfer-Encoding")) +
                                    ") is not accepted; send the body with a Content-Length");
  if (!req.has_header("Content-Length"))
    return api::length_required("length-required", "a POST body needs a Content-Length header");
  const std::string length_text = req.header("Content-Length");
  std::uint64_t length = 0;
  const auto [end, ec] =
      std::from_chars(length_text.data(), length_text.data() + length_text.size(), length);
  if (req.header_count("Content-Length") != 1 || length_text.empty() || ec != std::errc() ||
      end != length_text.data() + length_text.size())
    return api::bad_request("bad-request", "Content-Length must be one decimal number, not '" +
                                               shortened(length_text) + "'");
  if (req.has_header("Content-Encoding")) {
    api::Problem p = api::unsupported_media_type(
        "unsupported-media-type", "Content-Encoding '" + shortened(req.header("Content-Encoding")) +
                                      "' is not accepted; send the STL bytes as they are");
    p.field = "Content-Encoding";
    return p;
  }
  const std::string type = media_type(req.header("Content-Type"));
  // curl --data-binary labels the body application/x-www-form-urlencoded unless told
  // otherwise. The bytes arrive unchanged and are never form-decoded, so the plain
  // `curl --data-binary @part.stl URL` a user types is accepted as raw STL.
  // multipart/form-data (curl -F file=@part.stl): its boundary is checked before the upload.
  const std::optional<std::string> boundary = multipart_boundary(req.header("Content-Type"));
  if (boundary && boundary->empty()) {
    api::Problem p = api::bad_request(
        "bad-request", "multipart/form-data needs a boundary parameter of 1 to 70 characters");
    p.field = "Content-Type";
    return p;
  }
  // The mesh formats read_mesh takes (the body is sniffed by content whatever it says).
  const bool mesh_type = type == "model/3mf" || type == "model/obj" || type == "model/x-ply" ||
                         type == "application/x-ply" || type == "application/zip";
  if (type != "model/stl" && type != "application/octet-stream" && !mesh_type &&
      type != "application/x-www-form-urlencoded" && !boundary) {
    api::Problem p = api::unsupported_media_type(
        "unsupported-media-type",
        "Content-Type must be model/stl, model/3mf, model/obj, model/x-ply, application/zip, "
        "application/octet-stream or multipart/form-data, not '" +
            shortened(req.header("Content-Type")) + "'");
    p.field = "Content-Type";
    return p;
  }
  if (length > config.max_body_bytes) {
    api::Problem p =
        api::content_too_large("payload-too-large", "the body is " + std::to_string(length) +
                                                        " bytes; this server accepts at most " +
                                                        std::to_string(config.max_body_bytes));
    p.extensions["max_body_bytes"] = config.max_body_bytes;
    return p;
  }

  // Parameters, before the body is uploaded: resolved once, for the handler. A refinement's
  // validation makes its scheme (make_scheme(RefineParams)); that scheme is the one it runs.
  try {
    api::RawParams raw = req.parameters();
    // The upload's own parameters (not the computation's): read by the handlers (a job's
    // callback_url; the name of a file whose downloads are named, not /v1/info's).
    const bool named = route->path != std::string_view("/v1/info");
    std::erase_if(raw, [&](const auto& p) {
      return (p.first == "filename" && named) ||
             (p.first == "callback_url" && route->kind == RouteKind::Submit);
    });
    if (route->kind == RouteKind::Submit || route->path == std::string_view("/v1/refine"))
      checked.refine = api::plan_refine(api::parse_refine_fields(raw, limits));
    else if (route->path == std::string_view("/v1/slice"))
      checked.slice = api::parse_slice_params(raw, limits);
    else
      checked.info = api::parse_info_params(raw);
  } catch (const Error& e) {
    return api::problem_from_error(e);
  }
  return check_capacity(*route);
}

std::optional<api::Problem> RouteContext::check_capacity(const Route& route) const {
  // A full house is told at once. The handler takes the slot for real after the upload.
  if (route.kind == RouteKind::Submit) {
    if (stopping || jobs->queued() >= jobs->config().max_queued) {
      if (stopping) return busy_problem(true);
      api::Problem p = api::service_unavailable("queue-full",
                                                "all " + std::to_string(jobs->config().max_queued) +
                                                    " job queue places are taken; retry later");
      p.extensions["max_queued"] = jobs->config().max_queued;
      return p;
    }
    return std::nullopt;
  }
  if (stopping || slots.available() == 0) return busy_problem(stopping);
  return std::nullopt;
}

api::Problem RouteContext::busy_problem(bool is_stopping) const {
  if (is_stopping) return api::service_unavailable("shutting-down", "the server is shutting down");
  api::Problem p = api::service_unavailable(
      "busy", "all " + std::to_string(slots.capacity()) + " compute slots are taken; retry later");
  p.extensions["compute_slots"] = slots.capacity();
  return p;
}

api::Problem RouteContext::memory_busy_problem(std::uint64_t predicted) const {
  api::Problem p = api::service_unavailable(
      "busy", "the memory budget is taken by the requests running now (this one needs about " +
                  std::to_string((predicted + (1 << 20) - 1) >> 20) + " MiB); retry later");
  p.extensions["reason"] = "memory";
  p.extensions["memory_budget_bytes"] = memory.capacity();
  return p;
}

Fields RouteContext::problem_headers(const api::Problem& problem) const {
  Fields h;
  // 507: space comes back as finished jobs expire.
  if (problem.status == api::http::kServiceUnavailable ||
      problem.status == api::http::kInsufficientStorage ||
      problem.status == api::http::kTooManyRequests)
    h.emplace("Retry-After", std::to_string(config.retry_after_seconds));
  if (problem.status == api::http::kUnauthorized) h.emplace("WWW-Authenticate", "Bearer");
  if (problem.status == api::http::kMethodNotAllowed && problem.extensions.contains("allow"))
    h.emplace("Allow", problem.extensions["allow"].get<std::string>());
  return h;
}

void RouteContext::respond(HttpAnswer& res, const api::Problem& problem) const {
  for (const auto& [name, value] : problem_headers(problem)) res.set_header(name, value);
  send_problem(res, problem);
}

std::string RouteContext::tenant(const HttpRequest& req) const {
  if (config.api_keys.empty() || !jobs) return {};
  // authorized() let it through: one of the keys.
  return jobs->tenant_of(presented_key(req).value_or(std::string()));
}

bool RouteContext::authorized(const HttpRequest& req) const {
  if (config.api_keys.empty()) return true;
  const Route* route = find_route(req.path);
  // The page is public: the API calls it makes carry the key the user types in.
  if (route &&
      (route->kind == RouteKind::Page || std::string_view(route->path) == "/healthz" ||
       std::string_view(route->path) == "/readyz" || std::string_view(route->path) == "/metrics"))
    return true;
  const std::optional<std::string> given = presented_key(req);
  if (!given) return false;
  bool ok = false;
  for (const std::string& key : config.api_keys) ok |= same_secret(*given, key);  // no early exit
  return ok;
}

}  // namespace stlrefine::server
