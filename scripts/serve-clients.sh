#!/usr/bin/env bash
# Does watching slow the stream? Runs the same virtual-device stream with and without 20
# clients following /events, alternating, and compares the files (must be identical) and
# the wall time the stream reports. A measurement, not a test: it states a ratio.
#
#   bash scripts/serve-clients.sh [ROLLFUSE] [FRAMES] [RUNS]
#
# ROLLFUSE defaults to target/release/rollfuse, FRAMES (the letters scene lengthened) to
# 2000, RUNS (of each kind) to 3. FRAME_RATE=HZ paces the virtual device as a camera would
# (--frame-rate); by default it runs in virtual time, as fast as the 2 cores allow, so the
# clients' threads compete with it for the CPU. Needs curl.
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/release/rollfuse}"
frames="${2:-2000}"
runs="${3:-3}"
clients=20
pace=()
[ -n "${FRAME_RATE:-}" ] && pace=(--frame-rate "$FRAME_RATE")
work="$(mktemp -d)"
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    [ -n "${KEEP_WORK:-}" ] || rm -rf "$work"
}
trap cleanup EXIT

sed "s/^frames = .*/frames = $frames/" host/scenes/letters.toml > "$work/scene.toml"

# Seconds the stream took, from its summary line ("N tiles in S s ...").
seconds_of() { sed -n 's/^[0-9]* tiles in \([0-9.]*\) s.*/\1/p' "$1"; }

run_plain() {
    "$bin" stream --device sim --scene "$work/scene.toml" --out "$work/plain" "${pace[@]}" > "$work/plain.log"
    seconds_of "$work/plain.log"
}

run_watched() {
    local fifo="$work/said"
    rm -f "$fifo" && mkfifo "$fifo"
    "$bin" stream --device sim --scene "$work/scene.toml" --out "$work/watched" \
        --serve 127.0.0.1:0 "${pace[@]}" > "$fifo" &
    local stream=$!
    exec 3< "$fifo"
    local line addr
    read -r line <&3
    addr="${line#live page: }"
    pids=()
    for _ in $(seq "$clients"); do
        curl -sN "${addr}events" > /dev/null &
        pids+=($!)
    done
    cat <&3 > "$work/watched.log"
    exec 3<&-
    wait "$stream"
    for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
    pids=()
    seconds_of "$work/watched.log"
}

plain=() watched=()
for _ in $(seq "$runs"); do
    plain+=("$(run_plain)")
    watched+=("$(run_watched)")
    # A live device answers the session's heartbeat (one status a second of wall time),
    # so the manifest's message and byte counts follow the run's duration; all else,
    # and every strip file, must be identical.
    for f in $(ls "$work/plain"); do
        if [ "$f" = manifest.json ]; then
            heartbeat='"(messages|bytes|messages_sent)":'
            same() { diff -q <(grep -Ev "$heartbeat" "$1") <(grep -Ev "$heartbeat" "$2") > /dev/null; }
        else
            same() { cmp -s "$1" "$2"; }
        fi
        same "$work/plain/$f" "$work/watched/$f" ||
            { echo "FAIL: $f differs with $clients clients"; exit 1; }
    done
done
tiles="$(sed -n 's/^\([0-9]*\) tiles in.*/\1/p' "$work/plain.log")"
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print a[int((NR + 1) / 2)]}'; }
mp="$(median "${plain[@]}")" mw="$(median "${watched[@]}")"
echo "stream of $tiles tiles ($frames frames), $runs runs each:"
echo "  without clients: ${plain[*]} s (median $mp)"
echo "  with $clients /events clients: ${watched[*]} s (median $mw)"
echo "  strip files identical, manifests identical but for the heartbeat's message counts; wall-time ratio (with / without): $(awk -v a="$mw" -v b="$mp" 'BEGIN {printf "%.3f", a / b}')"
