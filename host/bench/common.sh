# Shared by the compare scripts (sourced): one thread on both sides, best-of-N timing, the ratio.

# Every numeric library and rayon on one thread.
export RAYON_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

# min_of BEST NEW: the smaller of two times in seconds (BEST may be empty: none yet).
min_of() {
    if [ -z "$1" ] || (( $(echo "$2 < $1" | bc -l) )); then echo "$2"; else echo "$1"; fi
}

# print_ratio RUST_LABEL RUST_SECONDS REF_LABEL REF_SECONDS
print_ratio() {
    printf '%-34s %.4f s\n' "$1:" "$2"
    printf '%-34s %.4f s\n' "$3:" "$4"
    printf 'ratio (reference / rollfuse): %.2f×\n' "$(echo "$4 / $2" | bc -l)"
}
