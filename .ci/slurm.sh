#!/usr/bin/env bash
# A real single-node Slurm on localhost for the batch test: installs Debian's munge and Slurm
# when missing, writes a configuration into a temporary folder, starts munged, slurmctld and
# slurmd (each remembered by pid), runs the Slurm test target (or the command given after `--`),
# and stops exactly the daemons it started on exit, whatever the outcome.
#
#   bash .ci/slurm.sh            # the test: cargo test --release --test suite slurm:: -- --ignored
#   bash .ci/slurm.sh -- CMD...  # any command with SLURM_CONF set, e.g. `-- bash` to try things
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null \
  || ! command -v sbatch >/dev/null || ! command -v munged >/dev/null; then
  echo "== installing munge and Slurm"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurmctld slurmd slurm-client munge >/dev/null
fi

work=$(mktemp -d /tmp/scanatlas-slurm.XXXXXX)
pids=()
stop_daemons() {
  local status=$?
  # Newest first: slurmd, then slurmctld, then munged, each by the pid this script started.
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
    kill -TERM "${pids[i]}" 2>/dev/null || true
  done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
  if [ "$status" -ne 0 ]; then
    for log in "$work"/*.log "$work"/*.out; do
      [ -f "$log" ] && { echo "--- $log (last lines)"; tail -n 30 "$log"; }
    done
  fi
  rm -rf "$work"
  exit "$status"
}
trap stop_daemons EXIT

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

mkdir -p "$work/state" "$work/spool" "$work/munge"
chmod 700 "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 600 "$work/munge/munge.key"
socket="$work/munge/munge.socket"

host=$(hostname -s)
# The node line as slurmd sees this machine (CPUs, sockets, cores, threads, memory).
node=$(slurmd -C | head -n 1)
ctld_port=$(free_port)
slurmd_port=$(free_port)
while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(free_port); done

export SLURM_CONF="$work/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=scanatlas-ci
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
ReturnToService=2
$node State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF

echo "== starting munged, slurmctld, slurmd (config $SLURM_CONF)"
munged -F --force --socket="$socket" --key-file="$work/munge/munge.key" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/munged.log" \
  --seed-file="$work/munge/munged.seed" >"$work/munged.out" 2>&1 &
pids+=($!)
for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
[ -S "$socket" ] || { echo "munged did not open its socket $socket" >&2; exit 1; }

slurmctld -D -i -f "$SLURM_CONF" >"$work/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" >"$work/slurmd.out" 2>&1 &
pids+=($!)

# Wait until the node takes jobs.
ready=
for _ in $(seq 120); do
  state=$(sinfo -h -n "$host" -o '%t' 2>/dev/null || true)
  case "$state" in idle*|mix*|alloc*) ready=1; break ;; esac
  sleep 0.5
done
if [ -z "$ready" ]; then
  echo "Slurm did not come up (node state: '${state:-unreachable}')" >&2
  exit 1
fi
sinfo

if [ "${1:-}" = "--" ]; then
  shift
  "$@"
else
  # The default members in the release profile, so that the dependencies' features unify as in .ci/run's
  # `cargo test --release` (the README command) and nothing but the test is built again.
  echo "== Slurm test: cargo test --release --test suite slurm:: -- --ignored"
  SCANATLAS_SLURM=1 cargo test --release --test suite slurm:: -- --ignored --nocapture
fi
