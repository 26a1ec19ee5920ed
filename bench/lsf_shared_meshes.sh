#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Copyright (c) 2026 stlrefine authors
#
# Issue 4, "Done when": `lsf`, uniform and curvature-adaptive, through the CLI and over HTTP
# on every mesh of the shared test set. For each mesh and mode it runs
#   stlrefine refine IN -o OUT --scheme lsf --levels 2
#   stlrefine refine IN -o OUT --scheme lsf --adaptive-tol TOL --max-level 3
# and the same two requests as POST /v1/refine?scheme=lsf&... against a stlrefined it starts
# on a free port, and prints one Markdown row per (mesh, mode): the tolerance, faces in and
# out, what ingest repaired, seconds, CLI exit code, HTTP status, and whether the CLI and
# HTTP outputs are the same bytes. A non-zero exit or 4xx that names the problem is a
# result; a crash (exit >= 128 or 1 = internal error), a timeout or a 5xx is a bug and is
# marked **BUG**. Progress goes to stderr; the exit status is 1 when a row says **BUG**.
#
# Usage: bench/lsf_shared_meshes.sh BUILD_DIR [MESH_DIR] [TOL] > table.md
#   BUILD_DIR: holds bin/stlrefine and bin/stlrefined (Release)
#   MESH_DIR:  default /work/shared/meshes; *.stl and *.stl.gz below it (gz is unpacked)
#   TOL:       adaptive tolerance: a number is in model units; a number followed by "d"
#              (default 0.001d) is that fraction of each mesh's bounding-box diagonal, so
#              a 0.2 m scan and a 350 mm plate are both refined where they are curved
set -u

BIN=${1:?usage: $0 BUILD_DIR [MESH_DIR] [TOL]}/bin
MESHES=${2:-/work/shared/meshes}
TOL=${3:-0.001d}
TIMEOUT=${TIMEOUT:-900}
for exe in stlrefine stlrefined; do
  [ -x "$BIN/$exe" ] || { echo "missing $BIN/$exe" >&2; exit 2; }
done
command -v curl > /dev/null || { echo "curl is needed" >&2; exit 2; }

TMP=$(mktemp -d)
DAEMON_PID=
cleanup() {
  [ -n "$DAEMON_PID" ] && kill "$DAEMON_PID" 2> /dev/null && wait "$DAEMON_PID" 2> /dev/null
  rm -rf "$TMP"
}
trap cleanup EXIT

"$BIN/stlrefined" --port 0 --data-dir "$TMP/data" > "$TMP/daemon.out" 2> "$TMP/daemon.err" &
DAEMON_PID=$!
URL=
for _ in $(seq 100); do
  URL=$(sed -n 's/^listening on //p' "$TMP/daemon.out")
  [ -n "$URL" ] && break
  sleep 0.1
done
[ -n "$URL" ] || { echo "stlrefined did not start" >&2; cat "$TMP/daemon.err" >&2; exit 1; }
echo "daemon at $URL (pid $DAEMON_PID)" >&2

# tolerance FILE: the adaptive tolerance for one mesh (TOL, or TOL's fraction of the
# bounding-box diagonal of the file's finite vertices; 0.05 when the file cannot be read).
tolerance() {
  case $TOL in
    *d) python3 - "$1" "${TOL%d}" << 'PY' ;;
import math, os, re, struct, sys
path, frac = sys.argv[1], float(sys.argv[2])
lo, hi = [math.inf] * 3, [-math.inf] * 3
def add(x, y, z):
    for i, c in enumerate((x, y, z)):
        if math.isfinite(c):
            lo[i], hi[i] = min(lo[i], c), max(hi[i], c)
try:
    data = open(path, "rb").read()
    n = struct.unpack_from("<I", data, 80)[0] if len(data) >= 84 else -1
    if n >= 0 and len(data) >= 84 + 50 * n and (n > 0 or len(data) == 84):
        for rec in struct.iter_unpack("<12x9f2x", data[84:84 + 50 * n]):
            add(*rec[0:3]); add(*rec[3:6]); add(*rec[6:9])
    else:
        for m in re.finditer(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)", data):
            add(*(float(t) for t in m.groups()))
    d = math.dist(lo, hi)
    print(f"{frac * d:.6g}" if math.isfinite(d) and d > 0 else "0.05")
except Exception:
    print("0.05")
PY
    *) echo "$TOL" ;;
  esac
}

# fields CLI_REPORT HEADERS: faces in, CLI faces out, HTTP faces out and what ingest
# repaired, separated by ";" ("" when absent; a tab would merge empty fields in read). One python start per row: it is slow under load.
fields() {
  python3 - "$1" "$2" << 'PY' 2> /dev/null
import json, sys
def load(path):
    try:
        return json.load(open(path))
    except Exception:
        return {}
cli = load(sys.argv[1])
http = {}
try:
    for line in open(sys.argv[2], errors="replace"):
        name, _, value = line.partition(":")
        if name.strip().lower() == "x-stlrefine-report":
            http = json.loads(value.strip())
except Exception:
    pass
def get(d, *keys):
    for k in keys:
        d = d.get(k, {}) if isinstance(d, dict) else {}
    return "" if d == {} else str(d)
names = [("non_manifold_edges", "non-manifold edges cut"),
         ("vertices_duplicated", "vertices split"),
         ("index_degenerate_removed", "degenerate facets dropped"),
         ("faces_reoriented", "facets reoriented"),
         ("non_orientable_cuts", "non-orientable cuts")]
ingest = cli.get("ingest") or http.get("ingest") or {}
repaired = ", ".join(f"{ingest[k]} {t}" for k, t in names if ingest.get(k))
print(";".join([get(cli, "input", "faces") or get(http, "input", "faces"),
                 get(cli, "output", "faces"), get(http, "output", "faces"), repaired or "-"]))
PY
}

echo "| mesh | mode | tol | faces in | ingest repaired | CLI faces out | CLI s | CLI exit | HTTP faces out | HTTP s | HTTP status | same bytes | result |"
echo "|---|---|--:|--:|---|--:|--:|--:|--:|--:|--:|---|---|"

bugs=0
while read -r path; do
  rel=${path#"$MESHES"/}
  input=$path
  if [[ $path == *.gz ]]; then
    input="$TMP/$(basename "${path%.gz}")"
    gunzip -c "$path" > "$input"
  fi
  tol=$(tolerance "$input")
  for mode in uniform adaptive; do
    if [ $mode = uniform ]; then
      cli_args=(--levels 2)
      query="scheme=lsf&levels=2"
    else
      cli_args=(--adaptive-tol "$tol" --max-level 3)
      query="scheme=lsf&adaptive_tol=$tol&max_level=3"
    fi
    echo "$rel $mode" >&2
    rm -f "$TMP/cli.stl" "$TMP/http.stl" "$TMP/cli.json" "$TMP/headers"

    t0=$(date +%s%N)
    timeout "$TIMEOUT" "$BIN/stlrefine" refine "$input" -o "$TMP/cli.stl" --scheme lsf \
      "${cli_args[@]}" --report "$TMP/cli.json" > /dev/null 2> "$TMP/cli.err"
    cli_rc=$?
    cs=$((($(date +%s%N) - t0) / 10000000))
    cli_s=$(printf '%d.%02d' $((cs / 100)) $((cs % 100)))

    http=$(timeout "$TIMEOUT" curl -sS -o "$TMP/http.stl" -D "$TMP/headers" \
      -w '%{http_code} %{time_total}' -H 'Content-Type: model/stl' \
      --data-binary @"$input" "$URL/v1/refine?$query" 2> "$TMP/curl.err")
    curl_rc=$?
    status=${http%% *}
    http_s=$(printf '%.2f' "${http##* }" 2> /dev/null)
    IFS=';' read -r faces_in cli_out http_out repaired < <(fields "$TMP/cli.json" "$TMP/headers")
    [ "$repaired" = - ] && repaired=

    same=—
    if [ "$cli_rc" = 0 ] && [ "$status" = 200 ]; then
      cmp -s "$TMP/cli.stl" "$TMP/http.stl" && same=yes || same=no
    fi
    result=ok
    note=
    if [ "$cli_rc" != 0 ]; then
      note="CLI: $(head -c 160 "$TMP/cli.err" | tr '\n|' '  ')"
      if [ "$cli_rc" -ge 124 ] || [ "$cli_rc" = 1 ]; then result="**BUG**"; else result=refused; fi
    fi
    if [ "$curl_rc" != 0 ] || [ "${status:-000}" = 000 ] || [ "${status:0:1}" = 5 ]; then
      result="**BUG**"
      note="$note HTTP: curl $curl_rc status ${status:-none} $(head -c 200 "$TMP/http.stl" 2> /dev/null | tr '\n|' '  ')"
    elif [ "$status" != 200 ]; then
      [ "$result" = ok ] && result=refused
      note="$note HTTP $status: $(head -c 160 "$TMP/http.stl" | tr '\n|' '  ')"
    fi
    if ! kill -0 "$DAEMON_PID" 2> /dev/null; then
      result="**BUG**"
      note="$note daemon died"
    fi
    [ "$result" = ok ] || [ "$result" = refused ] || bugs=$((bugs + 1))
    [ $mode = adaptive ] && shown_tol=$tol || shown_tol=—
    echo "| $rel | $mode | $shown_tol | ${faces_in:-—} | ${repaired:-—} | ${cli_out:-—} | $cli_s | $cli_rc | ${http_out:-—} | ${http_s:-—} | ${status:-—} | $same | $result${note:+: $note} |"
  done
  if [[ $path == *.gz ]]; then rm -f "$input"; fi
done < <(find "$MESHES" \( -name '*.stl' -o -name '*.stl.gz' \) | sort)
echo "$bugs row(s) marked BUG" >&2
[ "$bugs" = 0 ]
