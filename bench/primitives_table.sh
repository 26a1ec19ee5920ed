#!/bin/sh
# Issue 17 items 4, 6, 7: the post-pass on the shared CAD meshes, per scheme, primitives=off
# (measured only: --max-deviation 0) and auto (--primitives auto; the default is off). Prints one markdown row per run.
# usage: bench/primitives_table.sh BUILD_DIR MESH_DIR
set -eu
bin=$1/bin/stlrefine
dir=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "| mesh | scheme | levels | off: max dist | auto: max dist before | auto: max dist | default bound (max) | pulled | regions | snapped (+curve) | refused | worst normal change deg (off / auto) | >60 deg (off / auto) | collapsed (off / auto) | fold fallbacks | refine s | detect s | pass s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for m in fandisk featuretype_open gearwheel round tray_bottom xyz_cube_20mm; do
  for s in lsf butterfly sqrt3-interp loop; do
    l=2
    [ "$s" = sqrt3-interp ] && l=4
    "$bin" refine "$dir/$m.stl" -o "$tmp/o.stl" --scheme $s --levels $l --threads 1 \
      --primitives off --max-deviation 0 --report "$tmp/off.json" >/dev/null
    mv "$tmp/o.stl" "$tmp/off.stl"
    "$bin" refine "$dir/$m.stl" -o "$tmp/o.stl" --scheme $s --levels $l --threads 1 \
      --primitives auto --report "$tmp/auto.json" >/dev/null
    python3 - "$tmp/off.json" "$tmp/auto.json" "$m" "$s" "$l" "$tmp/off.stl" "$tmp/o.stl" <<'PY'
import json, struct, sys
def collapsed(path):
    # Faces with two corners at the same (float32) point: no normal, so the report's
    # turned-face count skips them.
    data = open(path, "rb").read()
    n = struct.unpack_from("<I", data, 80)[0]
    count = 0
    for i in range(n):
        v = struct.unpack_from("<9f", data, 84 + 50 * i + 12)
        a, b, c = v[0:3], v[3:6], v[6:9]
        count += a == b or b == c or c == a
    return count
off = json.load(open(sys.argv[1])); a = json.load(open(sys.argv[2]))
do, da, p = off["deviation"], a["deviation"], a["primitives"]
g = lambda x: f"{x:.3g}"
print(f"| {sys.argv[3]} | {sys.argv[4]} | {sys.argv[5]} | {g(do['max_distance_from_input'])} | "
      f"{g(da['max_distance_before'])} | {g(da['max_distance_from_input'])} | "
      f"{g(da['max_bound']) if da['bound'] == 'auto' else da['bound']} | {da['pulled_back']} | "
      f"{p.get('regions_found', '-')} | {p.get('snapped', '-')} (+{p.get('snapped_to_curve', '-')}) | "
      f"{p.get('snap_refused', '-')} | {g(do['worst_normal_change_deg'])} / {g(da['worst_normal_change_deg'])} | "
      f"{do['faces_turned_over_60_deg']} / {da['faces_turned_over_60_deg']} | "
      f"{collapsed(sys.argv[6])} / {collapsed(sys.argv[7])} | {a['fold_fallbacks']} | "
      f"{g(a['seconds']['refine'])} | {g(da['detect_seconds'])} | {g(da['seconds'])} |")
PY
  done
done
