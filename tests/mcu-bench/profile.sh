#!/usr/bin/env bash
# Where one configuration's frame goes, by function: builds the bench with the feature
# `profile` for that configuration alone, runs it under QEMU with its execution log
# (-d exec,nochain,in_asm) and counts the instructions of the measured frames by function
# (tests/mcu-bench/profile.py). The bench's own count for the same frames is printed with
# it: the two agree to a SysTick tick or so.
#
#   bash tests/mcu-bench/profile.sh [wavelet,levels,downsample,norm,precision]
#
# e.g. `db2,1,1,frame,fixed` (the default), `db2,2,2,frame,fixed` (half resolution).
# The log of 16 frames of db2 at 1x takes about 320 MB, in target/mcu-profile/ (removed after).
set -euo pipefail
spec="${1:-db2,1,1,frame,fixed}"
cd "$(dirname "$0")"
root="$(cd ../.. && pwd)"
dir="$root/target/mcu-profile"
mkdir -p "$dir"

ROLLFUSE_PROFILE="$spec" cargo build -q --release --target thumbv7em-none-eabihf \
    --features profile --target-dir "$dir"
elf="$dir/thumbv7em-none-eabihf/release/rollfuse-mcu-bench"
log="$dir/exec.log"
trap 'rm -f "$log"' EXIT
if ! timeout 1200 qemu-system-arm -machine mps2-an500 -cpu cortex-m7 -icount shift=0 \
    -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native -kernel "$elf" \
    -d exec,nochain,in_asm -D "$log" > "$dir/bench.csv"; then
    # The bench says why on its output (a configuration it cannot run, a panic).
    grep '^# ' "$dir/bench.csv" | grep -v '^# \(rollfuse-mcu-bench\|board\|section\)' >&2 || true
    echo "profile: the bench failed for configuration $spec" >&2
    exit 1
fi
echo "configuration $spec, the bench's count (instructions per frame, mean of 8):"
grep -E '^pipeline' "$dir/bench.csv" | awk -F, '{ printf "  %d\n\n", $10 }'
# Sections: the calibration loop, 8 warm-up frames, then the 8 measured.
python3 profile.py "$log" --last 8
