#!/usr/bin/env bash
# Chooses the detector's ML crate by measurement: the same network (stem 16, blocks 32 and
# 64, a 64-channel head, a 17-class classifier) built with candle and with burn, each timed
# for one AdamW training step on a batch of 16 crops of 128 × 128 (median of 10) and one
# inference of a 320 × 240 image, on all threads and on one. Prints each build's wall
# time from clean. Results and the choice: docs/detect.md, "Why burn".
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
target=${TARGET_DIR:-$here/../../../target/ml_choice}
for crate in candle burn; do
    rm -rf "$target/$crate"
    start=$(date +%s)
    cargo build --release --quiet --manifest-path "$here/$crate/Cargo.toml" --target-dir "$target/$crate"
    echo "$crate: clean release build $(( $(date +%s) - start )) s"
done
for crate in candle burn; do
    bin="$target/$crate/release/ml_choice_$crate"
    echo "$crate, all threads: $("$bin")"
    echo "$crate, one thread:  $(RAYON_NUM_THREADS=1 "$bin")"
done
