// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// man/: every option the binaries' --help lists is in their man page, and every option the
// man page names exists, so the two cannot drift apart.

#include <gtest/gtest.h>

#include <filesystem>
#include <regex>
#include <set>
#include <sstream>

#include "deploy_files.h"
#include "subprocess.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

std::string help(std::vector<std::string> argv) {
  argv.push_back("--help");
  const ProcessResult r = run_process(argv, 20s);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.out;
}

// The options of a CLI11 help text: "  -o,--output TEXT ..." -> -o, --output.
std::set<std::string> help_options(const std::string& text) {
  std::set<std::string> options;
  std::istringstream in(text);
  const std::regex line(R"(^\s+(-[A-Za-z0-9](?:,|\s|$)|--[a-z0-9][a-z0-9-]*))");
  const std::regex name(R"(--?[A-Za-z0-9][a-z0-9-]*)");
  for (std::string l; std::getline(in, l);) {
    if (!std::regex_search(l, line)) continue;
    // The option's names are the first word ("-o,--output"); the rest is its type and help.
    const std::string names = l.substr(l.find('-')).substr(0, l.substr(l.find('-')).find(' '));
    for (std::sregex_iterator it(names.begin(), names.end(), name), end; it != end; ++it)
      options.insert(it->str());
  }
  return options;
}

// The man page's text with roff's \- as -.
std::string man_text(const std::string& page) {
  const std::string roff = read_text(fs::path(STLREFINE_SOURCE_DIR) / "man" / page);
  std::string text;
  for (std::size_t i = 0; i < roff.size(); ++i) {
    if (roff[i] == '\\' && i + 1 < roff.size() && roff[i + 1] == '-') continue;  // "\-" -> "-"
    text += roff[i];
  }
  return text;
}

// Options the man page names: --long anywhere, -x only as a .BR / .B item.
std::set<std::string> man_options(const std::string& text) {
  std::set<std::string> options;
  const std::regex long_option(R"((^|[^A-Za-z0-9-])(--[a-z0-9][a-z0-9-]*))");
  for (std::sregex_iterator it(text.begin(), text.end(), long_option), end; it != end; ++it)
    options.insert((*it)[2].str());
  const std::regex short_option(R"((^|\n)\.BR? (-[A-Za-z0-9])\b)");
  for (std::sregex_iterator it(text.begin(), text.end(), short_option), end; it != end; ++it)
    options.insert((*it)[2].str());
  return options;
}

// The subcommands a CLI11 help lists under "Subcommands:".
std::vector<std::string> subcommands(const std::string& text) {
  std::vector<std::string> names;
  const std::size_t at = text.find("Subcommands:");
  if (at == std::string::npos) return names;
  std::istringstream in(text.substr(at));
  std::string l;
  std::getline(in, l);
  while (std::getline(in, l) && !l.empty()) {
    std::istringstream words(l);
    std::string word;
    if (words >> word) names.push_back(word);
  }
  return names;
}

void expect_documented(const std::set<std::string>& in_help, const std::string& page) {
  const std::set<std::string> in_man = man_options(man_text(page));
  for (const std::string& option : in_help)
    EXPECT_TRUE(in_man.count(option)) << option << " is in --help but not in man/" << page;
  for (const std::string& option : in_man)
    EXPECT_TRUE(in_help.count(option)) << option << " is in man/" << page << " but in no --help";
}

TEST(ManPages, StlrefinedPageHasEveryOptionOfItsHelp) {
  const std::set<std::string> options = help_options(help({STLREFINED}));
  ASSERT_GT(options.size(), 20u);  // the parse found the options
  expect_documented(options, "stlrefined.8");
}

// The text of a man page's ".SS name" subsection, up to the next .SS or .SH.
std::string subsection(const std::string& text, const std::string& name) {
  const std::size_t at = text.find("\n.SS " + name + "\n");
  if (at == std::string::npos) return {};
  const std::size_t body = at + 6 + name.size();
  return text.substr(body, std::min(text.find("\n.SS ", body), text.find("\n.SH ", body)) - body);
}

// Each command's options in its own subsection, the options every command has (--help) in
// "All commands"; no option in the page that no --help has.
TEST(ManPages, StlrefinePageHasEveryCommandAndOptionOfItsHelp) {
  const std::string top = help({STLREFINE_CLI});
  const std::set<std::string> common = help_options(top);
  const std::vector<std::string> commands = subcommands(top);
  ASSERT_GE(commands.size(), 4u);
  const std::string text = man_text("stlrefine.1");
  const std::set<std::string> in_common = man_options(subsection(text, "All commands"));
  for (const std::string& option : common)
    EXPECT_TRUE(in_common.count(option)) << option << " is not under \"All commands\"";
  std::set<std::string> all = common;
  for (const std::string& command : commands) {
    EXPECT_NE(text.find(".B " + command + "\n"), std::string::npos)
        << "command " << command << " has no entry in man/stlrefine.1";
    std::set<std::string> own = help_options(help({STLREFINE_CLI, command}));
    all.insert(own.begin(), own.end());
    for (const std::string& option : common) own.erase(option);
    ASSERT_FALSE(own.empty()) << command;
    const std::set<std::string> in_man = man_options(subsection(text, command));
    for (const std::string& option : own)
      EXPECT_TRUE(in_man.count(option))
          << option << " is in `stlrefine " << command << " --help` but not in its man section";
    for (const std::string& option : in_man)
      EXPECT_TRUE(own.count(option))
          << option << " is in the man section of " << command << " but not in its --help";
  }
  for (const std::string& option : man_options(text))
    EXPECT_TRUE(all.count(option)) << option << " is in man/stlrefine.1 but in no --help";
}

}  // namespace
}  // namespace stlrefine::test
