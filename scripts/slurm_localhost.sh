#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, for tests/explore/test_slurm.py (run by .ci/run): Debian's slurm-wlm and munge,
# slurmctld and slurmd on localhost, the node named by `hostname`. Root, no systemd needed.
#
#   scripts/slurm_localhost.sh install   apt-get install slurm-wlm and munge (if sbatch is missing)
#   scripts/slurm_localhost.sh start     write the configuration, start munged, slurmctld and slurmd, wait until idle
#   scripts/slurm_localhost.sh stop      stop the three daemons by their PID files
#
# The settings are the ones a single container needs: processes tracked from /proc (no cgroup), no task plugin,
# consumable cores and memory, every daemon as root except munged (which refuses to run as root).
set -euo pipefail

CONF_DIR=/etc/slurm
RUN_DIR=/run/roughsense-slurm
NODE=$(hostname)

install() {
  if ! command -v sbatch >/dev/null 2>&1 || ! command -v munged >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
  fi
}

configure() {
  local cpus memory_mb
  cpus=$(nproc)
  memory_mb=$(( $(awk '/^MemTotal:/ {print $2}' /proc/meminfo) / 1024 - 512 ))  # leave the system some room
  mkdir -p "$CONF_DIR" "$RUN_DIR" /var/spool/slurmctld /var/spool/slurmd /var/log/slurm
  cat >"$CONF_DIR/slurm.conf" <<EOF
ClusterName=roughsense
SlurmctldHost=$NODE
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=$RUN_DIR/slurmctld.pid
SlurmdPidFile=$RUN_DIR/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
ReturnToService=2
MpiDefault=none
NodeName=$NODE CPUs=$cpus RealMemory=$memory_mb State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
  # munge: a key of 1024 random bytes, owned by munge and readable by it alone
  mkdir -p /etc/munge /run/munge /var/lib/munge /var/log/munge
  if [ ! -s /etc/munge/munge.key ]; then
    head -c 1024 /dev/urandom >/etc/munge/munge.key
  fi
  chown -R munge:munge /etc/munge /run/munge /var/lib/munge /var/log/munge
  chmod 0700 /etc/munge
  chmod 0400 /etc/munge/munge.key
}

running() {  # is the daemon of PID file $1 alive?
  [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null
}

start() {
  configure
  running /run/munge/munged.pid || runuser -u munge -- /usr/sbin/munged
  running "$RUN_DIR/slurmctld.pid" || slurmctld
  running "$RUN_DIR/slurmd.pid" || slurmd
  for _ in $(seq 1 60); do  # idle after ~3 s on this machine kind; a minute before giving up
    state=$(sinfo -h -N -o %t 2>/dev/null | head -n 1 || true)
    if [ "$state" = idle ] || [ "$state" = mix ]; then
      echo "slurm: node $NODE $state"
      return 0
    fi
    sleep 1
  done
  echo "slurm: node $NODE did not become idle (state '${state:-none}'); see /var/log/slurm" >&2
  return 1
}

stop() {
  local pidfile
  for pidfile in "$RUN_DIR/slurmd.pid" "$RUN_DIR/slurmctld.pid" /run/munge/munged.pid; do
    if running "$pidfile"; then
      kill "$(cat "$pidfile")"
    fi
  done
}

case "${1:-}" in
  install) install ;;
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 install|start|stop" >&2; exit 2 ;;
esac
