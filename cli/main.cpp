// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine: the command-line front end. It validates parameters with the daemon's code
// (api/params) and runs the daemon's pipeline (api/pipeline), on files.
//
//   stlrefine info IN.stl [--crease-angle auto|DEG] [--weld-tolerance T] [--curvature OUT.csv]
//   stlrefine refine IN.stl -o OUT.stl [--scheme butterfly] [--levels 1]
//                    [--crease-angle auto|DEG] [--max-faces N] [--threads N]
//                    [--weld-tolerance T] [--ascii]
//                    [--adaptive-tol MM] [--adaptive-angle DEG] [--max-level L]
//                    [--alpha A] [--alpha-features A]
//                    [--kappa K] [--ramp-steps N]
//                    [--report R.json]
//                    [--layer-height H --slice-out CONTOURS [--slice-format
//                    json|svg|cli|cli-binary]]
//   stlrefine spectrum --scheme S --valence N|A..B [--format lines|table] [--count K]
//                      [--kappa K] [--alpha A] [--alpha-features A] [--unmodified] [--curve]
//                      [--markdown] [-o OUT]
//   stlrefine slice IN.stl -o OUT [--layer-height 0.1] [--format json|svg|cli|cli-binary]
//                   [--z-min Z] [--z-max Z] [--heights a,b,c] [--max-layers N] [--threads N]
//                   [--weld-tolerance T] [--report R.json]
//
// IN may be `-` for stdin and any output `-` for stdout (`stlrefine refine - -o - < a.stl >
// b.stl`), one output at most: then stdout carries only it, every message goes to stderr.
// A file is replaced atomically; stdout cannot be, so a failed run may leave part of it.
//
// Exit codes (kExit* below): 0 success; 2 bad usage or parameter; 3 the input file cannot
// be read or is not a usable STL; 4 the face or layer budget would be exceeded; 1 anything else
// (an internal error, or the output cannot be written).

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "api/param_table.h"
#include "api/params.h"
#include "api/pipeline.h"
#include "api/plan.h"
#include "cli/spectrum_report.h"
#include "core/error.h"
#include "core/io/atomic_file.h"
#include "core/io/stl.h"
#include "core/refine.h"
#include "core/schemes/registry.h"
#include "core/schemes/split4_host.h"

namespace {

using stlrefine::Error;
using stlrefine::ErrorCode;
namespace api = stlrefine::api;

constexpr int kExitOk = 0;
constexpr int kExitInternal = 1;
constexpr int kExitUsage = 2;
constexpr int kExitBadInput = 3;
constexpr int kExitBudget = 4;

//! A failure with its exit code, thrown inside a command and reported by main.
struct Failure {
  int exit_code;
  std::string message;
};

int exit_code(ErrorCode code) {
  switch (code) {
    case ErrorCode::InvalidParameter:
      return kExitUsage;
    case ErrorCode::MalformedStl:
      return kExitBadInput;
    case ErrorCode::NotTriangleMesh:
      return kExitBadInput;
    case ErrorCode::BudgetExceeded:
      return kExitBudget;
    case ErrorCode::NothingToMake:
      return kExitBadInput;
    case ErrorCode::Cancelled:
      return kExitInternal;
    case ErrorCode::Internal:
      return kExitInternal;
  }
  return kExitInternal;
}

// "crease_angle" -> "--crease-angle": errors name the option the user typed.
std::string option_name(std::string field) {
  for (char& c : field)
    if (c == '_') c = '-';
  return "--" + field;
}

Failure failure_from_error(const Error& e, const std::string& input) {
  std::string message;
  if ((e.code() == ErrorCode::InvalidParameter || e.code() == ErrorCode::NothingToMake) &&
      !e.field().empty()) {
    message = option_name(e.field()) + ": " + e.what();
  } else if (e.code() == ErrorCode::MalformedStl || e.code() == ErrorCode::NotTriangleMesh) {
    message = input == "-" ? "stdin" : input;
    if (e.line()) message += ":" + std::to_string(*e.line());
    message += ": ";
    message += (e.code() == ErrorCode::MalformedStl ? "malformed STL" : "not a triangle mesh");
    if (!e.reason().empty()) message += " (" + e.reason() + ")";
    if (e.byte_offset()) message += " at byte " + std::to_string(*e.byte_offset());
    message += ": " + std::string(e.what());
  } else {
    message = e.what();
  }
  return {exit_code(e.code()), message};
}

std::vector<std::uint8_t> read_file(const std::string& path) {
  if (path == "-") {
    std::vector<std::uint8_t> bytes;
    std::vector<std::uint8_t> buffer(1 << 16);
    for (std::size_t n; (n = std::fread(buffer.data(), 1, buffer.size(), stdin)) > 0;)
      bytes.insert(bytes.end(), buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(n));
    if (std::ferror(stdin))
      throw Failure{kExitBadInput, "cannot read stdin: " + std::string(std::strerror(errno))};
    return bytes;
  }
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Failure{kExitBadInput, path + " is a directory, not an STL file"};
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Failure{kExitBadInput, "cannot open " + path + ": " + std::strerror(errno)};
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) throw Failure{kExitBadInput, "cannot read " + path};
  return bytes;
}

// Written next to the target, synced and renamed over it (core/io/atomic_file.h): a failed
// run never leaves half a file, nor a changed one. "-" is stdout, written as it is made.
void write_file(const std::string& path,
                const std::function<void(const stlrefine::ByteSink&)>& produce) {
  if (path == "-") {
    const auto fail = [] {
      throw Failure{kExitInternal, "cannot write to stdout: " + std::string(std::strerror(errno))};
    };
    std::cout.flush();
    produce([&fail](std::string_view bytes) {
      if (std::fwrite(bytes.data(), 1, bytes.size(), stdout) != bytes.size()) fail();
    });
    if (std::fflush(stdout) != 0) fail();
    return;
  }
  try {
    stlrefine::write_file_atomically(path, produce);
  } catch (const stlrefine::FileError& e) {
    throw Failure{kExitInternal, e.what()};
  }
}

void write_file(const std::string& path, std::string_view bytes) {
  write_file(path, [bytes](const stlrefine::ByteSink& sink) { sink(bytes); });
}

// Outputs given as "-", by option name: at most one may be, else they would interleave on
// stdout. `stdout_taken` names what already writes there (info's report), if anything.
void check_stdout_outputs(
    std::initializer_list<std::pair<std::string_view, const std::string*>> outputs,
    std::string_view stdout_taken = {}) {
  std::string_view first = stdout_taken;
  for (const auto& [option, path] : outputs) {
    if (*path != "-") continue;
    if (!first.empty())
      throw Failure{kExitUsage,
                    std::string(option) + " -: stdout already carries " + std::string(first)};
    first = option;
  }
}

//! The progress line: only when stderr is a terminal, redrawn in place, at most once per
//! percent.
class ProgressLine {
 public:
  ProgressLine() : enabled_(::isatty(STDERR_FILENO) == 1) {}
  ~ProgressLine() { finish(); }

  stlrefine::ProgressFn sink() {
    if (!enabled_) return {};
    return [this](double fraction, std::string_view stage) {
      std::lock_guard lock(mutex_);
      const int percent = static_cast<int>(std::lround(100 * std::clamp(fraction, 0.0, 1.0)));
      if (percent == last_percent_ && stage == last_stage_) return;
      last_percent_ = percent;
      last_stage_ = stage;
      std::fprintf(stderr, "\r\033[Krefining: %3d%%  %.*s", percent, static_cast<int>(stage.size()),
                   stage.data());
      std::fflush(stderr);
      drawn_ = true;
    };
  }

  void finish() {
    std::lock_guard lock(mutex_);
    if (drawn_) std::fputs("\r\033[K", stderr);
    drawn_ = false;
  }

 private:
  bool enabled_;
  std::mutex mutex_;
  int last_percent_ = -1;
  std::string last_stage_;
  bool drawn_ = false;
};

//! The values of a subcommand's request parameters, by API name (the options come from
//! api/param_table.h).
using ParamValues = std::map<std::string_view, std::string>;

struct InfoOptions {
  std::string input;
  ParamValues params;
  std::string curvature;  // per-vertex CSV path
};

struct RefineOptions {
  std::string input, output, report, slice_out;
  ParamValues params;
  bool ascii = false;
};

struct SliceCliOptions {
  std::string input, output, report;
  ParamValues params;
};

// The part's name in the contour files: the input's file name without its extension.
std::string label_of(const std::string& input) {
  if (input == "-") return "part";
  std::string stem = std::filesystem::path(input).stem().string();
  if (stem.empty()) stem = "part";
  if (stem.size() > 256) stem.resize(256);
  return stem;
}

std::string scheme_list() {
  std::string list;
  for (std::string_view name : stlrefine::scheme_names())
    list += (list.empty() ? "" : ", ") + std::string(name);
  return list;
}

// One option per parameter of the table `kind` takes, its help the table's.
void add_param_options(CLI::App& cmd, api::RequestKind kind, ParamValues& values) {
  for (const api::ParamRow& row : api::param_table()) {
    if (!row.takes(kind) || row.http_only) continue;
    std::string help = api::cli_help(row);
    if (row.name == "scheme") help = "Subdivision scheme: " + scheme_list() + " (butterfly)";
    cmd.add_option(api::cli_option(row.name), values[row.name], help);
  }
}

// Options given on the command line, as (API name, text) pairs: api/params validates them
// exactly as the daemon validates a query string.
api::RawParams given_params(const CLI::App& cmd, api::RequestKind kind, const ParamValues& values) {
  api::RawParams raw;
  for (const api::ParamRow& row : api::param_table())
    if (row.takes(kind) && !row.http_only && cmd.get_option(api::cli_option(row.name))->count() > 0)
      raw.emplace_back(std::string(row.name), values.at(row.name));
  return raw;
}

int run_info(const CLI::App& cmd, const InfoOptions& o) {
  const api::RawParams raw = given_params(cmd, api::RequestKind::Info, o.params);
  check_stdout_outputs({{"--curvature", &o.curvature}}, "the report");
  try {
    const api::InfoRequest request = api::parse_info_params(raw);
    const std::vector<std::uint8_t> bytes = read_file(o.input);
    const api::InfoOutcome out = api::run_info(bytes, request, !o.curvature.empty());
    if (out.curvature_csv) write_file(o.curvature, *out.curvature_csv);
    std::cout << out.report.dump(2) << std::endl;
    return kExitOk;
  } catch (const Error& e) {
    throw failure_from_error(e, o.input);
  }
}

// A file name ending in .3mf (any case).
bool ends_with_3mf(const std::string& name) {
  if (name.size() < 4) return false;
  std::string end = name.substr(name.size() - 4);
  for (char& c : end) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return end == ".3mf";
}

int run_refine(const CLI::App& cmd, const RefineOptions& o) {
  const api::RawParams raw = given_params(cmd, api::RequestKind::Refine, o.params);
  check_stdout_outputs({{"-o", &o.output}, {"--slice-out", &o.slice_out}, {"--report", &o.report}});
  // Slicing is asked for by a layer height (--layer-height, or --slice, its old name) or
  // explicit --heights; the contours need a file.
  const bool slicing = cmd.get_option("--layer-height")->count() > 0 ||
                       cmd.get_option("--slice")->count() > 0 ||
                       cmd.get_option("--heights")->count() > 0;
  if (slicing != (cmd.get_option("--slice-out")->count() > 0))
    throw Failure{kExitUsage,
                  slicing ? "slicing (--layer-height or --heights) needs --slice-out (the contour "
                            "file)"
                          : "--slice-out needs --layer-height (mm) or --heights"};
  api::RequestLimits limits;
  limits.max_faces = (std::uint64_t{1} << 31) - 1;  // the core's maximum
  limits.default_max_faces = stlrefine::RefineParams{}.max_faces;
  limits.accept_threads = true;
  try {
    api::RefineRequest request = api::parse_refine_fields(raw, limits);
    request.output_format = o.ascii ? stlrefine::StlFormat::Ascii : stlrefine::StlFormat::Binary;
    // -o part.3mf asks for 3MF as --mesh-format 3mf does (an explicit --mesh-format wins).
    if (!request.mesh_format_given && ends_with_3mf(o.output)) {
      if (request.slice)
        throw Failure{kExitUsage,
                      "-o " + o.output +
                          ": refine with --slice writes an STL; 3MF output is for refine alone"};
      request.mesh_format = stlrefine::MeshFormat::ThreeMf;
    }
    if (request.mesh_format == stlrefine::MeshFormat::ThreeMf && o.ascii)
      throw Failure{kExitUsage, "--ascii writes an ASCII STL; it does not go with 3MF output"};
    if (request.slice) request.slice->writer.label = label_of(o.input);
    // Planned (validated, the scheme made) before the file is read. The CLI has no memory
    // budget: the body's shape and the memory estimate are not needed.
    const api::RefinePlan plan = api::plan_refine(std::move(request));
    const std::vector<std::uint8_t> bytes = read_file(o.input);
    ProgressLine progress;
    api::RefinedMesh refined = api::run_refine_to_mesh(bytes, plan, progress.sink());
    progress.finish();
    api::RefineOutcome& out = refined.outcome;
    if (refined.stream()) {  // binary: made as it is written, never whole in memory
      const auto start = std::chrono::steady_clock::now();
      write_file(o.output, [&](const stlrefine::ByteSink& sink) {
        stlrefine::write_binary_stl(refined.mesh, sink);
      });
      // The report's write time is the streamed write's (run_refine's included its own).
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      out.report["seconds"]["write"] = seconds;
      out.report["seconds"]["total"] = out.report["seconds"]["total"].get<double>() + seconds;
    } else {
      write_file(o.output, out.stl);
    }
    if (out.contours) write_file(o.slice_out, *out.contours);
    if (!o.report.empty()) write_file(o.report, out.report.dump(2) + "\n");
    std::cerr << "stlrefine: " << out.report["input"]["faces"] << " -> "
              << out.report["output"]["faces"] << " faces (" << plan.request.refine.scheme << ", "
              << out.report["levels"] << (plan.request.refine.adaptive() ? " adaptive" : "")
              << " levels) in " << out.report["seconds"]["total"] << " s -> " << o.output
              << std::endl;
    return kExitOk;
  } catch (const Error& e) {
    throw failure_from_error(e, o.input);
  }
}

int run_slice(const CLI::App& cmd, const SliceCliOptions& o) {
  const api::RawParams raw = given_params(cmd, api::RequestKind::Slice, o.params);
  check_stdout_outputs({{"-o", &o.output}, {"--report", &o.report}});
  api::RequestLimits limits;
  limits.accept_threads = true;
  try {
    api::SliceRequest request = api::parse_slice_params(raw, limits);
    request.slice.writer.label = label_of(o.input);
    const std::vector<std::uint8_t> bytes = read_file(o.input);
    api::SliceOutcome out = api::run_slice(bytes, request);
    write_file(o.output, out.contours);
    if (!o.report.empty()) write_file(o.report, out.report.dump(2) + "\n");
    const auto& s = out.report["slice"];
    std::cerr << "stlrefine: " << s["layers"] << " layers, " << s["outer_loops"] << " outer loops, "
              << s["holes"] << " holes, " << s["open_polylines"] << " open polylines ("
              << s["format"].get<std::string>() << ") in " << out.report["seconds"]["total"]
              << " s -> " << o.output << std::endl;
    return kExitOk;
  } catch (const Error& e) {
    throw failure_from_error(e, o.input);
  }
}

struct SpectrumOptions {
  std::string scheme = "butterfly", valence = "3..16", format, output;
  ParamValues options;  // the schemes' options (api/param_table.h rows with scheme_option)
  int count = 7;
  bool unmodified = false, curve = false, markdown = false;
};

// "7" or "3..16", each valence in [3, 64].
std::pair<int, int> parse_valences(const std::string& text) {
  const std::size_t dots = text.find("..");
  const std::string first = dots == std::string::npos ? text : text.substr(0, dots);
  const std::string last = dots == std::string::npos ? text : text.substr(dots + 2);
  try {
    const int a = static_cast<int>(api::parse_integer("valence", first, 3, 64));
    const int b = static_cast<int>(api::parse_integer("valence", last, 3, 64));
    if (a > b) throw Failure{kExitUsage, "--valence: " + text + " is an empty range"};
    return {a, b};
  } catch (const Error& e) {
    throw Failure{kExitUsage,
                  "--valence: " + std::string(e.what()) + " (a valence N or a range A..B)"};
  }
}

// "only loop-g2 and butterfly-g1 have a base": the schemes whose registry row has one.
std::string bases_message() {
  std::vector<std::string_view> names;
  for (const stlrefine::SchemeEntry& entry : stlrefine::scheme_registry())
    if (entry.base) names.push_back(entry.name);
  std::string text = "only ";
  for (std::size_t i = 0; i < names.size(); ++i)
    text +=
        std::string(i == 0 ? "" : (i + 1 == names.size() ? " and " : ", ")) + std::string(names[i]);
  return text + (names.size() == 1 ? " has a base" : " have a base");
}

int run_spectrum(const CLI::App& cmd, const SpectrumOptions& o) {
  namespace an = stlrefine::analysis;
  std::string text;
  if (o.markdown) {
    text = an::spectra_markdown();
  } else {
    // The scheme and its options are read and validated as a refinement's.
    api::RawParams raw = {{"scheme", o.scheme}};
    for (const api::ParamRow& row : api::param_table())
      if (row.scheme_option && cmd.get_option(api::cli_option(row.name))->count() > 0)
        raw.emplace_back(std::string(row.name), o.options.at(row.name));
    std::unique_ptr<stlrefine::Scheme> scheme;
    try {
      scheme = stlrefine::make_scheme(api::parse_refine_params(raw, {}).refine);
    } catch (const Error& e) {
      throw failure_from_error(e, "");
    }
    // --unmodified: the base the spectral schemes change (their registry rows say which),
    // analysed on its own.
    std::unique_ptr<stlrefine::Split4Stencil> base;
    if (o.unmodified) {
      const stlrefine::SchemeEntry* entry = stlrefine::find_scheme(o.scheme);
      if (!entry->base) throw Failure{kExitUsage, "--unmodified: " + bases_message()};
      base = entry->base();
    }
    const an::Refiner refiner = base ? an::Refiner::of(*base) : an::Refiner::of(*scheme);
    const std::string title = o.scheme + (o.unmodified ? " (unmodified base)" : "");
    if (o.curve) {
      text = an::format_curve(title + " curve rule",
                              an::spectrum(an::curve_subdivision_matrix(refiner))) +
             "\n";
    } else {
      const auto [first, last] = parse_valences(o.valence);
      std::string format = o.format.empty() ? (first == last ? "lines" : "table") : o.format;
      if (format != "lines" && format != "table")
        throw Failure{kExitUsage, "--format: '" + o.format + "' is not lines or table"};
      std::vector<an::ValenceReport> reports;
      for (int n = first; n <= last; ++n) reports.push_back(an::analyse_valence(refiner, n));
      if (format == "table") {
        text = "# " + title + "\n\n" + an::format_table(reports, o.count);
      } else {
        for (const an::ValenceReport& r : reports) text += an::format_lines(title, r);
      }
    }
  }
  if (o.output.empty())
    std::cout << text << std::flush;
  else
    write_file(o.output, text);
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stlrefine: refine coarse STL files with interpolatory subdivision"};
  app.set_version_flag("--version", std::string(STLREFINE_VERSION));
  app.require_subcommand(1);
  app.footer(
      "Exit codes: 0 ok, 2 bad usage or parameter, 3 unreadable or unusable input file,\n"
      "4 face or layer budget exceeded, 1 internal error or output not writable.");

  InfoOptions info;
  CLI::App* info_cmd = app.add_subcommand("info", "Print a JSON report on an STL file");
  info_cmd
      ->add_option("input", info.input,
                   "Mesh file: STL (binary or ASCII), OBJ, PLY or 3MF, by content; - reads stdin")
      ->required();
  add_param_options(*info_cmd, api::RequestKind::Info, info.params);
  info_cmd->add_option("--curvature", info.curvature,
                       "Write per-vertex curvatures (vertex,x,y,z,kind,gaussian,mean,k1,k2,"
                       "valid) of the welded mesh to this CSV file");

  RefineOptions refine;
  CLI::App* refine_cmd = app.add_subcommand("refine", "Refine an STL file");
  refine_cmd
      ->add_option("input", refine.input,
                   "Mesh file: STL (binary or ASCII), OBJ, PLY or 3MF, by content; - reads stdin")
      ->required();
  refine_cmd
      ->add_option("-o,--output", refine.output,
                   "Output file: binary STL, or 3MF when --mesh-format 3mf or the name ends in "
                   ".3mf; - writes stdout")
      ->required();
  add_param_options(*refine_cmd, api::RequestKind::Refine, refine.params);
  refine_cmd->add_flag("--ascii", refine.ascii, "Write ASCII STL instead of binary");
  refine_cmd->add_option("--report", refine.report, "Also write the JSON report to this file");
  refine_cmd->add_option("--slice-out", refine.slice_out,
                         "Contour file (with --layer-height or --heights)");

  SpectrumOptions spectrum;
  CLI::App* spectrum_cmd = app.add_subcommand(
      "spectrum",
      "Print the eigenvalues of a scheme's local subdivision matrix around a vertex of valence "
      "N, by Fourier frequency, with the smoothness checks (docs/spectra.md)");
  spectrum_cmd->add_option("--scheme", spectrum.scheme,
                           "Scheme: " + scheme_list() + " (butterfly)");
  spectrum_cmd->add_option("--valence", spectrum.valence,
                           "A valence N or a range A..B, 3..64 (3..16)");
  spectrum_cmd->add_option("--format", spectrum.format,
                           "lines (one eigenvalue per line; default for one valence) or table "
                           "(Markdown, one row per valence; default for a range)");
  spectrum_cmd->add_option("--count", spectrum.count, "Eigenvalues per table row (7)")
      ->check(CLI::Range(1, 1000));
  for (const api::ParamRow& row : api::param_table())
    if (row.scheme_option)
      spectrum_cmd->add_option(api::cli_option(row.name), spectrum.options[row.name],
                               api::cli_help(row));
  spectrum_cmd->add_flag("--unmodified", spectrum.unmodified,
                         "loop-g2, butterfly-g1: the base scheme before the spectral change");
  spectrum_cmd->add_flag("--curve", spectrum.curve,
                         "The curve (crease and boundary) rule's 1-D spectrum instead");
  spectrum_cmd->add_flag("--markdown", spectrum.markdown,
                         "Print docs/spectra.md (every scheme; slow: about a minute)");
  spectrum_cmd->add_option("-o,--output", spectrum.output, "Write to this file instead of stdout");

  SliceCliOptions slice;
  CLI::App* slice_cmd =
      app.add_subcommand("slice", "Slice an STL file into layers of closed, oriented contours");
  slice_cmd
      ->add_option("input", slice.input,
                   "Mesh file: STL (binary or ASCII), OBJ, PLY or 3MF, by content; - reads stdin")
      ->required();
  slice_cmd->add_option("-o,--output", slice.output, "Contour file; - writes stdout")->required();
  add_param_options(*slice_cmd, api::RequestKind::Slice, slice.params);
  slice_cmd->add_option("--report", slice.report, "Also write the JSON report to this file");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;  // --help / --version exit with 0
  }

  try {
    if (info_cmd->parsed()) return run_info(*info_cmd, info);
    if (slice_cmd->parsed()) return run_slice(*slice_cmd, slice);
    if (spectrum_cmd->parsed()) return run_spectrum(*spectrum_cmd, spectrum);
    return run_refine(*refine_cmd, refine);
  } catch (const Failure& f) {
    std::cerr << "stlrefine: " << f.message << std::endl;
    return f.exit_code;
  } catch (const std::exception& e) {
    std::cerr << "stlrefine: internal error: " << e.what() << std::endl;
    return kExitInternal;
  }
}
