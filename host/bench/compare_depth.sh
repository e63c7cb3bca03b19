#!/usr/bin/env bash
# rollfuse depth vs a numpy + scipy implementation of the same steps, on the same 640×480
# image of a ball, in one run, single-threaded, best of five each (loading and saving
# excluded on both sides). Prints both times and the ratio, and the largest difference
# between the two height maps.
#
#   pip install numpy scipy pillow
#   bash host/bench/compare_depth.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p rollfuse
bin=target/release/rollfuse
python3 host/bench/ref_depth.py --make "$work"

source host/bench/common.sh
best_rust=""
best_py=""
for _ in 1 2 3 4 5; do
    rust=$("$bin" depth "$work/ball.png" --lights "$work/lights.toml" \
        --background "$work/background.png" --out "$work/rust" |
        sed -n 's/.*took \([0-9.]*\) s.*/\1/p')
    py=$(python3 host/bench/ref_depth.py "$work/ball.png" "$work/lights.toml" \
        "$work/background.png" "$work/py.npy" | tail -n 1)
    best_py=$(min_of "$best_py" "$py")
    best_rust=$(min_of "$best_rust" "$rust")
done
print_ratio "rollfuse depth (one thread)" "$best_rust" "numpy + scipy (one thread)" "$best_py"
python3 -c "
import numpy as np
a, b = np.load('$work/rust.npy'), np.load('$work/py.npy')
print(f'largest height difference: {np.abs(a - b).max():.2e} mm (peak {a.max():.3f} mm)')"
