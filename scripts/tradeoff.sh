#!/usr/bin/env bash
# Regenerates the trade-off study in docs/tradeoff/: the Cortex-M7 bench under QEMU
# (instructions per frame for every configuration; its tables in mcu-bench.md), then
# `rollfuse tradeoff`, which fuses the letters scene with every configuration, measures host
# time and accuracy against the f64 reference, reads the bench's CSV and writes
# tradeoff.md, tradeoff.csv and pareto.svg.
#
#   bash scripts/tradeoff.sh [OUT]     (default docs/tradeoff)
#
# Without qemu-system-arm or the thumbv7em target the bench is skipped (loudly) and the
# study reports host time only. Run it on a quiet machine: host times are measured.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-docs/tradeoff}"
csv=target/mcu-bench/mcu-bench.csv
mkdir -p "$out"

if command -v qemu-system-arm > /dev/null &&
    rustup target list --installed 2> /dev/null | grep -x thumbv7em-none-eabihf > /dev/null; then
    bash tests/mcu-bench/run.sh "$csv"
    bash tests/mcu-bench/table.sh "$csv" > "$out/mcu-bench.md"
else
    echo "SKIPPED: the Cortex-M7 bench (needs qemu-system-arm and the thumbv7em-none-eabihf target)" >&2
    rm -f "$csv"
fi
cargo build --release -q -p rollfuse
target/release/rollfuse tradeoff --out "$out" --bench "$csv"
