#!/usr/bin/env bash
# Starts a throwaway PostgreSQL server on loopback for the records' tests and prints the
# URL to test against (the records' suite reads ROLLFUSE_TEST_POSTGRES). Debian's package,
# installed if missing; the server runs as the `postgres` user from a fresh data folder
# with password authentication, so a wrong password is refused as on a site's server.
# Usage: url="$(bash .ci/postgres.sh start DIR)"; bash .ci/postgres.sh stop DIR
# Exits non-zero, with the reason on stderr, when no server can be had.
set -euo pipefail
action="$1" dir="$2"
# Another port with ROLLFUSE_PG_PORT (a second server beside CI's).
port="${ROLLFUSE_PG_PORT:-54329}"
bin="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)"
as_postgres() {
    if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}
case "$action" in
start)
    if [ -z "$bin" ]; then
        if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
            apt-get install -y -q postgresql >&2 || true
        fi
        bin="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)"
        [ -n "$bin" ] || { echo "no PostgreSQL server (apt-get install postgresql)" >&2; exit 1; }
    fi
    mkdir -p "$dir"
    [ "$(id -u)" = 0 ] && chown postgres "$dir"
    echo rollfuse-ci > "$dir/pw"
    as_postgres "$bin/initdb" -D "$dir/data" -U rollfuse --pwfile="$dir/pw" \
        -A scram-sha-256 >"$dir/initdb.log" 2>&1 || { cat "$dir/initdb.log" >&2; exit 1; }
    as_postgres "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w \
        -o "-c listen_addresses=127.0.0.1 -p $port -k $dir -c fsync=off" start >/dev/null \
        || { cat "$dir/server.log" >&2; exit 1; }
    echo "postgres://rollfuse:rollfuse-ci@127.0.0.1:$port/postgres"
    ;;
stop)
    [ -n "$bin" ] && [ -d "$dir/data" ] && as_postgres "$bin/pg_ctl" -D "$dir/data" -m fast stop >/dev/null || true
    rm -rf "$dir"
    ;;
esac
