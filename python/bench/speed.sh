#!/usr/bin/env bash
# rollfuse.fuse from Python against the command line's fusion and against the numpy +
# PyWavelets reference of the same algorithm (host/bench/ref_fusion.py), on the same six
# 1280×960 frames, in one run, single-threaded, the three taking turns for ROUNDS rounds
# (default 5), the best of each kept (file reading and writing excluded on every side).
# Builds the release wheel into a fresh venv first. Prints the three times and the ratios.
#
#   bash python/bench/speed.sh            # ROUNDS=9 bash python/bench/speed.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source host/bench/common.sh
rounds=$(bench_rounds)
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p rollfuse
bin=target/release/rollfuse
python3 -m venv "$work/venv"
py="$work/venv/bin/python"
"$work/venv/bin/pip" install -q numpy pillow PyWavelets
CARGO_TARGET_DIR="$PWD/target" MATURIN_PEP517_ARGS="--strip" "$work/venv/bin/pip" install -q ./python

letters_1280 "$bin" "$work"
frames=("$work"/frames/frame_000{0..5}.png)
best_cli="" best_module="" best_ref=""
for _ in $(seq "$rounds"); do
    cli=$("$bin" fuse "${frames[@]}" --out "$work/cli.png" --align none --levels 1 |
        sed -n 's/.*fusion took \([0-9.]*\) s.*/\1/p')
    module=$("$py" python/bench/speed.py 3 "${frames[@]}" | tail -n 1)
    ref=$("$py" host/bench/ref_fusion.py "$work/ref.png" "${frames[@]}" | tail -n 1)
    best_cli=$(min_of "$best_cli" "$cli")
    best_module=$(min_of "$best_module" "$module")
    best_ref=$(min_of "$best_ref" "$ref")
done
printf '%-40s %.4f s\n' "rollfuse.fuse from Python (in-process):" "$best_module"
printf '%-40s %.4f s\n' "rollfuse fuse (the CLI's fusion):" "$best_cli"
printf '%-40s %.4f s\n' "numpy + PyWavelets reference:" "$best_ref"
printf 'Python / CLI: %.2f× (target ≤ 1.3×)\n' "$(echo "$best_module / $best_cli" | bc -l)"
printf 'reference / Python: %.1f× (target ≥ 15×)\n' "$(echo "$best_ref / $best_module" | bc -l)"
