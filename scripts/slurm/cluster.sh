#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, for scripts/slurm/test-cluster.sh.
#
#   scripts/slurm/cluster.sh up DIR     # DIR: a new or empty directory for all its state
#   export SLURM_CONF=DIR/slurm.conf    # then sbatch, squeue, scancel, scontrol talk to it
#   scripts/slurm/cluster.sh down DIR   # stops everything it started, removes DIR
#
# `up` installs slurm-wlm and munge if missing (scripts/setup-slurm.sh), writes a MUNGE key
# and a slurm.conf into DIR (one node `localhost` with 2 CPUs, one partition `hilcam`,
# select/cons_tres, proctrack/linuxproc, task/none: no cgroups, no systemd, no accounting),
# starts munged, slurmctld and slurmd as root on free 127.0.0.1 ports with that config, and
# waits until the node is idle. If any step fails, `up` runs `down` itself.
# `down` cancels the cluster's jobs, stops its daemons (and any job process left: every
# process whose environment holds SLURM_CONF=DIR/slurm.conf), SIGKILL after a grace period,
# and fails if one survives. Needs root.
set -euo pipefail
# down finds job processes by SLURM_CONF in their environment: this script and its
# subshells must not carry it (the caller may have exported it for sbatch).
if [ -n "${SLURM_CONF+x}" ]; then exec env -u SLURM_CONF "$0" "$@"; fi
cmd=${1:-}
dir=${2:-}
if [ -z "$cmd" ] || [ -z "$dir" ] || [ $# -ne 2 ]; then
  echo "usage: $0 up|down DIR" >&2
  exit 2
fi
dir=$(realpath -m "$dir")
conf=$dir/slurm.conf
PATH=$PATH:/usr/sbin

# Slurm's client commands, pointed at this cluster. (SLURM_CONF is not exported here:
# the daemons and jobs carry it in their environment, which is how down finds them.)
sl() { SLURM_CONF=$conf "$@"; }

say() { echo "cluster.sh: $*" >&2; }

# This script's ancestors (never to be stopped, whatever their environment).
ancestors() {
  local p=$$
  while [ "$p" -gt 1 ]; do
    echo "$p"
    p=$(ps -o ppid= -p "$p" 2>/dev/null || echo 1)
    p=${p// /}
  done
}

# Our processes: the daemons by pid file, everything else by SLURM_CONF in its environment.
our_pids() {
  local p env
  for p in "$dir"/munged.pid "$dir"/slurmctld.pid "$dir"/slurmd.pid; do
    [ -s "$p" ] && kill -0 "$(cat "$p")" 2>/dev/null && cat "$p"
  done
  for env in /proc/[0-9]*/environ; do
    if { tr '\0' '\n' <"$env" | grep -qxF "SLURM_CONF=$conf"; } 2>/dev/null; then
      p=${env#/proc/}
      echo "${p%/environ}"
    fi
  done | sort -u | grep -vxF -f <(ancestors) || true
}

any_alive() {
  local p
  for p in "$@"; do kill -0 "$p" 2>/dev/null && return 0; done
  return 1
}

# Send SIGTERM to the pids given, wait up to $1 s, then SIGKILL what is left.
stop_pids() {
  local grace=$1 i
  shift
  [ $# -gt 0 ] || return 0
  kill -TERM "$@" 2>/dev/null || true
  for ((i = 0; i < grace * 10; i++)); do
    any_alive "$@" || return 0
    sleep 0.1
  done
  say "SIGKILL to $* (still running after ${grace} s)"
  kill -KILL "$@" 2>/dev/null || true
  sleep 0.5
}

pid_of() { [ -s "$dir/$1.pid" ] && cat "$dir/$1.pid"; }

down() {
  [ -d "$dir" ] || return 0
  local left i
  if [ -s "$dir/slurmctld.pid" ] && command -v scancel >/dev/null; then
    sl timeout 10 scancel --partition=hilcam 2>/dev/null || true
    for ((i = 0; i < 150; i++)); do
      [ -z "$(sl timeout 5 squeue -h -o %i 2>/dev/null)" ] && break
      sleep 0.1
    done
  fi
  # slurmd first (no new steps), then the controller, then whatever job process is left,
  # then munged (the others authenticate through it until they stop).
  # shellcheck disable=SC2046 # word splitting of the pid lists is intended
  stop_pids 10 $(pid_of slurmd)
  # shellcheck disable=SC2046
  stop_pids 10 $(pid_of slurmctld)
  # shellcheck disable=SC2046
  stop_pids 10 $(our_pids | grep -vxF "$(pid_of munged || echo none)")
  # shellcheck disable=SC2046
  stop_pids 5 $(pid_of munged)
  left=$(our_pids | tr '\n' ' ')
  if [ -n "$left" ]; then
    say "down: processes still running: $left"
    return 1
  fi
  rm -rf "$dir"
  say "down: stopped munged, slurmctld, slurmd; removed $dir"
}

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

write_conf() {
  local host ctld_port d_port
  host=$(hostname -s)
  ctld_port=$(free_port)
  d_port=$(free_port)
  while [ "$d_port" = "$ctld_port" ]; do d_port=$(free_port); done
  mkdir -p "$dir/ctld" "$dir/spool" "$dir/logs"
  cat >"$conf" <<CONF
# Written by scripts/slurm/cluster.sh: a private single-node cluster (state in $dir).
ClusterName=hilcam
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge.socket
StateSaveLocation=$dir/ctld
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/logs/slurmctld.log
SlurmdLogFile=$dir/logs/slurmd.log
# No cgroups (no systemd on this machine): processes tracked by parent pid, no binding.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
# scancel: SIGTERM, then SIGKILL after KillWait seconds (hilcam finishes the frame in hand).
KillWait=10
SchedulerParameters=sched_interval=1
NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=hilcam Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
}

up() {
  if [ "$(id -u)" != 0 ]; then
    say "up: needs root (daemons run as root with a private config)"
    return 1
  fi
  "$(dirname "$0")/../setup-slurm.sh"
  if [ -e "$dir" ] && [ -n "$(ls -A "$dir")" ]; then
    say "up: $dir is not empty"
    return 1
  fi
  mkdir -p "$dir"
  # munged wants its socket's directory searchable by all; the key stays 0600.
  chmod 755 "$dir"
  trap 'say "up failed; logs:"; tail -n 20 "$dir"/logs/*.log >&2 || true; down' ERR
  write_conf
  mungekey -c -k "$dir/munge.key"
  munged --key-file="$dir/munge.key" --socket="$dir/munge.socket" --pid-file="$dir/munged.pid" \
    --log-file="$dir/logs/munged.log" --seed-file="$dir/munged.seed"
  sl slurmctld -c -f "$conf"
  sl slurmd -N localhost -f "$conf"
  local i state=
  for ((i = 0; i < 300; i++)); do
    state=$(sl timeout 5 sinfo -h -N -n localhost -o %t 2>/dev/null || true)
    [ "$state" = idle ] && break
    sleep 0.1
  done
  if [ "$state" != idle ]; then
    say "up: node localhost is '${state:-unknown}' after 30 s, not idle"
    false
  fi
  trap - ERR
  say "up: munged, slurmctld, slurmd running; node localhost idle (2 CPUs); export SLURM_CONF=$conf"
}

case $cmd in
  up) up ;;
  down) down ;;
  *) echo "usage: $0 up|down DIR" >&2; exit 2 ;;
esac
