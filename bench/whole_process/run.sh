#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Issue 18 item 5, side by side in one run: whole-process time and peak RSS of
#  - our CLI (read, refine, write) for loop and butterfly, 2 levels, with the default
#    deviation pass (max_deviation=auto) and without it (off);
#  - CGAL Loop_subdivision and OpenMesh ModifiedButterflyT, each with its own STL reader and
#    writer (bench/whole_process/peer_whole.cpp);
#  - one POST /v1/refine against a fresh stlrefined (peak RSS of the daemon: VmHWM, and its
#    RSS before the request).
# Hand-run, never a ctest test:
#   bench/whole_process/run.sh BUILD_DIR [REPS]   (BUILD_DIR with stlrefine, stlrefined, peer_whole)
# The input is a 277,804-triangle scan made from the shared bunny (one butterfly level):
# /work/shared/meshes holds no 269k-triangle scan.
set -euo pipefail
build=${1:?build dir}
reps=${2:-3}
meshes=${STLREFINE_SHARED_MESHES:-/work/shared/meshes}
work=${TMPDIR:-/tmp}/stlrefine-whole-$$
mkdir -p "$work"
trap 'rm -rf "$work"' EXIT
cli=$build/bin/stlrefine
daemon=$build/bin/stlrefined
peer=$build/bin/peer_whole

"$cli" refine "$meshes/organic/bunny.stl" -o "$work/scan.stl" --scheme butterfly --levels 1 \
  --max-deviation off 2>/dev/null
in_bytes=$(stat -c %s "$work/scan.stl")
echo "input: bunny.stl refined once (butterfly): $in_bytes bytes, $(( (in_bytes - 84) / 50 )) triangles"
echo

# name | command...: wall seconds and peak RSS (MiB) of the whole process, REPS times.
run() {
  local name=$1; shift
  for r in $(seq "$reps"); do
    rm -f "$work/out.stl"
    /usr/bin/time -f "%e %M %U %S" -o "$work/time" "$@" > "$work/stdout" 2> "$work/stderr" || {
      echo "$name failed: $(tail -3 "$work/stderr")"; return; }
    read -r wall kib usr sys < "$work/time"
    out_bytes=$(stat -c %s "$work/out.stl")
    extra=""
    if [[ -s "$work/report.json" ]]; then
      extra=$(python3 - "$work/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
s = r["seconds"]
dev = r.get("deviation", {})
d = dev.get("seconds")
det = dev.get("detect_seconds")
print(f"ingest {s['ingest']:.3f} refine {s['refine']:.3f} total {s['total']:.3f}"
      + (f" deviation {d:.3f}" if d is not None else "")
      + (f" detect {det:.3f}" if det is not None else ""))
PY
)
      rm -f "$work/report.json"
    fi
    [[ -s "$work/stdout" ]] && extra="$extra $(cat "$work/stdout")"
    printf '| %s | %d | %s | %.2f | %.1f | %.2f | %s |\n' "$name" "$r" "$wall" "$(echo "$usr+$sys" | bc -l)" \
      "$(echo "$kib/1024" | bc -l)" \
      "$(echo "$kib*1024/($in_bytes+$out_bytes)" | bc -l)" "$extra"
  done
}

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg) (2 cores shared with other builds)"
echo
echo "| process | rep | wall s | CPU s (user+sys) | peak RSS MiB | peak / (in + out STL) | phases (s) |"
echo "|---|---|---|---|---|---|---|"
for scheme in loop butterfly; do
  for dev in auto off; do
    run "stlrefine refine --scheme $scheme --levels 2 --max-deviation $dev" \
      "$cli" refine "$work/scan.stl" -o "$work/out.stl" --scheme "$scheme" --levels 2 \
      --max-deviation "$dev" --report "$work/report.json"
  done
done
for scheme in loop butterfly; do
  for dev in "" "-off" "-off-string"; do
    run "in-process, per phase: ours-$scheme$dev" "$peer" "ours-$scheme$dev" "$work/scan.stl" 2 "$work/out.stl"
  done
done
run "CGAL Loop_subdivision (read_polygon_mesh, write_STL)" "$peer" cgal-loop "$work/scan.stl" 2 "$work/out.stl"
run "OpenMesh ModifiedButterflyT (read_mesh, write_mesh)" "$peer" openmesh-butterfly "$work/scan.stl" 2 "$work/out.stl"

echo
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| daemon request | rep | client wall s | daemon RSS before MiB | daemon peak RSS MiB | peak / (in + out STL) | (peak - before) / (in + out) |"
echo "|---|---|---|---|---|---|---|"
port=$(( 20000 + $$ % 20000 ))
for query in "scheme=loop&levels=2" "scheme=loop&levels=2&max_deviation=off" \
             "scheme=butterfly&levels=2" "scheme=butterfly&levels=2&max_deviation=off"; do
  for r in $(seq "$reps"); do
    "$daemon" --port "$port" --data-dir "$work/data" --compute-slots 1 > /dev/null 2> "$work/daemon.log" &
    pid=$!
    for _ in $(seq 100); do curl -sf "http://127.0.0.1:$port/healthz" > /dev/null && break; sleep 0.1; done
    before=$(awk '/VmRSS/ {print $2}' /proc/$pid/status)
    start=$(date +%s.%N)
    code=$(curl -s -o "$work/out.stl" -w '%{http_code}' --data-binary "@$work/scan.stl" \
      -H 'Content-Type: application/octet-stream' "http://127.0.0.1:$port/v1/refine?$query")
    end=$(date +%s.%N)
    hwm=$(awk '/VmHWM/ {print $2}' /proc/$pid/status)
    kill -TERM "$pid"; wait "$pid" || true
    out_bytes=$(stat -c %s "$work/out.stl")
    [[ "$code" == 200 ]] || { echo "$query: HTTP $code $(head -c 300 "$work/out.stl")"; continue; }
    printf '| %s | %d | %.2f | %.1f | %.1f | %.2f | %.2f |\n' "$query" "$r" "$(echo "$end-$start" | bc -l)" \
      "$(echo "$before/1024" | bc -l)" "$(echo "$hwm/1024" | bc -l)" \
      "$(echo "$hwm*1024/($in_bytes+$out_bytes)" | bc -l)" \
      "$(echo "($hwm-$before)*1024/($in_bytes+$out_bytes)" | bc -l)"
  done
done
