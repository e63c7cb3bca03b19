#!/usr/bin/env bash
# Builds the Cortex-M7 instruction-count bench, runs it under QEMU (mps2-an500,
# -icount shift=0) and writes its CSV to OUT (default target/mcu-bench/mcu-bench.csv),
# headed by the SHA-256 of the binary that produced it.
#
#   bash tests/mcu-bench/run.sh [OUT]          run once
#   bash tests/mcu-bench/run.sh --check [OUT]  run twice, require identical numbers and
#                                              sane values (what CI does)
#
# Needs the thumbv7em-none-eabihf target and qemu-system-arm (Debian: qemu-system-arm).
set -euo pipefail
check=false
if [ "${1:-}" = "--check" ]; then
    check=true
    shift
fi
# OUT is relative to the caller's directory, resolved before changing to this one.
out="${1:+$(realpath -m "$1")}"
cd "$(dirname "$0")"
root="$(cd ../.. && pwd)"
out="${out:-$root/target/mcu-bench/mcu-bench.csv}"
mkdir -p "$(dirname "$out")"

cargo build -q --release --target thumbv7em-none-eabihf --target-dir "$root/target"
elf="$root/target/thumbv7em-none-eabihf/release/rollfuse-mcu-bench"
build_id="$(sha256sum "$elf" | cut -c1-16)"

run() {
    timeout 600 qemu-system-arm -machine mps2-an500 -cpu cortex-m7 -icount shift=0 \
        -nographic -monitor none -serial none \
        -semihosting-config enable=on,target=native -kernel "$elf"
}

# With --check the second run goes beside the first: counts are in instructions, so
# sharing the host's cores changes none.
second=""
if $check; then
    second="$(mktemp)"
    trap 'rm -f "$second"' EXIT
    { echo "# build $build_id"; run; } > "$second" &
    second_run=$!
fi
if ! {
    echo "# build $build_id"
    run
} > "$out.part"; then
    # The bench says why on its `#` lines (an instruction that disagrees with its
    # definition, a panic).
    grep '^# ' "$out.part" | grep -v '^# \(build\|rollfuse-mcu-bench\|board\|section\)' >&2 || true
    echo "mcu-bench: the bench failed" >&2
    exit 1
fi
mv "$out.part" "$out"

if $check; then
    wait "$second_run" || true
    if ! diff -q "$out" "$second" > /dev/null; then
        echo "mcu-bench: two runs of one build differ:" >&2
        diff "$out" "$second" >&2 || true
        exit 1
    fi
    # Sane: the calibration loop shows 40 instructions per SysTick tick, every
    # configuration ran, and every per-pixel count is positive and below 10 000.
    awk -F, '
        /^calibration/ { cal = $10 }
        /^pipeline/ { p++ }
        /^(kernel|tile|pipeline)/ { if (!($11 > 0 && $11 < 10000)) { bad = bad " " $1 "/" $2 } }
        END {
            if (cal != 40) { print "mcu-bench: calibration gave " cal " instructions per tick, not 40"; exit 1 }
            if (p != 72) { print "mcu-bench: " p " of 72 pipeline configurations ran"; exit 1 }
            if (bad != "") { print "mcu-bench: implausible per-pixel counts:" bad; exit 1 }
        }' "$out" >&2
    echo "mcu-bench: two runs identical, numbers sane"
fi
echo "mcu-bench: $out (build $build_id)"
grep -E '^pipeline,frame_fixed,db2,1,1,frame' "$out" |
    awk -F, '{ printf "default (db2, 1 level, 1x, per frame): %d instructions per frame, %.1f per camera pixel\n", $10, $11 }'
