#!/usr/bin/env bash
# CI lints through clippy-driver as the workspace's compiler (see .ci/run). Were the driver
# ever to stop reading CLIPPY_ARGS, every build would pass with lints as mere warnings;
# this builds a scratch crate with one lint under the same environment and fails unless
# the build fails on it.
set -euo pipefail
: "${RUSTC_WORKSPACE_WRAPPER:?set it to clippy-driver first}"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
mkdir -p "$scratch/src"
cat > "$scratch/Cargo.toml" <<'TOML'
[package]
name = "clippy-probe"
version = "0.0.0"
edition = "2024"
[workspace]
TOML
# clippy::len_zero (style, on by default).
echo 'fn main() { let v = [std::env::args().count()]; if v.len() == 0 { println!(); } }' \
    > "$scratch/src/main.rs"
if out="$(cargo build -q --manifest-path "$scratch/Cargo.toml" \
    --target-dir "$scratch/target" 2>&1)"; then
    echo "clippy's lints are not failing builds: a crate with a lint built" >&2
    exit 1
fi
if ! grep -q "clippy::len_zero\|length comparison to zero" <<< "$out"; then
    echo "the probe failed for another reason than the lint:" >&2
    echo "$out" >&2
    exit 1
fi
echo "clippy lints the builds and fails them on a warning"
