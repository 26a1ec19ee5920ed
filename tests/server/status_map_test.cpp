// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// server/ sets no HTTP status by number: statuses are named in api/problem.h (api::http)
// and problems made by its named constructors, so the map from error to HTTP is in one
// place. This greps the sources of server/ for a status number in code (comments and
// string literals, such as the OpenAPI document's response keys, do not count).

#include <gtest/gtest.h>

#include <cctype>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace stlrefine::test {
namespace {

namespace fs = std::filesystem;

// The code of a C++ source: comments and string and character literals blanked out (line
// breaks kept, so line numbers stay).
std::string code_of(const std::string& text) {
  std::string out = text;
  std::size_t i = 0;
  const auto blank = [&](std::size_t from, std::size_t to) {
    for (std::size_t k = from; k < to && k < out.size(); ++k)
      if (out[k] != '\n') out[k] = ' ';
  };
  while (i < text.size()) {
    if (text.compare(i, 2, "//") == 0) {
      const std::size_t end = text.find('\n', i);
      blank(i, end == std::string::npos ? text.size() : end);
      i = end == std::string::npos ? text.size() : end;
    } else if (text.compare(i, 2, "/*") == 0) {
      const std::size_t end = text.find("*/", i + 2);
      const std::size_t stop = end == std::string::npos ? text.size() : end + 2;
      blank(i, stop);
      i = stop;
    } else if (text.compare(i, 2, "R\"") == 0) {
      const std::size_t open = text.find('(', i);
      std::string close(1, ')');
      close.append(text, i + 2, open - i - 2);
      close.push_back('"');
      const std::size_t end = text.find(close, open);
      const std::size_t stop = end == std::string::npos ? text.size() : end + close.size();
      blank(i, stop);
      i = stop;
    } else if (text[i] == '\'' && i > 0 && std::isxdigit(static_cast<unsigned char>(text[i - 1]))) {
      ++i;  // a digit separator: 200'000'000
    } else if (text[i] == '"' || text[i] == '\'') {
      const char quote = text[i];
      std::size_t k = i + 1;
      while (k < text.size() && text[k] != quote) k += text[k] == '\\' ? 2 : 1;
      blank(i, k + 1);
      i = k + 1;
    } else {
      ++i;
    }
  }
  return out;
}

// "file:line: text" of every status number in the code of `text`.
std::vector<std::string> literal_statuses(const std::string& name, const std::string& text) {
  // The statuses an HTTP server answers with (RFC 9110) and the access log's 499.
  static const std::set<int> kStatuses = [] {
    std::set<int> s{200, 201, 202, 204, 206, 301, 302, 303, 304, 307, 308, 451, 499};
    for (int v = 400; v <= 431; ++v) s.insert(v);
    for (int v = 500; v <= 511; ++v) s.insert(v);
    return s;
  }();
  static const std::regex kNumber(R"((^|[^0-9A-Za-z_.'])([1-5][0-9][0-9])(?![0-9A-Za-z_.']))");
  std::vector<std::string> hits;
  std::istringstream lines(code_of(text));
  std::string line;
  for (int n = 1; std::getline(lines, line); ++n)
    for (std::sregex_iterator m(line.begin(), line.end(), kNumber), end; m != end; ++m)
      if (kStatuses.count(std::stoi((*m)[2].str())))
        hits.push_back(name + ":" + std::to_string(n) + ": " + line);
  return hits;
}

TEST(StatusMap, TheScannerFindsAStatusInCodeOnly) {
  EXPECT_EQ(literal_statuses("x", "res.status = 404;\n").size(), 1u);
  EXPECT_EQ(literal_statuses("x", "return make_problem(503, \"busy\", d);\n").size(), 1u);
  EXPECT_EQ(literal_statuses("x", "HeadError{400, \"bad-request\", d};\n").size(), 1u);
  EXPECT_TRUE(literal_statuses("x", "// a 404 here\nauto s = \"413\"; /* 500 */\n").empty());
  EXPECT_TRUE(literal_statuses("x", "char host[256]; int kMax = 120; f(x, 50, 1000);\n").empty());
  EXPECT_TRUE(literal_statuses("x", "res.status = api::http::kNotFound;\n").empty());
  EXPECT_TRUE(literal_statuses("x", "timespec t{0, 200'000'000}; char c = '4';\n").empty());
}

TEST(StatusMap, ServerSetsNoLiteralStatus) {
  // The source tree: the examples directory's parent.
  const fs::path server = fs::path(STLREFINE_EXAMPLES_DIR).parent_path() / "server";
  ASSERT_TRUE(fs::is_directory(server)) << server;
  std::vector<std::string> hits;
  int files = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(server)) {
    const std::string ext = e.path().extension().string();
    if (ext != ".cpp" && ext != ".h") continue;
    ++files;
    std::ifstream in(e.path(), std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    for (std::string& hit : literal_statuses(e.path().filename().string(), text.str()))
      hits.push_back(std::move(hit));
  }
  EXPECT_GT(files, 10);
  EXPECT_TRUE(hits.empty()) << "name the status (api::http) or use a named problem "
                               "(api/problem.h):\n"
                            << [&] {
                                 std::string all;
                                 for (const std::string& h : hits) all += h + "\n";
                                 return all;
                               }();
}

}  // namespace
}  // namespace stlrefine::test
