#!/usr/bin/env bash
# Markdown tables from the bench's CSV (default target/mcu-bench/mcu-bench.csv): the device
# pipeline per configuration against the frame budget, and the default configuration's
# kernels. docs/tradeoff.md shows its output.
#
#   bash tests/mcu-bench/table.sh [CSV]
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
csv="${1:-$root/target/mcu-bench/mcu-bench.csv}"
[ -f "$csv" ] || { echo "no bench output at $csv: run tests/mcu-bench/run.sh first" >&2; exit 1; }

# 30 frames/s at 480 MHz: 16 M cycles per frame; the pipeline may take 10 % of it.
awk -F, -v budget=1600000 '
    /^# build/ { build = $0; sub(/^# build /, "", build) }
    /^pipeline/ {
        if (!header) {
            print "| wavelet | levels | downsample | normalized per | fuse step | instructions / frame | per downsampled pixel | % of a frame at 480 MHz, 30 fps | within 10 % | fits the firmware'"'"'s RAM |"
            print "|---|---|---|---|---|---:|---:|---:|---|---|"
            header = 1
        }
        precision = $2; sub(/^frame_/, "", precision)
        printf "| %s | %s | %s× | %s | %s | %d | %.1f | %.1f %% | %s | %s |\n", $3, $4, $5, $6, precision, $10, $11, 100 * $10 / 16000000, ($10 <= budget ? "yes" : "no"), ($13 == 1 ? "yes" : "no")
    }
    END { printf "\nBench build %s.\n", build }
' "$csv"

echo
echo "Default configuration (db2, 1 level, the camera's full resolution, per-frame normalization, QVGA YUYV in):"
echo
awk -F, '
    /^kernel,[^,]*,db2,1,1,/ { k[$2] = $10; kp[$2] = $11; kpx[$2] = $7 }
    /^pipeline,frame_fixed,db2,1,1,frame/ { frame = $10; per = $11; obs = $12 }
    /^tile,fuse_fixed,db2,1,1,frame/ { fuse = $10; fusepx = $11; tilepx = $7 }
    /^tile,fuse_f32,db2,1,1,frame/ { fuse32 = $10; fuse32px = $11 }
    END {
        print "| part | instructions per call | per pixel it works on | calls per frame (tile observations, the first of each tile a copy) |"
        print "|---|---:|---:|---:|"
        printf "| whole pipeline | %d | %.1f (per camera pixel) | 1 |\n", frame, per
        split("downsample row_profile refine_shift laplacian_max", names, " ")
        for (i = 1; i <= 4; i++) printf "| %s | %d | %.2f | 1 |\n", names[i], k[names[i]], kp[names[i]]
        printf "| fuse step, integer (one %d-pixel tile; in 16-bit lanes) | %d | %.1f | %.2f |\n", tilepx, fuse, fusepx, obs
        printf "| 32-bit forward lifting of one image (lifting::forward_2d) | %d | %.1f | |\n", k["forward_2d"], kp["forward_2d"]
        printf "| its inverse (lifting::inverse_2d, saturating every load) | %d | %.1f | |\n", k["inverse_2d"], kp["inverse_2d"]
        printf "| the fuse step with max-abs(coefficient) selection, no saliency (32-bit: the ablations do not run in lanes) | %d | %.1f | |\n", k["fuse_max_high"], kp["fuse_max_high"]
        printf "| fuse step, f32 on the FPU (same tile) | %d | %.1f | |\n", fuse32, fuse32px
    }' "$csv"
