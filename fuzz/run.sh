#!/usr/bin/env bash
# Runs the libFuzzer harnesses (built by `cmake --preset fuzz && cmake --build --preset fuzz`)
# one after the other, each for SECONDS from its seed corpus, with the options below.
#
#   fuzz/run.sh [--build-dir DIR] [--seconds N] [--work DIR] [NAME...] [-- libFuzzer flags]
#
# NAME: fuzz_stl_binary fuzz_stl_ascii fuzz_query fuzz_pipeline fuzz_mesh_formats fuzz_archive
# (default: all).
# New inputs go to WORK/corpus/NAME (default WORK: BUILD_DIR/fuzz-work), crashes, leaks and
# timeouts to WORK/artifacts/NAME/; the seeds in the repository are only read. A harness
# that finds something stops there and names the input that reproduces it; the others still
# run, and the script then exits non-zero.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")

build_dir=$root/build-fuzz
seconds=60
work=""
names=()
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build_dir=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    -h | --help) sed -n '2,12p' "$0"; exit 0 ;;
    *) names+=("$1"); shift ;;
  esac
done
[ -n "$work" ] || work=$build_dir/fuzz-work
[ ${#names[@]} -gt 0 ] || names=(fuzz_stl_binary fuzz_stl_ascii fuzz_query fuzz_pipeline fuzz_mesh_formats fuzz_archive)

# Per harness: libFuzzer options, then the seed directories (read only). Parsers: inputs
# up to 16 KiB (binary: 326 facets; ASCII: ~60 facets), a 10 s timeout where one input
# takes well under a millisecond. The pipeline: a 60 s timeout for one input that runs
# 6 schemes, the adaptive mode and 8 slices.
common=(-rss_limit_mb=2048 -print_final_stats=1)
options() {
  case "$1" in
    fuzz_stl_binary) echo "-max_len=16384 -timeout=10 -use_value_profile=1" ;;
    fuzz_stl_ascii) echo "-max_len=16384 -timeout=10 -use_value_profile=1 -dict=$here/dict/stl_ascii.dict" ;;
    fuzz_query) echo "-max_len=2048 -timeout=10 -use_value_profile=1 -dict=$here/dict/query.dict" ;;
    fuzz_pipeline) echo "-max_len=16384 -timeout=60 -rss_limit_mb=3072" ;;
    fuzz_mesh_formats) echo "-max_len=16384 -timeout=10 -use_value_profile=1 -dict=$here/dict/mesh_formats.dict" ;;
    fuzz_archive) echo "-max_len=16384 -timeout=10 -use_value_profile=1 -dict=$here/dict/archive.dict" ;;
    *) echo "unknown harness $1" >&2; return 1 ;;
  esac
}
seeds() {
  case "$1" in
    fuzz_stl_binary) echo "$here/corpus/stl_binary $here/corpus/shared_meshes $here/corpus/regressions $root/tests/data/core $root/tests/data/malformed" ;;
    fuzz_stl_ascii) echo "$here/corpus/stl_ascii" ;;
    fuzz_query) echo "$here/corpus/query" ;;
    fuzz_mesh_formats) echo "$here/corpus/mesh_formats $here/corpus/stl_ascii" ;;
    fuzz_archive) echo "$here/corpus/archive" ;;
    fuzz_pipeline) echo "$here/corpus/stl_binary $here/corpus/stl_ascii $here/corpus/shared_meshes $here/corpus/regressions $root/tests/data/core $root/tests/data/malformed" ;;
  esac
}

# Stack traces for UBSan reports too (ASan prints them anyway).
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}
# Suppressions for leaks that are not ours (scripts/lsan.supp; none today).
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/scripts/lsan.supp}

for name in "${names[@]}"; do
  [ -x "$build_dir/bin/$name" ] || { echo "fuzz/run.sh: $build_dir/bin/$name is missing (cmake --build --preset fuzz)" >&2; exit 2; }
done
failed=()
for name in "${names[@]}"; do
  bin=$build_dir/bin/$name
  opts=$(options "$name")
  corpus=$work/corpus/$name
  artifacts=$work/artifacts/$name
  mkdir -p "$corpus" "$artifacts"
  echo "== $name: ${seconds} s, $opts"
  # shellcheck disable=SC2046,SC2086  # the option and seed lists are split on purpose
  if ! "$bin" "${common[@]}" $opts -max_total_time="$seconds" -artifact_prefix="$artifacts/" \
      "${extra[@]}" "$corpus" $(seeds "$name") 2>"$work/$name.log"; then
    tail -n 60 "$work/$name.log" >&2
    echo "fuzz/run.sh: $name found a problem; reproduce with: $bin $artifacts/<file> (log $work/$name.log)" >&2
    ls -l "$artifacts" >&2
    failed+=("$name")
    continue
  fi
  grep -E '^(#[0-9]+ +DONE|stat::)' "$work/$name.log" || tail -n 5 "$work/$name.log"
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz/run.sh: FAILED: ${failed[*]}" >&2
  exit 1
fi
