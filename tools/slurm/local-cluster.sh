#!/usr/bin/env bash
# A single-node Slurm "cluster" on this machine, for tests: munged, slurmctld and slurmd on
# localhost with a generated slurm.conf under a state folder. Needs root and Debian's
# `slurm-wlm` and `munge` packages.
#
#   tools/slurm/local-cluster.sh start STATE_DIR   # prints `export SLURM_CONF=…` on stdout
#   tools/slurm/local-cluster.sh stop STATE_DIR
set -euo pipefail
cmd=${1:?usage: local-cluster.sh start|stop STATE_DIR}
state=$(realpath -m "${2:?usage: local-cluster.sh start|stop STATE_DIR}")

case "$cmd" in
start)
  mkdir -p "$state"/{spool,ctld,log,munge}
  host=$(hostname -s)
  cpus=$(nproc)
  mem_mb=$(awk '/MemTotal/ {printf "%d", $2 / 1024 * 0.9}' /proc/meminfo)
  cat > "$state/slurm.conf" <<CONF
ClusterName=penumbra-ci
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CryptoType=crypto/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
SchedulerType=sched/backfill
SlurmctldPort=6817
SlurmdPort=6818
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$state/log/slurmctld.log
SlurmdLogFile=$state/log/slurmd.log
NodeName=$host CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
CONF
  export SLURM_CONF="$state/slurm.conf"
  # munge: its own socket and pid under the state folder (root needs --force).
  if ! pgrep -x munged >/dev/null; then
    mkdir -p /run/munge && chown munge:munge /run/munge 2>/dev/null || true
    munged --force >/dev/null 2>&1 || sudo -u munge munged
  fi
  slurmctld -f "$SLURM_CONF"
  slurmd -f "$SLURM_CONF"
  for _ in $(seq 1 60); do
    if sinfo -h -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
      echo "export SLURM_CONF=$SLURM_CONF"
      exit 0
    fi
    sleep 1
  done
  echo "local-cluster.sh: the node did not come up; see $state/log" >&2
  sinfo >&2 || true
  tail -n 20 "$state"/log/*.log >&2 || true
  exit 1
  ;;
stop)
  pids=()
  for d in slurmd slurmctld; do
    if [ -f "$state/$d.pid" ]; then
      pid=$(cat "$state/$d.pid")
      kill "$pid" 2>/dev/null && pids+=("$pid")
    fi
  done
  # Wait (up to 30 s) until the daemons have exited: slurmctld writes its state files while it
  # shuts down, and a caller that deletes STATE_DIR at once races with it.
  for _ in $(seq 300); do
    alive=0
    for pid in "${pids[@]}"; do
      kill -0 "$pid" 2>/dev/null && alive=1
    done
    [ "$alive" = 0 ] && break
    sleep 0.1
  done
  ;;
*)
  echo "usage: local-cluster.sh start|stop STATE_DIR" >&2
  exit 2
  ;;
esac
