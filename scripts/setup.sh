#!/usr/bin/env bash
# stlrefine set-up for a fresh Debian 12 machine: installs the Debian packages that are
# missing, builds (Release, -Wall -Wextra) into build/, then
#   scripts/setup.sh demo   starts stlrefined on 127.0.0.1:8080 and refines examples/fandisk.stl
#   scripts/setup.sh test   runs every test (ctest), then the sanitizer suite and the fuzzers
#                           (what CI runs, via .ci/run: the asan and fuzz steps below)
#   scripts/setup.sh build  only builds
#   scripts/setup.sh asan   only the sanitizer suite: the `asan` CMake preset (clang 14,
#                           ASan + UBSan) builds into build-asan/ and runs every test there
#   scripts/setup.sh fuzz   only the fuzzers: the `fuzz` preset builds into build-fuzz/, then
#                           fuzz/run.sh runs each harness FUZZ_SECONDS (default 60) seconds
#                           from its seeds; any crash, leak, timeout or out-of-memory fails
set -euo pipefail
cd "$(dirname "$0")/.."

mode=${1:-demo}
build_dir=${STLREFINE_BUILD_DIR:-build}
jobs=$(nproc 2>/dev/null || echo 2)

packages=(build-essential cmake pkg-config curl ca-certificates
  libcgal-dev libeigen3-dev libcpp-httplib-dev nlohmann-json3-dev libcli11-dev libtbb-dev
  libgtest-dev libgmock-dev libbenchmark-dev libopenmesh-dev libzip-dev libssl-dev
  lib3mf-dev  # 3MF out (core/io/threemf_writer.cpp)
  libexpat1-dev  # 3MF in: the model XML, streamed (core/io/threemf_xml.cpp)
  clang-14 libclang-rt-14-dev
  libjson-validator-perl  # the OpenAPI validator of tests/server/openapi_validator_test.cpp
  libhiredis-dev redis-server)  # --queue redis:// (server/queue_*), and its tests
# The web page (web/) needs node and npm at build time (npm ci fetches three.js), and its
# browser test (tests/web/) chromium. Checked by command, not by package: nodejs from
# elsewhere (NodeSource) bundles npm and conflicts with Debian's npm package.
web_tools=(nodejs:node npm:npm chromium:chromium)

install_missing() {
  local missing=()
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  for t in "${web_tools[@]}"; do
    command -v "${t#*:}" >/dev/null 2>&1 || missing+=("${t%%:*}")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "installing: ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

build() {
  cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DSTLREFINE_STRICT=ON
  cmake --build "$build_dir" -j"$jobs"
}

# The whole test suite again, built by clang 14 with AddressSanitizer (leaks included) and
# UndefinedBehaviorSanitizer: the first report fails its test (CMakePresets.json).
asan() {
  cmake --preset asan
  cmake --build --preset asan -j"$jobs"
  ctest --preset asan -j"$jobs"
}

# The libFuzzer harnesses (fuzz/README.md), each FUZZ_SECONDS from its seed corpus.
fuzz() {
  cmake --preset fuzz
  cmake --build --preset fuzz -j"$jobs"
  fuzz/run.sh --seconds "${FUZZ_SECONDS:-60}"
}

demo() {
  local port=8080 log="$build_dir/stlrefined.log"
  if curl -fsS "http://127.0.0.1:$port/healthz" >/dev/null 2>&1; then
    echo "something already answers on 127.0.0.1:$port; using it"
  else
    nohup "$build_dir/bin/stlrefined" --host 127.0.0.1 --port "$port" >"$log" 2>&1 &
    echo $! >"$build_dir/stlrefined.pid"
    for _ in $(seq 1 100); do
      curl -fsS "http://127.0.0.1:$port/healthz" >/dev/null 2>&1 && break
      sleep 0.1
    done
  fi
  mkdir -p out
  curl -fsS --data-binary @examples/fandisk.stl -H 'Content-Type: model/stl' \
    -D out/fandisk_refined.headers \
    "http://127.0.0.1:$port/v1/refine?scheme=butterfly&levels=2" -o out/fandisk_refined.stl
  echo "refined examples/fandisk.stl -> out/fandisk_refined.stl ($(stat -c %s out/fandisk_refined.stl) bytes)"
  grep -i '^x-stlrefine-report:' out/fandisk_refined.headers | cut -d' ' -f2- || true
  echo
  echo "stlrefined is running on http://127.0.0.1:$port (pid $(cat "$build_dir/stlrefined.pid" 2>/dev/null || echo '?'), log $log)."
  echo "Try:  curl --data-binary @examples/fandisk.stl 'http://127.0.0.1:$port/v1/refine?scheme=butterfly&levels=2' -o out.stl"
  echo "Stop: kill \$(cat $build_dir/stlrefined.pid)"
}

# Runs one step and says how long it took (CI's budget is 90 minutes on 2 cores).
timed() {
  local start=$SECONDS
  "$@"
  echo "setup.sh: '$*' took $((SECONDS - start)) s"
}

case "$mode" in
  demo | test | build | asan | fuzz) ;;
  *) echo "usage: $0 [demo|test|build|asan|fuzz]" >&2; exit 2 ;;
esac
install_missing
case "$mode" in
  demo) build; demo ;;
  test)
    timed build
    timed ctest --test-dir "$build_dir" --output-on-failure -j"$jobs"
    timed asan
    timed fuzz
    ;;
  build) timed build ;;
  asan) timed asan ;;
  fuzz) timed fuzz ;;
esac
