#!/usr/bin/env bash
# Re-processes 20 recorded rolls into the inspection records on a local Dask cluster of
# one worker, then of two, and prints rolls per second for each (docs/records.md).
#
# Needs the Python package and Dask in the Python that runs it:
#   python3 -m venv .venv && .venv/bin/pip install ./python "dask[distributed]"
#   PYTHON=.venv/bin/python bash scripts/batch-records.sh [OUT] [RECORDS]
# RECORDS: a SQLite file (default OUT/records.db, made anew for each cluster size) or a
# postgres:// URL. The 20 recordings are made first with the `rollfuse` on PATH (or
# $ROLLFUSE): the textile scene, 400 frames each, one seed a roll.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-out/batch}"
records="${2:-$out/records.db}"
python="${PYTHON:-python3}"
rollfuse="${ROLLFUSE:-rollfuse}"
mkdir -p "$out/recordings" "$out/scenes"
for i in $(seq 1 20); do
    rec="$out/recordings/roll$(printf %02d "$i").rfrec"
    [ -s "$rec" ] && continue
    scene="$out/scenes/textile-$i.toml"
    sed -e "s/^seed = .*/seed = $((100 + i))/" -e "s/^frames = .*/frames = 400/" \
        host/scenes/textile.toml > "$scene"
    rm -rf "$out/scratch"
    "$rollfuse" stream --device sim --scene "$scene" --out "$out/scratch" --record "$rec" \
        --progress none > /dev/null 2>&1
done
rm -rf "$out/scratch"
"$python" scripts/batch_records.py "$out/recordings" --records "$records" \
    --out "$out/strips" --engine dask --workers 1,2
