// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Reading the deployment files (docker/Dockerfile, docker/compose.yaml, docker/nginx.conf,
// packaging/stlrefined.service.in) the way docker, compose, nginx and systemd read them, as
// far as the tests need: the daemon's argument vector and the numbers that must agree.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stlrefine::test {

//! The instructions of a Dockerfile's last stage, continuation lines joined, comments
//! dropped: {"ENTRYPOINT", "[...]"}, ...
struct DockerInstruction {
  std::string keyword;  //!< upper case
  std::string arguments;
};
std::vector<DockerInstruction> final_stage(const std::string& dockerfile);

//! The value of the last `keyword` instruction of the stage, if any.
std::optional<std::string> instruction(const std::vector<DockerInstruction>& stage,
                                       const std::string& keyword);

//! An exec-form (JSON array) ENTRYPOINT / CMD. \throw std::runtime_error for the shell
//! form, which docker runs under /bin/sh -c.
std::vector<std::string> exec_form(const std::string& arguments);

//! The value at `path` of a YAML document restricted to block mappings whose values are
//! scalars, flow sequences (JSON-like, may span lines) or block sequences of scalars: what
//! compose files use. Nullopt when a key is missing.
struct YamlValue {
  std::string scalar;              //!< the text after "key:", empty for a nested block
  std::vector<std::string> items;  //!< a sequence's items (flow or block)
  bool is_sequence = false;
};
std::optional<YamlValue> yaml_get(const std::string& yaml, const std::vector<std::string>& path);

//! What docker runs for a compose service built from `dockerfile`: the entrypoint (the
//! service's, else the image's) followed by the service's `command:` (else the image's CMD,
//! unless the service set its own entrypoint, which resets it).
std::vector<std::string> container_argv(const std::string& dockerfile, const std::string& compose,
                                        const std::string& service);

//! The value following `flag` (as `--flag value` or `--flag=value`), if present.
std::optional<std::string> flag_value(const std::vector<std::string>& argv,
                                      const std::string& flag);

//! Flags (`--x`) given more than once.
std::vector<std::string> repeated_flags(const std::vector<std::string>& argv);

//! Replaces the value of `flag` (both spellings); false when the flag is absent.
bool set_flag(std::vector<std::string>& argv, const std::string& flag, const std::string& value);

//! An nginx time ("960s", "16m", "900") in seconds, of the first `directive` in `conf`.
std::optional<double> nginx_seconds(const std::string& conf, const std::string& directive);

//! An nginx size ("256m", "1g", "4096k") in bytes, of the first `directive` in `conf`.
std::optional<double> nginx_bytes(const std::string& conf, const std::string& directive);

//! `Key=value` lines of a systemd unit's section (all of them, in order).
std::vector<std::pair<std::string, std::string>> unit_entries(const std::string& unit,
                                                              const std::string& section);

//! A default shown by CLI11 in --help ("--request-deadline FLOAT:... =900 (Env:...)").
std::optional<std::string> help_default(const std::string& help, const std::string& flag);

std::string read_text(const std::filesystem::path& path);

}  // namespace stlrefine::test
