#!/usr/bin/env bash
# Peak memory of `rollfuse fuse` on a roll of 1 000 and of 20 000 frames of 320×240
# (/usr/bin/time -v, maximum resident set size). The 20 000 frames are the 1 000 rendered
# frames of host/bench/roll.toml named again in order (links), so the long roll costs no
# extra rendering; its strip is a repeating one, which changes nothing in what is held.
#
#   bash host/bench/memory_roll.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p rollfuse
bin="$PWD/target/release/rollfuse"
sed -e 's/^frames = .*/frames = 1000/' host/bench/roll.toml > "$work/roll.toml"
"$bin" simulate "$work/roll.toml" --out "$work/rendered" > /dev/null
mkdir "$work/short" "$work/long"
rendered=("$work"/rendered/frame_*.png)
for k in $(seq 0 19999); do
    src="${rendered[$((k % 1000))]}"
    name=$(printf 'frame_%05d.png' "$k")
    [ "$k" -lt 1000 ] && ln -s "$src" "$work/short/$name"
    ln -s "$src" "$work/long/$name"
done
peak() {
    /usr/bin/time -v "$bin" fuse "$1" --out "$2" 2> "$work/time.txt" > /dev/null
    sed -n 's/.*Maximum resident set size (kbytes): \([0-9]*\)/\1/p' "$work/time.txt"
}
short=$(peak "$work/short" "$work/short.png")
long=$(peak "$work/long" "$work/long.png")
printf 'peak RSS, 1 000 frames:  %6.1f MB\n' "$(echo "$short / 1000" | bc -l)"
printf 'peak RSS, 20 000 frames: %6.1f MB\n' "$(echo "$long / 1000" | bc -l)"
printf 'difference:              %6.1f MB\n' "$(echo "($long - $short) / 1000" | bc -l)"
ls "$work" | grep -c '^long\.[0-9]*\.png$' | xargs printf '20 000-frame strip: %s segments\n'
