#!/usr/bin/env bash
# A throwaway one-node Slurm cluster for the Slurm end-to-end test and for trying
# deploy/slurm/gaitsweep-workers.sbatch by hand, from Debian's `slurm-wlm` and `munge`
# packages (installed when missing). Needs root: slurmd starts jobs as their user.
#   scripts/slurm-cluster.sh start DIR   start munged, slurmctld and slurmd with every state,
#                                        spool, log, pid and socket file under DIR, wait until
#                                        the node is idle, print the slurm.conf path (export it
#                                        as SLURM_CONF for sbatch, squeue, scancel, ...)
#   scripts/slurm-cluster.sh stop DIR    cancel every job, stop the daemons by PID (the caller
#                                        removes DIR)
# The node is `localhost` (127.0.0.1) with the machine's CPUs, in the partition `debug`.
# The cluster writes nothing outside DIR but the jobs' output files, so it can run beside a
# system Slurm: its ports are free loopback ports chosen at start, and munged listens on
# DIR/munge/munge.socket with a key of its own. DIR is made traversable by all (a+x):
# munged runs as the `munge` user and insists on it.
set -euo pipefail
cmd="${1:?usage: slurm-cluster.sh start|stop DIR}"
dir="${2:?usage: slurm-cluster.sh start|stop DIR}"
# Daemons live in /usr/sbin, which a non-login root shell may not have on PATH.
export PATH="$PATH:/usr/sbin:/sbin"
# How long each daemon and the node get to come up, seconds.
START_TIMEOUT="${GAITSWEEP_SLURM_START_TIMEOUT:-30}"

die() {
  echo "slurm-cluster: $*" >&2
  exit 1
}

# The last lines of a log, for an error message.
log_tail() {
  if [ -s "$1" ]; then
    echo "---- last lines of $1:" >&2
    tail -n 20 "$1" >&2
  fi
}

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# Waits until the PID file $1 names a live process; fails with the log $2 otherwise.
wait_pid_file() {
  local pidfile="$1" log="$2" what="$3" i
  for ((i = 0; i < START_TIMEOUT * 10; i++)); do
    if [ -s "$pidfile" ] && kill -0 "$(cat "$pidfile")" 2> /dev/null; then
      return 0
    fi
    sleep 0.1
  done
  log_tail "$log"
  die "$what did not start within ${START_TIMEOUT} s"
}

# Stops the process whose PID is in $1: SIGTERM, then SIGKILL after 10 s.
stop_pid_file() {
  local pidfile="$1" pid i
  [ -s "$pidfile" ] || return 0
  pid="$(cat "$pidfile")"
  kill -TERM "$pid" 2> /dev/null || { rm -f "$pidfile"; return 0; }
  for ((i = 0; i < 100; i++)); do
    kill -0 "$pid" 2> /dev/null || { rm -f "$pidfile"; return 0; }
    sleep 0.1
  done
  kill -KILL "$pid" 2> /dev/null || true
  rm -f "$pidfile"
}

stop_daemons() {
  stop_pid_file "$dir/run/slurmd.pid"
  stop_pid_file "$dir/run/slurmctld.pid"
  stop_pid_file "$dir/munge/munged.pid"
}

case "$cmd" in
  start)
    [ "$(id -u)" = 0 ] || die "needs root (slurmd runs jobs as their user, munged as munge)"
    if ! command -v slurmctld > /dev/null 2>&1 || ! command -v slurmd > /dev/null 2>&1 \
      || ! command -v munged > /dev/null 2>&1 || ! command -v sbatch > /dev/null 2>&1; then
      echo "installing Debian's slurm-wlm and munge for the Slurm tests (apt-get install slurm-wlm munge)" >&2
      { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge > /dev/null; } \
        || die "cannot install slurm-wlm and munge with apt-get"
    fi
    id munge > /dev/null 2>&1 || die "the munge package created no munge user"
    mkdir -p "$dir"
    dir="$(cd "$dir" && pwd)"
    [ -e "$dir/slurm.conf" ] && die "$dir already holds a cluster (stop it and use a fresh dir)"
    # A start that fails half-way stops the daemons it started.
    trap '[ $? = 0 ] || stop_daemons' EXIT
    chmod a+x "$dir"
    mkdir -p "$dir/state" "$dir/spool" "$dir/log" "$dir/run"

    # munged refuses a socket directory that others can write or not traverse (clients connect
    # as any user), and a key that others can read.
    install -d -m 0711 -o munge -g munge "$dir/munge"
    dd if=/dev/urandom bs=1 count=1024 of="$dir/munge/munge.key" status=none
    chown munge:munge "$dir/munge/munge.key"
    chmod 0400 "$dir/munge/munge.key"
    munge_socket="$dir/munge/munge.socket"
    runuser -u munge -- munged --socket="$munge_socket" --key-file="$dir/munge/munge.key" \
      --pid-file="$dir/munge/munged.pid" --log-file="$dir/munge/munged.log" \
      --seed-file="$dir/munge/munged.seed" > "$dir/log/munged.out" 2>&1 \
      || { cat "$dir/log/munged.out" >&2; log_tail "$dir/munge/munged.log"; die "munged did not start"; }
    wait_pid_file "$dir/munge/munged.pid" "$dir/munge/munged.log" munged
    munge --socket="$munge_socket" -n < /dev/null | unmunge --socket="$munge_socket" > /dev/null \
      || { log_tail "$dir/munge/munged.log"; die "munged at $munge_socket does not validate its own credential"; }

    # The node as slurmd itself sees it: a smaller CPU topology in slurm.conf than the
    # hardware's is fine, a larger one drains the node.
    topology="$(slurmd -C 2> /dev/null | head -n 1 | grep -o 'CPUs=.* ThreadsPerCore=[0-9]*' || true)"
    [ -n "$topology" ] || topology="CPUs=$(nproc)"
    ctld_port="$(free_port)"
    slurmd_port="$(free_port)"
    while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port="$(free_port)"; done
    cat > "$dir/slurm.conf" << EOF
# Written by scripts/slurm-cluster.sh: a one-node cluster with all its files under $dir.
ClusterName=gaitsweep
SlurmctldHost=localhost(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$munge_socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MailProg=/bin/true
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=60
# Seconds between SIGTERM and SIGKILL when a job is cancelled or hits its time limit:
# a stopping worker finishes its epoch and uploads its checkpoints first (at most 60 s).
KillWait=90
MinJobAge=300
NodeName=localhost NodeAddr=127.0.0.1 $topology RealMemory=1024 State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
    export SLURM_CONF="$dir/slurm.conf"
    # -D keeps each daemon in the foreground, so the PID it writes is the one to stop;
    # -c (slurmctld) starts without old state, -N names the node independent of hostname.
    setsid slurmctld -D -c -f "$SLURM_CONF" > "$dir/log/slurmctld.out" 2>&1 < /dev/null &
    wait_pid_file "$dir/run/slurmctld.pid" "$dir/log/slurmctld.log" slurmctld
    setsid slurmd -D -N localhost -f "$SLURM_CONF" > "$dir/log/slurmd.out" 2>&1 < /dev/null &
    wait_pid_file "$dir/run/slurmd.pid" "$dir/log/slurmd.log" slurmd
    state=""
    for ((i = 0; i < START_TIMEOUT * 5; i++)); do
      state="$(timeout 10 sinfo -h -n localhost -o %T 2> /dev/null || true)"
      [ "$state" = idle ] && break
      sleep 0.2
    done
    if [ "$state" != idle ]; then
      log_tail "$dir/log/slurmctld.log"
      log_tail "$dir/log/slurmd.log"
      die "node localhost is not idle after ${START_TIMEOUT} s (state: ${state:-no answer from slurmctld})"
    fi
    echo "$SLURM_CONF"
    ;;
  stop)
    dir="$(cd "$dir" 2> /dev/null && pwd)" || exit 0
    if [ -s "$dir/run/slurmctld.pid" ] && [ -e "$dir/slurm.conf" ]; then
      export SLURM_CONF="$dir/slurm.conf"
      # Jobs first, while slurmd is there to signal their processes (SIGTERM, SIGKILL after
      # KillWait): stopping slurmd alone would leave them running.
      timeout 10 scancel --full --partition=debug > /dev/null 2>&1 || true
      deadline=$((SECONDS + 120))
      while jobs="$(timeout 10 squeue -h -o %i 2> /dev/null)" && [ -n "$jobs" ]; do
        if [ "$SECONDS" -ge "$deadline" ]; then
          echo "slurm-cluster: jobs still there after 120 s, stopping the daemons anyway: $jobs" >&2
          break
        fi
        sleep 0.2
      done
    fi
    stop_daemons
    ;;
  *)
    echo "usage: slurm-cluster.sh start|stop DIR" >&2
    exit 2
    ;;
esac
