# Shared by the compare scripts (sourced): one thread on both sides, best-of-N timing, the ratio.

# Every numeric library and rayon on one thread.
export RAYON_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

# min_of BEST NEW: the smaller of two times in seconds (BEST may be empty: none yet).
# ROUNDS from the environment (default 5), checked: a whole number from 1 up; exits the
# calling script with 2 and a message otherwise (rounds=$(bench_rounds), under set -e).
bench_rounds() {
    local rounds="${ROUNDS:-5}"
    if ! [[ "$rounds" =~ ^[1-9][0-9]*$ ]]; then
        echo "$(basename "$0"): ROUNDS must be a whole number from 1 up, not '$rounds'" >&2
        exit 2
    fi
    echo "$rounds"
}

min_of() {
    if [ -z "$1" ] || (( $(echo "$2 < $1" | bc -l) )); then echo "$2"; else echo "$1"; fi
}

# print_ratio RUST_LABEL RUST_SECONDS REF_LABEL REF_SECONDS
print_ratio() {
    printf '%-34s %.4f s\n' "$1:" "$2"
    printf '%-34s %.4f s\n' "$3:" "$4"
    printf 'ratio (reference / rollfuse): %.2f×\n' "$(echo "$4 / $2" | bc -l)"
}

# letters_1280 BIN OUT: six frames of the letters scene at 1280×960 (the same field of
# view, finer pixels) simulated by BIN into OUT/frames; OUT must exist.
letters_1280() {
    sed -e 's/^mm_per_px = .*/mm_per_px = 0.0125/' -e 's/^width_px = .*/width_px = 1280/' \
        -e 's/^height_px = .*/height_px = 960/' -e 's/^frames = .*/frames = 6/' \
        host/scenes/letters.toml > "$2/letters_1280.toml"
    "$1" simulate "$2/letters_1280.toml" --out "$2/frames" > /dev/null
}
