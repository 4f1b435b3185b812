# Sourced by scripts/demo.sh and scripts/record-sweep.sh: the background processes they
# start (append each pid to `pids`, the coordinator first) are stopped when the script
# exits, on success, error, Ctrl-C or SIGTERM, and a bounded wait for the files a process
# writes once it is ready.

pids=()

# The first process started (the coordinator) is stopped last: the others (workers, a
# watcher) are stopped first and waited for, so that a worker stopped mid-cell finishes its
# epoch, uploads a checkpoint and gives the cell back while the coordinator still listens.
cleanup() {
  trap - EXIT INT TERM
  local rest=("${pids[@]:1}")
  for p in "${rest[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${rest[@]}"; do wait "$p" 2>/dev/null || true; done
  if [ "${#pids[@]}" -gt 0 ]; then
    kill "${pids[0]}" 2>/dev/null || true
    wait 2>/dev/null || true
  fi
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
