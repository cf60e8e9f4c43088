#!/usr/bin/env bash
# Installs (once) Debian's Slurm (slurmctld, slurmd, sbatch, …) and MUNGE, the
# single-node cluster scripts/slurm/cluster.sh starts for scripts/slurm/test-cluster.sh.
# Idempotent and quiet: does nothing when the daemons and client commands are there.
# Needs root (apt-get). The packages' own services are not started (no systemd here;
# cluster.sh starts the daemons itself with a private configuration).
set -euo pipefail
have() {
  local c
  for c in munged mungekey slurmctld slurmd sbatch scancel squeue sinfo; do
    command -v "$c" >/dev/null 2>&1 || [ -x "/usr/sbin/$c" ] || return 1
  done
}
if have; then exit 0; fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
  echo "setup-slurm: slurm-wlm / munge are missing and apt-get cannot run here (need root on Debian)" >&2
  exit 1
fi
pkgs=(slurm-wlm munge)
echo "setup-slurm: installing ${pkgs[*]} (apt-get)" >&2
export DEBIAN_FRONTEND=noninteractive
# policy-rc.d 101: the packages' postinst must not start munge/slurm services.
policy=/usr/sbin/policy-rc.d
own_policy=
if [ ! -e "$policy" ]; then
  printf '#!/bin/sh\nexit 101\n' >"$policy" && chmod +x "$policy" && own_policy=1
fi
cleanup() { if [ -n "$own_policy" ]; then rm -f "$policy"; fi; }
trap cleanup EXIT
apt-get install -y -qq --no-install-recommends "${pkgs[@]}" >&2 ||
  { apt-get update -qq >&2 && apt-get install -y -qq --no-install-recommends "${pkgs[@]}" >&2; }
have || { echo "setup-slurm: installed, but munged / slurmctld / slurmd / sbatch are still missing" >&2; exit 1; }
