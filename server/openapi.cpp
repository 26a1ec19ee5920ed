// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The OpenAPI 3 document of the daemon. Routes come from the daemon's own route table and
// parameters from api/'s parameter table (api/param_table.h), so the document cannot list a
// route or parameter the server does not serve; a parameter without a description fails the
// OpenAPI test (tests/server/jobs_test.cpp), so it cannot be served undocumented either.

#include <cctype>
#include <nlohmann/json.hpp>
#include <string>

#include "api/param_table.h"
#include "api/params.h"
#include "core/schemes/registry.h"
#include "server/daemon.h"
#include "slicer/writers.h"

namespace stlrefine::server {

namespace {

using Json = nlohmann::ordered_json;

Json problem_response(const char* description) {
  return {
      {"description", description},
      {"content",
       {{"application/problem+json", {{"schema", {{"$ref", "#/components/schemas/Problem"}}}}}}}};
}

// The type, range and default of a row (api/param_table.h).
Json parameter_schema(const api::ParamRow& row) {
  Json schema = {{"type", api::to_string(row.type)}};
  const auto number = [&](double value) -> Json {
    if (row.type == api::ParamType::Integer) return static_cast<long long>(value);
    return value;
  };
  if (row.minimum) schema["minimum"] = number(*row.minimum);
  if (row.minimum && row.exclusive_minimum) schema["exclusiveMinimum"] = true;  // OpenAPI 3.0
  if (row.maximum) schema["maximum"] = number(*row.maximum);
  if (const std::string value = api::default_text(row); !value.empty()) {
    if (row.type == api::ParamType::String)
      schema["default"] = value;
    else
      schema["default"] = number(std::stod(value));
  }
  return schema;
}

Json query_parameters(const std::vector<std::string_view>& names, api::RequestKind kind) {
  Json params = Json::array();
  for (std::string_view name : names) {
    const api::ParamRow* row = api::find_param(name);
    Json p;
    p["name"] = name;
    p["in"] = "query";
    p["required"] = false;
    if (row && !row->description.empty()) {
      p["description"] = row->description;
      p["schema"] = parameter_schema(*row);
    } else {
      p["schema"] = {{"type", "string"}};  // undocumented: the OpenAPI test fails on this
    }
    if (const std::string_view replacement = api::replaced_by(kind, name); !replacement.empty())
      p["deprecated"] = true;  // the description names the replacement
    if (name == "scheme") {
      Json names_json = Json::array();
      for (std::string_view s : scheme_names()) names_json.push_back(s);
      p["schema"]["enum"] = names_json;
    }
    params.push_back(p);
  }
  return params;
}

Json stl_body() {
  return {{"required", true},
          {"description",
           "A mesh file, sent with a Content-Length: STL (binary or ASCII), OBJ, PLY (ASCII or "
           "binary) or 3MF, told apart by content (a 3MF's unit is applied); as the body, or as "
           "the one part named `file` of a multipart/form-data body (curl -F file=@part.stl; "
           "the part's filename names the downloads). Other form fields are refused (400 naming "
           "them): parameters go in the query string. A zip of mesh files (not a 3MF) is one "
           "job with one result per part on POST /v1/jobs (422 `archive_needs_job` elsewhere); "
           "a hostile zip is a 422 naming the `entry`."},
          {"content",
           {{"model/stl", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"model/3mf", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"model/obj", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"model/x-ply", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"application/x-ply", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"application/zip", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"application/octet-stream", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
            {"multipart/form-data",
             {{"schema",
               {{"type", "object"},
                {"required", {"file"}},
                {"properties", {{"file", {{"type", "string"}, {"format", "binary"}}}}}}}}}}}};
}

// The raw body's file name (a multipart part carries its own).
Json disposition_parameter() {
  return {{"name", "Content-Disposition"},
          {"in", "header"},
          {"required", false},
          {"description",
           "The file's name for a raw body (`attachment; filename=\"part.stl\"`): the "
           "downloads are named after it (part_refined.stl)."},
          {"schema", {{"type", "string"}}}};
}

Json header(const char* description, const char* type = "string") {
  return {{"description", description}, {"schema", {{"type", type}}}};
}

// Busy and shutting-down answers say when to come back.
// The same as a query parameter, for clients that cannot set a header.
Json filename_parameter() {
  return {{"name", "filename"},
          {"in", "query"},
          {"required", false},
          {"description",
           "The file's name when the body does not carry one (no multipart filename, no "
           "Content-Disposition header): the downloads are named after it."},
          {"schema", {{"type", "string"}}}};
}

// Every download: `attachment; filename="part_refined.stl"` (RFC 6266, `filename*` for a
// name that is not ASCII).
Json download_header() {
  return header(
      "attachment; filename=\"<name>_refined.stl\" (or _refined.zip, _slices.cli, ...), after "
      "the uploaded file's name (`part` without one); filename*=UTF-8''... when it is not "
      "ASCII.");
}

Json retry_later(const char* description) {
  Json r = problem_response(description);
  r["headers"]["Retry-After"] = header("Seconds to wait before trying again.", "integer");
  return r;
}

Json common_errors(Json responses, bool with_body) {
  responses["400"] = problem_response("A parameter is malformed or out of range.");
  if (with_body) {
    responses["411"] = problem_response("No Content-Length, or a Transfer-Encoding.");
    responses["413"] = problem_response("The body is larger than the server accepts.");
    responses["415"] = problem_response("Unsupported Content-Type or Content-Encoding.");
    responses["422"] = problem_response("Not a usable STL, or over a budget.");
  }
  if (with_body) responses["408"] = problem_response("The body stalled or arrived too slowly.");
  responses["431"] = problem_response("Header fields too large or too many.");
  responses["401"] = problem_response("An API key is required.");
  responses["503"] = retry_later(
      "Busy (every compute slot taken, or not enough memory next to the running requests), "
      "overloaded or shutting down; see Retry-After.");
  if (with_body) {
    responses["422"] = problem_response(
        "Not a usable STL, or over a budget: faces (max_faces), layers, contour points, or the "
        "memory one request may have (title \"Memory budget exceeded\", field names the "
        "parameter to lower, predicted_bytes, memory_budget_bytes); or nothing to make from "
        "this part (a slice without a layer: field layer_height or slice).");
    responses["504"] =
        problem_response("The computation ran longer than the server's request deadline.");
  }
  return responses;
}

Json binary_response(const char* description, std::initializer_list<const char*> types) {
  Json content;
  for (const char* type : types)
    content[type] = {{"schema", {{"type", "string"}, {"format", "binary"}}}};
  return {{"description", description}, {"content", std::move(content)}};
}

Json binary_response(const char* description, const char* type) {
  return binary_response(description, {type});
}

// The media types of the slice formats (slicer/writers.cpp), without parameters.
Json json_response(const char* description) {
  return {{"description", description},
          {"content", {{"application/json", {{"schema", {{"type", "object"}}}}}}}};
}

Json operation(const char* summary, Json responses) {
  return {{"summary", summary}, {"responses", std::move(responses)}};
}

// A stable operationId per path and method ("refine", "getJob"), for generated clients.
std::string operation_id(const std::string& path, const std::string& method) {
  static const std::pair<const char*, const char*> kIds[] = {
      {"post /v1/refine", "refine"},
      {"post /v1/slice", "slice"},
      {"post /v1/info", "info"},
      {"post /v1/jobs", "submitJob"},
      {"get /v1/jobs", "listJobs"},
      {"get /v1/jobs/{id}/events", "followJob"},
      {"get /v1/jobs/{id}", "getJob"},
      {"delete /v1/jobs/{id}", "cancelJob"},
      {"get /v1/jobs/{id}/{file}", "downloadJobFile"},
      {"get /v1/openapi.json", "getOpenApi"},
      {"get /v1/version", "getVersion"},
      {"get /metrics", "getMetrics"},
      {"get /healthz", "getHealth"},
      {"get /readyz", "getReady"},
      {"get /", "getPage"},
      {"get /assets/{file}", "getAsset"},
  };
  const std::string key = method + " " + path;
  for (const auto& [k, id] : kIds)
    if (key == k) return id;
  // A route added without a name here: method + the path's words ("getV1Things").
  std::string id = method;
  bool upper = true;
  for (char c : path) {
    if (std::isalnum(static_cast<unsigned char>(c))) {
      id += upper ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
      upper = false;
    } else {
      upper = true;
    }
  }
  return id;
}

// Routes answered without an API key (Daemon::Impl::authorized).
bool public_route(const std::string& path) {
  return path == "/" || path == "/assets/{file}" || path == "/healthz" || path == "/readyz" ||
         path == "/metrics";
}

Json build() {
  const api::RequestLimits limits;  // the daemon's names (no `threads`)
  Json paths;
  for (const RouteInfo& route : served_routes()) {
    Json item;
    const std::string& p = route.path;
    if (p == "/v1/refine" || p == "/v1/jobs") {
      Json op = operation(
          p == "/v1/refine" ? "Refine an STL (and optionally slice it)" : "Queue a refinement job",
          common_errors(
              p == "/v1/refine"
                  ? Json{{"200", binary_response("The refined mesh: binary STL, or 3MF with "
                                                 "mesh_format=3mf or Accept: model/3mf (a zip "
                                                 "with contours and report when sliced).",
                                                 {"model/stl", "model/3mf", "application/zip"})}}
                  : Json{{"202", json_response("The queued job; "
                                               "Location names it.")}},
              true));
      if (p == "/v1/refine") {
        op["responses"]["200"]["headers"]["X-Stlrefine-Report"] =
            header("The refine report (JSON, one line).");
        op["responses"]["200"]["headers"]["Content-Disposition"] = download_header();
      } else {
        op["responses"]["202"]["headers"]["Location"] = header("The job's URL: /v1/jobs/{id}.");
      }
      if (p == "/v1/jobs")
        op["responses"]["507"] = problem_response(
            "No room in the data directory for the input and the predicted results.");
      op["parameters"] =
          query_parameters(api::refine_param_names(limits), api::RequestKind::Refine);
      if (p == "/v1/jobs")
        op["parameters"].push_back(
            {{"name", "callback_url"},
             {"in", "query"},
             {"required", false},
             {"description",
              "http(s) URL POSTed the job's JSON when it ends, with X-Stlrefine-Timestamp: <unix "
              "seconds> and X-Stlrefine-Signature: sha256=<HMAC-SHA256 hex of "
              "\"<timestamp>.<body>\"> under the tenant's callback key (HMAC-SHA256 hex of the "
              "tenant id under the server's --callback-secret; stlrefined --print-callback-key); "
              "retried with back-off. Only hosts on the server's --callback-allow list, and no "
              "loopback, link-local or private address unless the list names it (checked on "
              "the resolved addresses): otherwise 400."},
             {"schema", {{"type", "string"}, {"format", "uri"}, {"maxLength", 2048}}}});
      op["parameters"].push_back(disposition_parameter());
      op["parameters"].push_back(filename_parameter());
      op["requestBody"] = stl_body();
      item["post"] = op;
      if (p == "/v1/jobs") {
        const auto query = [](const char* name, const char* description, Json schema) {
          return Json{{"name", name},
                      {"in", "query"},
                      {"required", false},
                      {"description", description},
                      {"schema", std::move(schema)}};
        };
        Json list = operation(
            "The caller's jobs, newest first, a page at a time",
            {{"200", json_response("`jobs` (each as GET /v1/jobs/{id}), `links.next` (and "
                                   "`next_cursor`) while more follow.")},
             {"400", problem_response("A malformed or unknown parameter (`field` names it).")},
             {"401", problem_response("An API key is required.")}});
        list["parameters"] = Json::array(
            {query("limit", "Jobs per page.",
                   {{"type", "integer"}, {"minimum", 1}, {"maximum", 100}, {"default", 20}}),
             query("cursor", "Where the page starts: the `next_cursor` of the page before.",
                   {{"type", "string"}}),
             query("state", "Only jobs in this state.",
                   {{"type", "string"},
                    {"enum", {"queued", "running", "done", "failed", "cancelled"}}})});
        item["get"] = list;
      }
    } else if (p == "/v1/jobs/{id}/events") {
      item["parameters"] = Json::array(
          {{{"name", "id"}, {"in", "path"}, {"required", true}, {"schema", {{"type", "string"}}}}});
      item["get"] = operation(
          "Follow a job as server-sent events",
          {{"200",
            {{"description",
              "`progress` events (data: the job's JSON) at each change of state, progress or "
              "stage, `: keep-alive` comments, and a final `end` event with the job's JSON "
              "once it has ended (or `timeout` at the server's request deadline); the stream "
              "then closes."},
             {"content", {{"text/event-stream", {{"schema", {{"type", "string"}}}}}}}}},
           {"404", problem_response("Unknown job.")},
           {"410", problem_response("Removed after retention.")},
           {"429", problem_response("Too many event streams open (--max-event-streams, "
                                    "--max-event-streams-per-tenant); see Retry-After.")}});
      item["get"]["responses"]["429"]["headers"]["Retry-After"] =
          header("Seconds to wait before trying again.", "integer");
    } else if (p == "/v1/slice") {
      Json op = operation(
          "Slice an STL into layer contours",
          common_errors(
              {{"200", binary_response("The contours, in the format asked for (report=zip: a zip "
                                       "with them and report.json).",
                                       {"application/json", "image/svg+xml", "text/plain",
                                        "application/octet-stream", "application/zip"})}},
              true));
      op["responses"]["200"]["headers"]["X-Stlrefine-Report"] =
          header("The slice report (JSON, one line).");
      op["responses"]["200"]["headers"]["Content-Disposition"] = download_header();
      op["parameters"] = query_parameters(api::slice_param_names(limits), api::RequestKind::Slice);
      op["parameters"].push_back(disposition_parameter());
      op["parameters"].push_back(filename_parameter());
      op["requestBody"] = stl_body();
      item["post"] = op;
    } else if (p == "/v1/info") {
      Json op = operation("Report on an STL: ingest, features, curvature",
                          common_errors({{"200", json_response("The report.")}}, true));
      op["parameters"] = query_parameters(api::info_param_names(), api::RequestKind::Info);
      op["requestBody"] = stl_body();
      item["post"] = op;
    } else if (p == "/v1/jobs/{id}") {
      const Json id = Json::array(
          {{{"name", "id"}, {"in", "path"}, {"required", true}, {"schema", {{"type", "string"}}}}});
      item["parameters"] = id;
      item["get"] =
          operation("A job's state, progress, timings, report and links",
                    {{"200", json_response("The job.")},
                     {"404", problem_response("Unknown job.")},
                     {"410", json_response("The job's results were removed after retention.")}});
      item["delete"] = operation("Cancel a queued or running job; delete a finished job's results",
                                 {{"200", json_response("The job; `cancel` says `cancelled` "
                                                        "(it will end cancelled) or `too_late` "
                                                        "(it had ended; results deleted).")},
                                  {"404", problem_response("Unknown job.")},
                                  {"410", json_response("Already removed.")}});
    } else if (p == "/v1/jobs/{id}/{file}") {
      Json params = Json::array(
          {{{"name", "id"}, {"in", "path"}, {"required", true}, {"schema", {{"type", "string"}}}},
           {{"name", "file"},
            {"in", "path"},
            {"required", true},
            {"schema",
             {{"type", "string"},
              {"description",
               "result.stl (result.3mf with mesh_format=3mf), report.json, contours.<ext>; a zip "
               "job: result.zip and each part's part<k>.stl|3mf and part<k>.contours.<ext> (the "
               "job's `parts` links)"},
              {"pattern",
               "^(result\\.(stl|3mf|zip)|report\\.json|contours\\.(json|svg|cli)|"
               "part[1-9][0-9]{0,5}"
               "\\.(stl|3mf|contours\\.(json|svg|cli)))$"}}}}});
      item["parameters"] = params;
      Json download = operation(
          "Download a result of a done job",
          {{"200", binary_response("The file.",
                                   {"model/stl", "model/3mf", "application/zip", "application/json",
                                    "image/svg+xml", "text/plain", "application/octet-stream"})},
           {"206",
            binary_response("One byte range of the file (Range).", "application/octet-stream")},
           {"416", problem_response("The Range starts past the end.")},
           {"404", problem_response("Unknown job or no such result.")},
           {"409", problem_response("The job is not done.")},
           {"410", problem_response("Removed after retention.")}});
      download["responses"]["200"]["headers"]["Content-Disposition"] = download_header();
      item["get"] = download;
    } else if (p == "/v1/openapi.json") {
      item["get"] = operation("This document", {{"200", json_response("OpenAPI 3.0.3")}});
    } else if (p == "/v1/version") {
      item["get"] =
          operation("This build: version, API version, compiler, build type, the schemes it serves",
                    {{"200", json_response("The build.")}});
    } else if (p == "/metrics") {
      item["get"] =
          operation("Prometheus metrics",
                    {{"200",
                      {{"description", "Text format 0.0.4"},
                       {"content", {{"text/plain", {{"schema", {{"type", "string"}}}}}}}}}});
    } else if (p == "/healthz") {
      item["get"] = operation("Liveness", {{"200", json_response("Alive.")}});
    } else if (p == "/readyz") {
      item["get"] =
          operation("Readiness: 503 while shutting down or with no free slot",
                    {{"200", json_response("Ready.")}, {"503", problem_response("Not ready.")}});
    } else if (p == "/") {
      item["get"] = operation(
          "The web page: upload an STL, run a job, view the part and its layers, download",
          {{"200",
            {{"description", "The page (HTML). ETag and Cache-Control: no-cache."},
             {"content", {{"text/html", {{"schema", {{"type", "string"}}}}}}}}},
           {"304", {{"description", "Not modified (If-None-Match)."}}},
           {"404", problem_response("The daemon was built without the page (page-not-built).")}});
    } else if (p == "/assets/{file}") {
      item["parameters"] = Json::array({{{"name", "file"},
                                         {"in", "path"},
                                         {"required", true},
                                         {"description",
                                          "A file the page loads (app.js, "
                                          "three.module.js, ...)."},
                                         {"schema", {{"type", "string"}}}}});
      item["get"] =
          operation("A script or style sheet of the web page, embedded at build time",
                    {{"200", binary_response("The file (text/javascript, text/css, ...).",
                                             "application/octet-stream")},
                     {"304", {{"description", "Not modified (If-None-Match)."}}},
                     {"404", problem_response("No such file, or the page was not built.")}});
    } else {
      item["get"] = operation(route.path.c_str(), {{"200", {{"description", "OK"}}}});
    }
    for (auto& [method, op] : item.items()) {
      if (method == "parameters") continue;
      op["operationId"] = operation_id(p, method);
      if (public_route(p)) op["security"] = Json::array();  // no key needed
      op["responses"]["default"] = problem_response("Any other error, as a problem.");
    }
    paths[p] = item;
  }

  Json doc;
  doc["openapi"] = "3.0.3";
  doc["info"] = {{"title", "stlrefine"},
                 {"version", "1"},
                 {"description",
                  "Refines STL meshes with interpolatory subdivision and slices them into layer "
                  "contours. Every error is an RFC 9457 problem; every answer has an "
                  "X-Request-Id."}};
  doc["paths"] = paths;
  doc["components"]["schemas"]["Problem"] = {{"type", "object"},
                                             {"properties",
                                              {{"type", {{"type", "string"}}},
                                               {"title", {{"type", "string"}}},
                                               {"status", {{"type", "integer"}}},
                                               {"detail", {{"type", "string"}}},
                                               {"field", {{"type", "string"}}}}}};
  doc["components"]["securitySchemes"]["bearer"] = {
      {"type", "http"},
      {"scheme", "bearer"},
      {"description", "Only when the server is started with API keys (--api-key-file)."}};
  doc["components"]["securitySchemes"]["apiKey"] = {
      {"type", "apiKey"},
      {"in", "header"},
      {"name", "X-Api-Key"},
      {"description", "The same key as the bearer scheme, in the header API gateways use."}};
  // The key applies to every operation but the public ones (their own empty `security`);
  // either scheme will do; a server without keys ignores them.
  doc["security"] = Json::array({{{"bearer", Json::array()}}, {{"apiKey", Json::array()}}});
  doc["servers"] = Json::array({{{"url", "/"}, {"description", "This server."}}});
  return doc;
}

}  // namespace

const std::string& openapi_document() {
  static const std::string text = build().dump(2) + "\n";
  return text;
}

bool documented_parameter(const std::string& name) {
  const api::ParamRow* row = api::find_param(name);
  return row && !row->description.empty();
}

}  // namespace stlrefine::server
