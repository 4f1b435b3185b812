# Sourced by scripts/demo.sh and scripts/record-sweep.sh: the background processes they
# start (append each pid to `pids`, the coordinator first) are stopped when the script
# exits, on success, error, Ctrl-C or SIGTERM, and a bounded wait for the files a process
# writes once it is ready.

pids=()

# The first process started (the coordinator) is stopped last: the others (workers, a
# watcher) are stopped first, so that a worker stopped mid-cell finishes its epoch, uploads a
# checkpoint and gives the cell back while the coordinator still listens. Each wait is
# bounded and polls rather than using `wait PID`: two stops of a recording hung with bash in
# `wait` and the coordinator never signalled (session 35), which these steps' log lines
# would show next time.
cleanup() {
  trap - EXIT INT TERM
  local rest=("${pids[@]:1}")
  if [ "${#rest[@]}" -gt 0 ]; then
    echo "stopping: signalled ${#rest[@]} processes ($(date -u +%T)); waiting for the workers to give their cells back" >&2
    for p in "${rest[@]}"; do kill "$p" 2>/dev/null || true; done
    # A worker in its final evaluation finishes it first (2-3 minutes at 256 robots).
    for p in "${rest[@]}"; do stop_within 600 "$p"; done
  fi
  if [ "${#pids[@]}" -gt 0 ]; then
    echo "stopping: the coordinator, pid ${pids[0]} ($(date -u +%T))" >&2
    kill "${pids[0]}" 2>/dev/null || true
    stop_within 60 "${pids[0]}"
  fi
  wait 2>/dev/null || true
}

# stop_within SECONDS PID: true once PID (signalled already) has exited; after SECONDS,
# kills it with SIGKILL and says so.
stop_within() {
  local i
  for ((i = 0; i < $1 * 5; i++)); do
    kill -0 "$2" 2>/dev/null || return 0
    sleep 0.2
  done
  echo "pid $2 ($(ps -o args= -p "$2" 2>/dev/null)) did not stop within $1 s of SIGTERM: killing it" >&2
  kill -KILL "$2" 2>/dev/null || true
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
