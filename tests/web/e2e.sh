#!/bin/sh
# Runs e2e.mjs when everything it needs is here. Arguments (from CMakeLists.txt):
#   NODE NODE_MODULES STLREFINED ARTIFACT_DIR MESH PAGE_BUILT
# Exit 77 (ctest: skipped) when node, chromium or the page is missing on a developer
# machine; under CI (CI=true) a missing piece is a failure, since CI installs them all.
node=$1 modules=$2 daemon=$3 artifacts=$4 mesh=$5 built=$6

missing() {
  echo "web_e2e: $1" >&2
  if [ "${CI:-}" = "true" ]; then
    echo "web_e2e: CI=true, so this is a failure (scripts/setup.sh installs nodejs, npm, chromium)" >&2
    exit 1
  fi
  echo "web_e2e: SKIPPED (apt-get install nodejs npm chromium, then reconfigure and rebuild)" >&2
  exit 77
}

case "$node" in "" | *NOTFOUND) missing "node was not found when stlrefine was configured" ;; esac
[ -x "$node" ] || missing "node ($node) is gone"
[ "$built" = "ON" ] || missing "stlrefined was built without the web page (STLREFINE_WEB_BUILT=$built)"
[ -f "$modules/playwright-core/package.json" ] || missing "playwright-core is not in $modules (the npm ci build step did not run)"
chromium=${STLREFINE_CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}
[ -n "$chromium" ] || missing "no chromium on PATH (Debian: apt-get install chromium)"

exec "$node" "$(dirname "$0")/e2e.mjs" --node-modules "$modules" --daemon "$daemon" \
  --chromium "$chromium" --artifacts "$artifacts" --mesh "$mesh"
