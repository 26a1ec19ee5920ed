// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "deploy_files.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <stdexcept>

namespace stlrefine::test {

namespace {

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return {};
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> string_array(const std::string& json_text, const std::string& what) {
  const nlohmann::json j = nlohmann::json::parse(json_text, nullptr, false);
  if (!j.is_array())
    throw std::runtime_error(what + " is not a JSON array of strings: " + json_text);
  std::vector<std::string> out;
  for (const auto& item : j) {
    if (!item.is_string()) throw std::runtime_error(what + " holds a non-string: " + json_text);
    out.push_back(item.get<std::string>());
  }
  return out;
}

// A YAML scalar without its quotes.
std::string unquote(const std::string& text) {
  if (text.size() >= 2 && text.front() == '"')
    return nlohmann::json::parse(text).get<std::string>();
  if (text.size() >= 2 && text.front() == '\'' && text.back() == '\'')
    return text.substr(1, text.size() - 2);
  return text;
}

// The line without a trailing comment (a # at its start or after a blank, outside quotes).
std::string strip_yaml_comment(const std::string& line) {
  char quote = 0;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quote) {
      if (c == '\\' && quote == '"')
        ++i;
      else if (c == quote)
        quote = 0;
    } else if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '#' && (i == 0 || line[i - 1] == ' ' || line[i - 1] == '\t')) {
      return line.substr(0, i);
    }
  }
  return line;
}

struct YamlLine {
  int indent;
  std::string text;  // trimmed
};

}  // namespace

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<DockerInstruction> final_stage(const std::string& dockerfile) {
  std::vector<DockerInstruction> stage;
  std::string pending;
  auto finish = [&stage](const std::string& text) {
    const std::string t = trim(text);
    if (t.empty()) return;
    const std::size_t space = t.find_first_of(" \t");
    DockerInstruction in;
    in.keyword = t.substr(0, space);
    std::transform(in.keyword.begin(), in.keyword.end(), in.keyword.begin(),
                   [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    in.arguments = space == std::string::npos ? "" : trim(t.substr(space));
    if (in.keyword == "FROM") stage.clear();
    stage.push_back(in);
  };
  for (const std::string& raw : lines_of(dockerfile)) {
    const std::string line = trim(raw);
    if (!line.empty() && line.front() == '#') continue;  // comments, also inside continuations
    if (!line.empty() && line.back() == '\\') {
      pending += line.substr(0, line.size() - 1) + " ";
      continue;
    }
    finish(pending + line);
    pending.clear();
  }
  finish(pending);
  return stage;
}

std::optional<std::string> instruction(const std::vector<DockerInstruction>& stage,
                                       const std::string& keyword) {
  std::optional<std::string> found;
  for (const DockerInstruction& in : stage)
    if (in.keyword == keyword) found = in.arguments;
  return found;
}

std::vector<std::string> exec_form(const std::string& arguments) {
  if (arguments.empty() || arguments.front() != '[')
    throw std::runtime_error("shell form (docker would run it under /bin/sh -c): " + arguments);
  return string_array(arguments, "exec form");
}

std::optional<YamlValue> yaml_get(const std::string& yaml, const std::vector<std::string>& path) {
  std::vector<YamlLine> lines;
  for (const std::string& raw : lines_of(yaml)) {
    const std::string line = strip_yaml_comment(raw);
    const std::string text = trim(line);
    if (text.empty() || text == "---") continue;
    lines.push_back({static_cast<int>(line.find_first_not_of(' ')), text});
  }
  std::size_t begin = 0, end = lines.size();
  std::string value;
  for (const std::string& key : path) {
    if (begin >= end) return std::nullopt;
    int child = lines[begin].indent;
    for (std::size_t i = begin; i < end; ++i) child = std::min(child, lines[i].indent);
    std::size_t at = end;
    for (std::size_t i = begin; i < end && at == end; ++i)
      if (lines[i].indent == child && lines[i].text.rfind(key + ":", 0) == 0) at = i;
    if (at == end) return std::nullopt;
    value = trim(lines[at].text.substr(key.size() + 1));
    // The key's block: deeper lines, and a block sequence's "- " items at the key's indent.
    std::size_t stop = at + 1;
    while (stop < end &&
           (lines[stop].indent > lines[at].indent ||
            (lines[stop].indent == lines[at].indent && lines[stop].text.rfind("- ", 0) == 0)))
      ++stop;
    begin = at + 1;
    end = stop;
  }
  YamlValue out;
  if (!value.empty() && value.front() == '[') {
    std::string flow = value;
    for (std::size_t i = begin; i < end; ++i) flow += " " + lines[i].text;
    out.items = string_array(flow, "flow sequence (write every item as a \"string\")");
    out.is_sequence = true;
  } else if (value.empty() && begin < end && lines[begin].text.rfind("- ", 0) == 0) {
    for (std::size_t i = begin; i < end; ++i) {
      if (lines[i].text.rfind("- ", 0) != 0)
        throw std::runtime_error("a block sequence item that is not a scalar: " + lines[i].text);
      out.items.push_back(unquote(trim(lines[i].text.substr(2))));
    }
    out.is_sequence = true;
  } else {
    out.scalar = unquote(value);
  }
  return out;
}

std::vector<std::string> container_argv(const std::string& dockerfile, const std::string& compose,
                                        const std::string& service) {
  const auto stage = final_stage(dockerfile);
  const std::optional<std::string> image_entrypoint = instruction(stage, "ENTRYPOINT");
  const std::optional<std::string> image_cmd = instruction(stage, "CMD");
  auto list = [&](const char* key) -> std::optional<std::vector<std::string>> {
    const auto v = yaml_get(compose, {"services", service, key});
    if (!v) return std::nullopt;
    if (!v->is_sequence)
      throw std::runtime_error(std::string("compose `") + key +
                               ":` is a string (split by shell rules); the tests read the list "
                               "form only");
    return v->items;
  };
  const auto entrypoint = list("entrypoint");
  const auto command = list("command");
  std::vector<std::string> argv =
      entrypoint ? *entrypoint
                 : (image_entrypoint ? exec_form(*image_entrypoint) : std::vector<std::string>{});
  if (command) {
    argv.insert(argv.end(), command->begin(), command->end());
  } else if (!entrypoint && image_cmd) {
    const auto cmd = exec_form(*image_cmd);
    argv.insert(argv.end(), cmd.begin(), cmd.end());
  }
  return argv;
}

std::optional<std::string> flag_value(const std::vector<std::string>& argv,
                                      const std::string& flag) {
  std::optional<std::string> found;
  for (std::size_t i = 0; i < argv.size(); ++i) {
    if (argv[i] == flag && i + 1 < argv.size()) found = argv[i + 1];
    if (argv[i].rfind(flag + "=", 0) == 0) found = argv[i].substr(flag.size() + 1);
  }
  return found;
}

std::vector<std::string> repeated_flags(const std::vector<std::string>& argv) {
  std::map<std::string, int> seen;
  std::vector<std::string> repeated;
  for (const std::string& a : argv) {
    if (a.rfind("--", 0) != 0) continue;
    const std::string name = a.substr(0, a.find('='));
    if (++seen[name] == 2) repeated.push_back(name);
  }
  return repeated;
}

bool set_flag(std::vector<std::string>& argv, const std::string& flag, const std::string& value) {
  bool found = false;
  for (std::size_t i = 0; i < argv.size(); ++i) {
    if (argv[i] == flag && i + 1 < argv.size()) {
      argv[i + 1] = value;
      found = true;
    } else if (argv[i].rfind(flag + "=", 0) == 0) {
      argv[i] = flag + "=" + value;
      found = true;
    }
  }
  return found;
}

namespace {

std::optional<std::pair<double, std::string>> nginx_number(const std::string& conf,
                                                           const std::string& directive) {
  const std::regex re("(^|[\\s;{])" + directive + "\\s+([0-9]+)([a-zA-Z]*)\\s*;");
  std::smatch m;
  if (!std::regex_search(conf, m, re)) return std::nullopt;
  std::string unit = m[3];
  std::transform(unit.begin(), unit.end(), unit.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return std::make_pair(std::stod(m[2]), unit);
}

}  // namespace

std::optional<double> nginx_seconds(const std::string& conf, const std::string& directive) {
  const auto n = nginx_number(conf, directive);
  if (!n) return std::nullopt;
  static const std::map<std::string, double> units = {{"", 1},   {"s", 1},    {"ms", 1e-3},
                                                      {"m", 60}, {"h", 3600}, {"d", 86400}};
  const auto unit = units.find(n->second);
  if (unit == units.end()) throw std::runtime_error(directive + ": unknown time unit " + n->second);
  return n->first * unit->second;
}

std::optional<double> nginx_bytes(const std::string& conf, const std::string& directive) {
  const auto n = nginx_number(conf, directive);
  if (!n) return std::nullopt;
  static const std::map<std::string, double> units = {
      {"", 1}, {"k", 1024.0}, {"m", 1024.0 * 1024}, {"g", 1024.0 * 1024 * 1024}};
  const auto unit = units.find(n->second);
  if (unit == units.end()) throw std::runtime_error(directive + ": unknown size unit " + n->second);
  return n->first * unit->second;
}

std::vector<std::pair<std::string, std::string>> unit_entries(const std::string& unit,
                                                              const std::string& section) {
  std::vector<std::pair<std::string, std::string>> entries;
  std::string current, pending;
  for (const std::string& raw : lines_of(unit)) {
    std::string line = trim(raw);
    if (pending.empty() && (line.empty() || line.front() == '#' || line.front() == ';')) continue;
    if (!line.empty() && line.back() == '\\') {
      pending += line.substr(0, line.size() - 1) + " ";
      continue;
    }
    line = pending + line;
    pending.clear();
    if (line.front() == '[') {
      current = line.substr(1, line.find(']') - 1);
      continue;
    }
    const std::size_t eq = line.find('=');
    if (current == section && eq != std::string::npos)
      entries.emplace_back(trim(line.substr(0, eq)), trim(line.substr(eq + 1)));
  }
  return entries;
}

std::optional<std::string> help_default(const std::string& help, const std::string& flag) {
  for (const std::string& raw : lines_of(help)) {
    const std::string line = trim(raw);
    if (line.rfind(flag + " ", 0) != 0) continue;
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos) return std::nullopt;
    return line.substr(eq + 1, line.find(' ', eq) - eq - 1);
  }
  return std::nullopt;
}

}  // namespace stlrefine::test
