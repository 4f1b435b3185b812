# Sourced by scripts/demo.sh and scripts/record-sweep.sh: the background processes they
# start (append each pid to `pids`) are stopped when the script exits, on success, error,
# Ctrl-C or SIGTERM, and a bounded wait for the files a process writes once it is ready.

pids=()

cleanup() {
  trap - EXIT INT TERM
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}

# stop_on_exit MESSAGE: stop every process in `pids` on exit; on Ctrl-C or SIGTERM print
# MESSAGE first and exit 130.
stop_on_exit() {
  local msg="$1"
  trap cleanup EXIT
  trap 'echo "'"$msg"'" >&2; exit 130' INT TERM
}

# wait_for_file FILE: true once FILE is non-empty, false if it is not within 10 seconds.
wait_for_file() {
  for _ in $(seq 1 100); do
    [ -s "$1" ] && return 0
    sleep 0.1
  done
  [ -s "$1" ]
}
