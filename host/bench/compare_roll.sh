#!/usr/bin/env bash
# A whole roll, whole process: `rollfuse fuse` (decode, align by matching, fuse over the
# contact window, write the strip) against a numpy + PyWavelets reference of the same
# windowed fusion given the known offsets (host/bench/ref_roll.py), on 240 frames of
# host/bench/roll.toml at 320×240 and at 640×480. One core for both (taskset where it
# exists, and one thread each), best of ROUNDS (default 5) runs, taking turns. Prints each
# time per frame, how many times faster than the camera's 30 frames/s, and the ratio.
#
#   pip install PyWavelets numpy pillow
#   bash host/bench/compare_roll.sh          # ROUNDS=9 bash host/bench/compare_roll.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source host/bench/common.sh
rounds=$(bench_rounds)
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p rollfuse
bin="$PWD/target/release/rollfuse"
pin=()
command -v taskset > /dev/null && pin=(taskset -c 0)

# seconds COMMAND...: wall time of one run.
seconds() {
    local t0 t1
    t0=$(date +%s.%N)
    "$@" > /dev/null
    t1=$(date +%s.%N)
    echo "$t1 - $t0" | bc -l
}

for size in 320x240 640x480; do
    w=${size%x*} h=${size#*x}
    mmpp=$(printf "%.6f" "$(echo "0.05 * 320 / $w" | bc -l)")
    sed -e "s/^mm_per_px = .*/mm_per_px = $mmpp/" -e "s/^width_px = .*/width_px = $w/" \
        -e "s/^height_px = .*/height_px = $h/" host/bench/roll.toml > "$work/roll_$size.toml"
    "$bin" simulate "$work/roll_$size.toml" --out "$work/$size" > /dev/null
    frames=$(ls "$work/$size"/frame_*.png | wc -l)
    best_rust="" best_py=""
    for _ in $(seq "$rounds"); do
        rust=$(seconds "${pin[@]}" "$bin" fuse "$work/$size" --out "$work/rust_$size.png")
        py=$(seconds "${pin[@]}" python3 host/bench/ref_roll.py "$work/py_$size.png" "$work/$size")
        best_rust=$(min_of "$best_rust" "$rust")
        best_py=$(min_of "$best_py" "$py")
    done
    echo "== $frames frames of $size"
    print_ratio "rollfuse fuse (whole process)" "$best_rust" "numpy reference (whole process)" "$best_py"
    printf 'rollfuse: %.2f ms a frame, %.1f× real time at 30 frames/s\n' \
        "$(echo "1000 * $best_rust / $frames" | bc -l)" \
        "$(echo "($frames / 30) / $best_rust" | bc -l)"
done
