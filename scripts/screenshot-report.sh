#!/usr/bin/env bash
# Opens the demo's report in headless Chromium, fails if the page logs an error, and saves
# a screenshot of it.
#
#   bash scripts/screenshot-report.sh [REPORT=out/demo/report.html] [PNG=docs/img/report.png]
#
# Needs Debian's chromium (`apt-get install -y chromium`); runs `cargo run --release --
# demo` first when the report does not exist yet.
set -euo pipefail
cd "$(dirname "$0")/.."
report=${1:-out/demo/report.html}
png=${2:-docs/img/report.png}
browser=$(command -v chromium || command -v chromium-browser || true)
if [[ -z "$browser" ]]; then
    echo "SKIPPED: no chromium found (apt-get install -y chromium)" >&2
    exit 0
fi
if [[ ! -f "$report" ]]; then
    cargo run --release --quiet -- demo --out "$(dirname "$report")"
fi
mkdir -p "$(dirname "$png")"
url="file://$(realpath "$report")"
flags=(--headless --no-sandbox --disable-gpu --hide-scrollbars --allow-file-access-from-files)
log=$(mktemp)
trap 'rm -f "$log"' EXIT
# The DOM as Chromium parsed it, with its console messages on stderr: a broken page logs.
"$browser" "${flags[@]}" --enable-logging=stderr --v=0 --dump-dom "$url" >"$log.dom" 2>"$log" || {
    cat "$log" >&2
    echo "chromium could not open $report" >&2
    exit 1
}
if grep -E "CONSOLE|Uncaught|Failed to load|net::ERR" "$log" >&2; then
    echo "the report logged errors in chromium (above)" >&2
    exit 1
fi
grep -q "<h2>7. " "$log.dom" || { echo "the report did not render completely" >&2; exit 1; }
rm -f "$log.dom"
# The top of the page: frames, the strip, the fusion, Tables II–III and the depth maps.
"$browser" "${flags[@]}" --window-size=1100,2700 --screenshot="$(realpath -m "$png")" "$url" 2>/dev/null
echo "screenshot of $report → $png"
