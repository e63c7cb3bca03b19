#!/usr/bin/env bash
# rollfuse vs a numpy + PyWavelets implementation of the same fusion, on the same six
# 1280×960 frames, in one run, single-threaded, best of ROUNDS (default 5) each, the two
# taking turns (image loading and saving excluded on both sides). Prints both times and the
# ratio. The best of several runs is what the code costs without a shared machine's
# neighbours.
#
#   pip install PyWavelets numpy pillow
#   bash host/bench/compare.sh            # ROUNDS=9 bash host/bench/compare.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source host/bench/common.sh
rounds=$(bench_rounds)
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p rollfuse
bin=target/release/rollfuse
letters_1280 "$bin" "$work"
frames=("$work"/frames/frame_000{0..5}.png)
best_rust=""
best_py=""
for _ in $(seq "$rounds"); do
    # `rollfuse fuse` reports its fusion time (image loading excluded, as for the reference).
    rust=$("$bin" fuse "${frames[@]}" --out "$work/rust.png" --align none --levels 1 |
        sed -n 's/.*fusion took \([0-9.]*\) s.*/\1/p')
    py=$(python3 host/bench/ref_fusion.py "$work/py.png" "${frames[@]}" | tail -n 1)
    best_py=$(min_of "$best_py" "$py")
    best_rust=$(min_of "$best_rust" "$rust")
done
print_ratio "rollfuse (fusion only)" "$best_rust" "numpy + PyWavelets (fusion only)" "$best_py"
