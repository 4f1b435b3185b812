#!/usr/bin/env bash
# A throwaway PostgreSQL cluster for the tests and the load bench, from Debian's
# `postgresql` package (installed when missing).
#   scripts/pg-cluster.sh start DIR   initdb in DIR, start the server on a free loopback
#                                     port, print its URL (postgres://gaitsweep@127.0.0.1:PORT/postgres)
#   scripts/pg-cluster.sh stop DIR    stop it (the caller removes DIR)
# PostgreSQL refuses to run as root: as root, the server runs as the package's `postgres` user.
set -euo pipefail
cmd="${1:?usage: pg-cluster.sh start|stop DIR}"
dir="${2:?usage: pg-cluster.sh start|stop DIR}"

pg_bin() {
  local d
  for d in $(ls -d /usr/lib/postgresql/*/bin 2> /dev/null | sort -V -r); do
    [ -x "$d/initdb" ] && { echo "$d"; return 0; }
  done
  command -v initdb > /dev/null 2>&1 && { dirname "$(command -v initdb)"; return 0; }
  return 1
}

as_owner() {
  if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}

case "$cmd" in
  start)
    if ! bin="$(pg_bin)"; then
      echo "installing Debian's postgresql for the PostgreSQL store tests (apt-get install postgresql)" >&2
      if [ "$(id -u)" = 0 ]; then
        apt-get update -qq && apt-get install -y -qq postgresql > /dev/null
      else
        sudo apt-get update -qq && sudo apt-get install -y -qq postgresql > /dev/null
      fi
      bin="$(pg_bin)"
      # Debian's package creates and starts a system cluster of its own; only ours is wanted.
      if command -v pg_lsclusters > /dev/null 2>&1; then
        pg_lsclusters -h | while read -r version name _; do
          pg_ctlcluster "$version" "$name" stop > /dev/null 2>&1 || true
        done
      fi
    fi
    mkdir -p "$dir"
    [ "$(id -u)" = 0 ] && chown postgres "$dir"
    as_owner "$bin/initdb" -D "$dir/data" -U gaitsweep --auth=trust -E UTF8 > "$dir/initdb.log" 2>&1 \
      || { cat "$dir/initdb.log" >&2; exit 1; }
    port="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
    as_owner "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w \
      -o "-p $port -k $dir -c listen_addresses=127.0.0.1 -c max_connections=200" start > /dev/null \
      || { cat "$dir/server.log" >&2; exit 1; }
    echo "postgres://gaitsweep@127.0.0.1:$port/postgres"
    ;;
  stop)
    bin="$(pg_bin)"
    as_owner "$bin/pg_ctl" -D "$dir/data" -m fast -w stop > /dev/null
    ;;
  *)
    echo "usage: pg-cluster.sh start|stop DIR" >&2
    exit 2
    ;;
esac
