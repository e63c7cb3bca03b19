#!/usr/bin/env bash
# Chooses the live page's HTTP server crate by measurement: scratch crates serving one
# route with httparse under std's TcpListener (what the live page uses), with tiny_http
# and with axum on tokio, and an empty `main` to compare against,
# each built cold (its own target folder) in debug and release with the default profiles.
# Prints, per crate, the crates it compiles, both build times and the release binary's
# size. Results and the choice: docs/serve.md, "The server crate". Run it on a quiet
# machine: build times are measured.
set -euo pipefail
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

scratch() { # name, [dependencies], main.rs
    mkdir -p "$work/$1/src"
    printf '[package]\nname = "%s"\nversion = "0.1.0"\nedition = "2024"\n\n[dependencies]\n%s\n' \
        "$1" "$2" > "$work/$1/Cargo.toml"
    printf '%s\n' "$3" > "$work/$1/src/main.rs"
}

scratch empty "" 'fn main() {}'
scratch parse 'httparse = "1.10"' '
use std::io::{Read, Write};
fn main() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    for mut stream in listener.incoming().flatten() {
        let mut buf = [0u8; 4096];
        let n = stream.read(&mut buf).unwrap_or(0);
        let mut headers = [httparse::EMPTY_HEADER; 32];
        if httparse::Request::new(&mut headers).parse(&buf[..n]).is_ok() {
            let _ = stream.write_all(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nok");
        }
    }
}'
scratch tiny 'tiny_http = "0.12"' '
fn main() {
    let server = tiny_http::Server::http("127.0.0.1:0").unwrap();
    for request in server.incoming_requests() {
        let _ = request.respond(tiny_http::Response::from_string("ok"));
    }
}'
scratch axum 'axum = { version = "0.8", default-features = false, features = ["http1", "tokio", "query"] }
tokio = { version = "1", features = ["rt-multi-thread", "net", "sync", "macros"] }
tokio-stream = "0.1"' '
use axum::{Router, routing::get};
#[tokio::main]
async fn main() {
    let app = Router::new().route("/", get(|| async { "ok" }));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    axum::serve(listener, app).await.unwrap();
}'

for name in empty parse tiny axum; do
    dir="$work/$name"
    # Sources fetched first, so the timings are builds only.
    cargo fetch -q --manifest-path "$dir/Cargo.toml"
    crates=$(cargo metadata -q --format-version 1 --manifest-path "$dir/Cargo.toml" |
        python3 -c 'import json, sys; print(len(json.load(sys.stdin)["packages"]) - 1)')
    times=()
    for profile in dev release; do
        start=$(date +%s.%N)
        cargo build -q --profile "$profile" --manifest-path "$dir/Cargo.toml"
        times+=("$(echo "$(date +%s.%N) - $start" | bc)")
    done
    size=$(stat -c %s "$dir/target/release/$name")
    printf '%-6s %3d crates  debug %5.1f s  release %5.1f s  binary %.2f MB\n' \
        "$name" "$crates" "${times[0]}" "${times[1]}" "$(echo "$size / 1000000" | bc -l)"
done
