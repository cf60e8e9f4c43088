#!/usr/bin/env bash
# hilcam's copy of the shared vcan-vm recipe (shared/recipes/vcan-vm.{sh,md}),
# adapted: the cache defaults to ~/.cache/hilcam/vcan-vm so CI keeps it between
# runs; scripts/test.sh runs tests/can_socketcan.rs through it (vcan0 + vcan1).
#
# vcan-vm.sh - run one command inside a throwaway QEMU guest whose kernel has
# SocketCAN, with virtual CAN interface(s) (default: vcan0) already up.
#
# For hosts whose own kernel lacks CAN support (no CONFIG_CAN, no vcan module),
# e.g. containers / sandboxes / CI machines where `ip link add vcan0 type vcan`
# fails with "Unknown device type" and socket(AF_CAN, ...) fails.
#
# Usage:
#   vcan-vm.sh [--] COMMAND [ARGS...]   run COMMAND in the guest, exit with its status
#   vcan-vm.sh --prepare                only build/refresh the cached kernel+initramfs
#   vcan-vm.sh --help
#   As a cargo runner: CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER=/path/vcan-vm.sh cargo test
#
# How it works (more in vcan-vm.md next to this script):
#   * A Debian kernel package (default: the one linux-image-amd64 points to) is
#     fetched with `apt-get download` and unpacked with `dpkg-deb -x` into the
#     cache; it is NOT installed on the host. Its kernel (also cut out as an
#     uncompressed vmlinux for a fast direct PVH boot) and the needed modules
#     (can, can-raw, can-bcm, can-gw, can-isotp, can-j1939, can-dev, vcan, vxcan,
#     virtio-pci, virtio-console, 9p, overlay) go into a small busybox initramfs.
#   * The guest mounts the host's / read-only over virtio-9p, puts a tmpfs overlay
#     on top (writes work but are thrown away at poweroff), chroots into it and
#     runs COMMAND with the caller's environment and working directory. So
#     dynamically linked binaries, scripts and `cargo test` work unchanged.
#   * COMMAND's stdout and stderr are streamed to this script's stdout and stderr
#     (two virtio-serial ports); its stdin is /dev/null; it runs as root.
#   * KVM is used when it really works (vmx/svm in /proc/cpuinfo, not the
#     para-virtual "kvm_pvm"); otherwise QEMU's software emulation (TCG).
#
# Needs: bash, apt-get/dpkg-deb (Debian or derivative, x86_64), Debian packages
#   qemu-system-x86 and busybox-static (installed automatically when missing and
#   running as root; so is xz-utils), coreutils, util-linux (flock), grep with -P.
#
# Environment knobs (all optional):
#   VCAN_VM_CACHE       cache folder (default: ~/.cache/hilcam/vcan-vm)
#   VCAN_VM_IFACES      space separated vcan interfaces to create (default: vcan0;
#                       empty = none)
#   VCAN_VM_VXCAN       space separated vxcan pairs "a:b" to create (default: none;
#                       needs iproute2 on the host)
#   VCAN_VM_MEM         guest RAM in MiB (default: 1024); overlay writes live in it
#   VCAN_VM_CPUS        guest vCPUs (default: 1 under TCG, up to 4 under KVM)
#   VCAN_VM_ACCEL       auto | kvm | tcg (default: auto)
#   VCAN_VM_TIMEOUT     seconds before the whole VM is killed, 0 = never (default: 1800)
#   VCAN_VM_BOOT_TIMEOUT seconds for the guest to come up (default: 30 KVM, 300 TCG);
#                       in auto mode a failed KVM boot is retried with TCG
#   VCAN_VM_RW_DIRS     colon separated host folders the guest writes to for real
#                       (mounted read-write at the same path), e.g. for test reports
#   VCAN_VM_KERNEL_PKG  Debian kernel image package (default: resolved from
#                       linux-image-amd64; the "cloud" flavour has no CAN modules)
#   VCAN_VM_KERNEL_DEB  path of an already downloaded linux-image-*.deb (offline use)
#   VCAN_VM_BUSYBOX     path of a statically linked busybox (default: /bin/busybox)
#   VCAN_VM_AUTO_INSTALL 1 (default) = apt-get install missing packages when root
#   VCAN_VM_REBUILD     1 = rebuild the cached kernel+initramfs
#   VCAN_VM_APPEND      extra guest kernel command line parameters
#   VCAN_VM_QEMU_ARGS   extra QEMU options (word-split)
#   VCAN_VM_VERBOSE     1 = print progress and the guest's console log
#   VCAN_VM_KEEP_JOB    1 = keep the per-run job folder (console log, job script)
#
# Exit status: COMMAND's exit status (128+N if it died from signal N), or
#   124 if VCAN_VM_TIMEOUT expired, 125 if the VM itself failed (the guest's
#   console log is then printed to stderr), 127 if COMMAND is not found on the
#   host, 141 if whoever read our stdout/stderr went away (the VM is stopped).

set -euo pipefail

RECIPE_REV=8   # bump when the initramfs layout/init changes (invalidates caches)

me=${0##*/}
say()  { printf '%s: %s\n' "$me" "$*" >&2; }
vsay() { [ "${VCAN_VM_VERBOSE:-0}" = 1 ] && say "$@" || true; }
die()  { say "error: $*"; exit 125; }

usage() { sed -n '2,/^$/{s/^# \{0,1\}//;p}' "$0"; }

# ---------------------------------------------------------------- arguments
mode=run
case "${1:-}" in
  -h|--help) usage; exit 0 ;;
  --prepare) mode=prepare; shift ;;
  --) shift ;;
  "") usage >&2; exit 125 ;;
esac
if [ "$mode" = run ] && [ $# -eq 0 ]; then usage >&2; exit 125; fi

CACHE=${VCAN_VM_CACHE:-${HOME:-/tmp}/.cache/hilcam/vcan-vm}
BUSYBOX=${VCAN_VM_BUSYBOX:-/bin/busybox}
AUTO_INSTALL=${VCAN_VM_AUTO_INSTALL:-1}

is_root() { [ "$(id -u)" = 0 ]; }

BUILD_WORK='' JOB='' qpid='' opid='' epid=''
cleanup() {
  local p
  for p in $qpid $opid $epid; do kill "$p" 2>/dev/null || true; done
  [ -z "$BUILD_WORK" ] || rm -rf "$BUILD_WORK"
  if [ -n "$JOB" ]; then
    if [ "${VCAN_VM_KEEP_JOB:-0}" = 1 ]; then say "job folder kept: $JOB"; else rm -rf "$JOB"; fi
  fi
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

apt_updated=0
apt_update_once() {
  [ $apt_updated = 1 ] && return 0
  vsay "apt-get update"
  apt-get update -qq >/dev/null 2>&1 || say "warning: apt-get update failed"
  apt_updated=1
}

apt_install() {  # pkg...
  if [ "$AUTO_INSTALL" != 1 ] || ! is_root || ! command -v apt-get >/dev/null; then
    die "missing Debian package(s): $* (install them: apt-get install --no-install-recommends $*)"
  fi
  say "installing $* (apt-get) ..."
  if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null 2>&1; then
    apt_update_once
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null \
      || die "apt-get install $* failed"
  fi
}

is_static() { # file: true if not dynamically linked
  local o; o=$(LC_ALL=C ldd "$1" 2>&1 || true)
  case "$o" in *"not a dynamic executable"*|*"statically linked"*) return 0 ;; esac
  return 1
}

ensure_host_tools() {
  local need=()
  command -v qemu-system-x86_64 >/dev/null || need+=(qemu-system-x86)
  command -v xz >/dev/null || need+=(xz-utils)
  if [ ! -x "$BUSYBOX" ] || ! is_static "$BUSYBOX"; then
    [ -n "${VCAN_VM_BUSYBOX:-}" ] && die "VCAN_VM_BUSYBOX=$BUSYBOX is not a static executable"
    need+=(busybox-static)
  fi
  [ ${#need[@]} -eq 0 ] || apt_install "${need[@]}"
  command -v qemu-system-x86_64 >/dev/null || die "qemu-system-x86_64 not found"
  [ -x "$BUSYBOX" ] && is_static "$BUSYBOX" || die "no static busybox at $BUSYBOX"
}

# ------------------------------------------------------------ kernel + initramfs
# Modules wanted in the guest. "!" = required (the run fails without it).
WANT_MODULES="!can !can_raw can_bcm can_gw can_isotp can_j1939 !can_dev !vcan vxcan
 !virtio_pci !virtio_console !9pnet_virtio !9p !overlay"

resolve_kernel_pkg() {
  if [ -n "${VCAN_VM_KERNEL_PKG:-}" ]; then echo "$VCAN_VM_KERNEL_PKG"; return; fi
  local p
  p=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}') || true
  if [ -z "$p" ] && is_root; then
    apt_update_once
    p=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}') || true
  fi
  [ -n "$p" ] || die "cannot resolve linux-image-amd64 (run apt-get update, or set VCAN_VM_KERNEL_PKG / VCAN_VM_KERNEL_DEB)"
  echo "$p"
}

init_script() {
cat <<'EOF'
#!/bin/sh
# PID 1 of the vcan-vm guest (busybox). Per-run settings come from /job/config.sh.
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
log() { echo "vcan-vm-init: $*" >/dev/console; }
finish() { # exit code
  echo "$1" >/job/exit-code 2>/dev/null
  echo "VCAN-VM-EXIT-CODE=$1" >/dev/console
  sync
  poweroff -f
  sleep 5
}
fail() { log "FATAL: $*"; finish 125; }

while read -r m; do
  insmod "/lib/modules/$m" || log "insmod $m failed"
done </modules.list

mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 vcanjob /job || fail "cannot mount job share"
. /job/config.sh || fail "cannot read /job/config.sh"

hostname vcan-vm
ip link set dev lo up || fail "lo up"
for i in $VCAN_IFACES; do
  ip link add dev "$i" type vcan || fail "ip link add $i type vcan"
  ip link set dev "$i" up || fail "ip link set $i up"
done
mount -t 9p -o trans=virtio,version=9p2000.L,ro,cache=loose,msize=262144 hostroot /lower \
  || fail "cannot mount host root"
mount -t tmpfs -o mode=0755 tmpfs /rw
mkdir -p /rw/upper /rw/work
mount -t overlay -o lowerdir=/lower,upperdir=/rw/upper,workdir=/rw/work overlay /newroot \
  || fail "cannot mount overlay"
mount -t proc proc /newroot/proc || fail "proc"
mount -t sysfs sysfs /newroot/sys || fail "sys"
mount -t devtmpfs devtmpfs /newroot/dev || fail "dev"
mkdir -p /newroot/dev/pts /newroot/dev/shm
mount -t devpts -o newinstance,ptmxmode=0666 devpts /newroot/dev/pts
mount -t tmpfs -o mode=1777 tmpfs /newroot/dev/shm
mkdir -p /newroot/run/vcan-vm && mount --bind /job /newroot/run/vcan-vm || fail "job bind"
# vxcan pairs need "peer name", which busybox ip lacks: use the host's iproute2
hostip=''
for f in /usr/sbin/ip /sbin/ip /usr/bin/ip /bin/ip; do
  [ -x "/newroot$f" ] && [ ! -L "/newroot$f" ] && { hostip=$f; break; }
done
for p in $VCAN_VXCAN; do
  a=${p%%:*}; b=${p#*:}
  [ -n "$hostip" ] || fail "vxcan needs iproute2's ip on the host"
  chroot /newroot "$hostip" link add dev "$a" type vxcan peer name "$b" \
    || fail "ip link add $a type vxcan peer name $b"
  ip link set dev "$a" up && ip link set dev "$b" up || fail "vxcan up"
done
n=0
while [ "$n" -lt "${RW_COUNT:-0}" ]; do
  eval "d=\$RW_$n"
  mkdir -p "/newroot$d"
  mount -t 9p -o trans=virtio,version=9p2000.L,cache=mmap,msize=262144 "vcanrw$n" "/newroot$d" \
    || fail "cannot mount $d read-write"
  n=$((n+1))
done

# virtio-serial ports: p1 = stdout, p2 = stderr
out=/dev/vport0p1 err=/dev/vport0p2
for f in $out $err; do
  t=0; while [ ! -e "$f" ] && [ $t -lt 50 ]; do sleep 0.1; t=$((t+1)); done
  [ -e "$f" ] || fail "$f missing"
done

echo "VCAN-VM-READY" >/dev/console
chroot /newroot /bin/sh /run/vcan-vm/job.sh </dev/null >$out 2>$err
finish $?
EOF
}

# The bzImage decompresses itself (xz for Debian) before the kernel starts: under
# software emulation (TCG) that alone takes seconds. So the uncompressed ELF
# vmlinux is cut out of it once and booted directly through its PVH entry point.
extract_vmlinux() { # bzImage out kernel-config
  local magic off tool
  if [ ! -f "$3" ] || ! grep -q '^CONFIG_PVH=y' "$3"; then
    vsay "kernel built without CONFIG_PVH: booting the bzImage"
    return 1
  fi
  for magic in 'xz:\xfd7zXZ\x00' 'zstd:\x28\xb5\x2f\xfd' 'gzip:\x1f\x8b\x08'; do
    tool=${magic%%:*}
    command -v "$tool" >/dev/null || continue
    for off in $(LC_ALL=C grep -obUaP "${magic#*:}" "$1" 2>/dev/null | cut -d: -f1 | head -n 5); do
      case "$tool" in
        xz)   tail -c +"$((off + 1))" "$1" | xz -dcq >"$2" 2>/dev/null ;;
        zstd) tail -c +"$((off + 1))" "$1" | zstd -dcq >"$2" 2>/dev/null ;;
        gzip) tail -c +"$((off + 1))" "$1" | gzip -dcq >"$2" 2>/dev/null ;;
      esac
      if [ "$(head -c 4 "$2" 2>/dev/null | od -An -c | tr -d ' ')" = '177ELF' ]; then
        vsay "extracted uncompressed vmlinux ($tool) for direct PVH boot"
        return 0
      fi
    done
  done
  vsay "could not extract vmlinux: booting the bzImage"
  return 1
}

# Checking a module's appended signature costs ~50 ms per module under TCG.
# The kernel does not enforce signatures (unless booted with module.sig_enforce),
# so the signature is cut off: layout is  <module><sig><12-byte info><magic>,
# the info's last 4 bytes being the big-endian signature length.
strip_modsig() { # file
  local f=$1 size magic='~Module signature appended~' siglen
  size=$(wc -c <"$f")
  [ "$size" -gt 40 ] || return 0
  [ "$(tail -c 28 "$f" | head -c 27)" = "$magic" ] || return 0
  siglen=$(tail -c 32 "$f" | head -c 4 | od -An -tu1 | awk '{print (($1*256+$2)*256+$3)*256+$4}')
  [ "$siglen" -gt 0 ] && [ "$siglen" -lt "$size" ] || return 0
  truncate -s "$((size - 40 - siglen))" "$f"
}

build_artifacts() { # dest-dir
  local dest=$1 work pkg deb kroot kver
  work=$(mktemp -d "$CACHE/build.XXXXXX")
  BUILD_WORK=$work   # removed by cleanup() at exit

  if [ -n "${VCAN_VM_KERNEL_DEB:-}" ]; then
    deb=$VCAN_VM_KERNEL_DEB
    [ -f "$deb" ] || die "VCAN_VM_KERNEL_DEB=$deb does not exist"
  else
    command -v apt-get >/dev/null || die "apt-get not found; set VCAN_VM_KERNEL_DEB"
    pkg=$(resolve_kernel_pkg)
    mkdir -p "$CACHE/deb"
    deb=$(ls -t "$CACHE/deb/${pkg}"_*.deb 2>/dev/null | head -n1) || true
    if [ -z "$deb" ]; then
      say "downloading kernel package $pkg (apt-get download; it is not installed) ..."
      (cd "$work" && apt-get download "$pkg" >"$work/apt.log" 2>&1) || {
        cat "$work/apt.log" >&2; die "apt-get download $pkg failed"; }
      deb=$(ls "$work"/*.deb | head -n1)
      rm -f "$CACHE/deb/"*.deb   # keep only the newest one
      mv "$deb" "$CACHE/deb/" && deb="$CACHE/deb/${deb##*/}"
    fi
  fi
  vsay "unpacking $deb"
  mkdir "$work/pkg"
  dpkg-deb -x "$deb" "$work/pkg" || die "dpkg-deb -x $deb failed"

  kroot=$(find "$work/pkg" -maxdepth 4 -type d -path '*/lib/modules/*' -name '[0-9]*' | head -n1)
  [ -n "$kroot" ] || die "no lib/modules/<version> in $deb"
  kver=${kroot##*/}
  local vmlinuz
  vmlinuz=$(find "$work/pkg" -path "*/boot/vmlinuz-$kver" | head -n1)
  [ -n "$vmlinuz" ] || die "no boot/vmlinuz-$kver in $deb"

  # --- index modules: normalised name -> path (relative to $kroot)
  declare -A modpath=() loaded=()
  local f rel name
  while IFS= read -r f; do
    rel=${f#"$kroot"/}
    name=${f##*/}; name=${name%%.ko*}; name=${name//-/_}
    modpath[$name]=$rel
  done < <(find "$kroot" -name '*.ko' -o -name '*.ko.xz' -o -name '*.ko.zst' -o -name '*.ko.gz')
  declare -A builtin=()
  if [ -f "$kroot/modules.builtin" ]; then
    while IFS= read -r f; do
      name=${f##*/}; name=${name%%.ko*}; name=${name//-/_}; builtin[$name]=1
    done <"$kroot/modules.builtin"
  fi

  local root="$work/initramfs"
  mkdir -p "$root"/{bin,dev,proc,sys,job,lower,rw,newroot,lib/modules}
  : >"$root/modules.list"

  ko_plain() { # src dst: copy a module, decompressing it and dropping its signature
    case "$1" in
      *.ko.xz)  xz -dc "$1" >"$2" ;;
      *.ko.zst) zstd -qdc "$1" >"$2" ;;
      *.ko.gz)  gzip -dc "$1" >"$2" ;;
      *)        cp "$1" "$2" ;;
    esac
    strip_modsig "$2"
  }
  add_mod() { # name required(0/1)
    local n=${1//-/_} req=$2 dep deps out
    [ -n "${loaded[$n]:-}" ] && return 0
    if [ -n "${builtin[$n]:-}" ]; then loaded[$n]=1; return 0; fi
    if [ -z "${modpath[$n]:-}" ]; then
      [ "$req" = 1 ] && die "kernel $kver has no module $n (wrong flavour? the cloud flavour lacks CAN)"
      vsay "optional module $n not in kernel $kver, skipped"; loaded[$n]=1; return 0
    fi
    loaded[$n]=1
    out="$root/lib/modules/$n.ko"
    ko_plain "$kroot/${modpath[$n]}" "$out"
    deps=$(tr '\0' '\n' <"$out" | sed -n 's/^depends=//p' | head -n1)
    for dep in ${deps//,/ }; do add_mod "$dep" 1; done
    echo "$n.ko" >>"$root/modules.list"
  }
  local m
  for m in $WANT_MODULES; do
    case "$m" in '!'*) add_mod "${m#!}" 1 ;; *) add_mod "$m" 0 ;; esac
  done

  cp "$BUSYBOX" "$root/bin/busybox"
  local a
  for a in $("$BUSYBOX" --list); do
    [ "$a" = busybox ] || ln -sf busybox "$root/bin/$a"
  done
  init_script >"$root/init"
  chmod 755 "$root/init"

  # uncompressed: unpacking gzip in the guest is slower than loading a few MiB more
  (cd "$root" && find . | "$BUSYBOX" cpio -o -H newc 2>/dev/null) >"$work/initrd.img"
  cp "$vmlinuz" "$work/vmlinuz"
  extract_vmlinux "$vmlinuz" "$work/vmlinux" "${vmlinuz%/*}/config-$kver" || rm -f "$work/vmlinux"
  printf 'rev=%s\nkernel=%s\ndeb=%s\n' "$RECIPE_REV" "$kver" "${deb##*/}" >"$work/stamp"

  mkdir -p "$dest.new"
  mv "$work/vmlinuz" "$work/initrd.img" "$work/stamp" "$dest.new/"
  [ ! -f "$work/vmlinux" ] || mv "$work/vmlinux" "$dest.new/"
  rm -rf "$dest"
  mv "$dest.new" "$dest"
  rm -rf "$work"; BUILD_WORK=''
  say "built kernel $(sed -n 's/^kernel=//p' "$dest/stamp") + initramfs in $dest ($(du -sh --apparent-size "$dest" | cut -f1))"
}

prepare() {
  mkdir -p "$CACHE"
  ART="$CACHE/artifacts"
  if [ "${VCAN_VM_REBUILD:-0}" != 1 ] && [ -f "$ART/stamp" ] && grep -qx "rev=$RECIPE_REV" "$ART/stamp"; then
    return 0
  fi
  ensure_host_tools
  exec 8>"$CACHE/.lock"
  flock 8
  # someone else may have built it while we waited for the lock
  if [ "${VCAN_VM_REBUILD:-0}" = 1 ] || [ ! -f "$ART/stamp" ] || ! grep -qx "rev=$RECIPE_REV" "$ART/stamp"; then
    build_artifacts "$ART"
  fi
  flock -u 8
  exec 8>&-
}

# ------------------------------------------------------------------- run
shq() { # quote for POSIX sh
  local s=${1//\'/\'\\\'\'}
  printf "'%s'" "$s"
}
qemu_path() { printf '%s' "${1//,/,,}"; }  # escape commas for QEMU option values

prepare
if [ "$mode" = prepare ]; then
  say "ready: $(tr '\n' ' ' <"$ART/stamp")"
  exit 0
fi
command -v qemu-system-x86_64 >/dev/null || ensure_host_tools

if ! command -v -- "$1" >/dev/null 2>&1; then
  say "$1: command not found"; exit 127
fi

JOB=$(mktemp -d "${TMPDIR:-/tmp}/vcan-vm-job.XXXXXX")

# --- per-run config for the guest's init (busybox sh)
rwdirs=()
if [ -n "${VCAN_VM_RW_DIRS:-}" ]; then
  IFS=: read -r -a _rw <<<"$VCAN_VM_RW_DIRS"
  for d in "${_rw[@]}"; do
    [ -n "$d" ] || continue
    rd=$(cd "$d" 2>/dev/null && pwd -P) || die "VCAN_VM_RW_DIRS: no such folder: $d"
    rwdirs+=("$rd")
  done
fi
{
  printf 'VCAN_IFACES=%s\n' "$(shq "${VCAN_VM_IFACES-vcan0}")"
  printf 'VCAN_VXCAN=%s\n' "$(shq "${VCAN_VM_VXCAN:-}")"
  for i in "${!rwdirs[@]}"; do printf 'RW_%d=%s\n' "$i" "$(shq "${rwdirs[$i]}")"; done
  printf 'RW_COUNT=%d\n' "${#rwdirs[@]}"
} >"$JOB/config.sh"

# --- the command, with the caller's environment and working directory
{
  echo '# generated by vcan-vm.sh'
  while IFS= read -r v; do
    case "$v" in PWD|OLDPWD|SHLVL|_|BASH_*|VCAN_VM_*) continue ;; esac
    [[ "$v" =~ ^[A-Za-z_][A-Za-z0-9_]*$ ]] || continue
    printf 'export %s=%s\n' "$v" "$(shq "${!v}")"
  done < <(compgen -e)
  printf 'export PWD=%s\n' "$(shq "$PWD")"
  printf 'cd %s || exit 125\n' "$(shq "$PWD")"
  printf 'exec'
  for a in "$@"; do printf ' %s' "$(shq "$a")"; done
  printf '\n'
} >"$JOB/job.sh"

# --- accelerator
# /dev/kvm alone is not enough: some sandboxes expose a para-virtual KVM (e.g.
# PVM, module kvm_pvm) that only runs specially built guest kernels; a stock
# kernel hangs there before printing anything. So "auto" wants the CPU's
# vmx/svm flag as well, and falls back to TCG if a KVM boot does not come up.
kvm_usable() {
  [ -c /dev/kvm ] && [ -r /dev/kvm ] && [ -w /dev/kvm ] || return 1
  [ ! -d /sys/module/kvm_pvm ] || return 1
  grep -qwE 'vmx|svm' /proc/cpuinfo 2>/dev/null
}
accel=${VCAN_VM_ACCEL:-auto}
auto_accel=0
if [ "$accel" = auto ]; then
  auto_accel=1
  if kvm_usable; then accel=kvm; else accel=tcg; fi
fi
case "$accel" in kvm|tcg) ;; *) die "VCAN_VM_ACCEL must be auto, kvm or tcg" ;; esac
ncpu=$(nproc 2>/dev/null || echo 1)
if [ -n "${VCAN_VM_CPUS:-}" ]; then cpus=$VCAN_VM_CPUS
elif [ "$accel" = kvm ]; then cpus=$(( ncpu > 4 ? 4 : ncpu ))
else cpus=1   # under TCG a 2nd vCPU costs ~1.5 s of boot on a 2-core host
fi
mem=${VCAN_VM_MEM:-1024}
timeout_s=${VCAN_VM_TIMEOUT:-1800}

kernel=$ART/vmlinuz
[ -f "$ART/vmlinux" ] && kernel=$ART/vmlinux
bios=()
for f in /usr/share/qemu/qboot.rom /usr/share/qemu/bios-microvm.bin; do
  # qboot: a minimal firmware that starts the kernel sooner than SeaBIOS
  if [ -f "$f" ]; then bios=(-bios "$f"); break; fi
done

mkfifo "$JOB/out.in" "$JOB/out.out" "$JOB/err.in" "$JOB/err.out" "$JOB/tick"
exec 9<>"$JOB/tick"   # never written: reading it with a timeout is a builtin sleep
# Hold a read-write handle on the output FIFOs so that the readers below never
# block in open() even if QEMU fails to start; closed once QEMU has exited.
exec 5<>"$JOB/out.out" 6<>"$JOB/err.out"
cat "$JOB/out.out" 5>&- 6>&- 9>&- &
opid=$!
cat "$JOB/err.out" >&2 5>&- 6>&- 9>&- &
epid=$!

# shellcheck disable=SC2054  # commas inside QEMU option values are intended
run_vm() { # accel -> sets qrc, booted
  local acc=$1 boot_timeout deadline
  local -a qargs
  if [ "$acc" = kvm ]; then
    qargs=(-accel kvm -cpu host); boot_timeout=${VCAN_VM_BOOT_TIMEOUT:-30}
  else
    qargs=(-accel tcg,thread=multi -cpu max); boot_timeout=${VCAN_VM_BOOT_TIMEOUT:-300}
    [ -n "${VCAN_VM_CPUS:-}" ] || cpus=1
  fi
  qargs+=(
    -nodefaults -no-user-config -nographic -no-reboot
    -machine pc -smp "$cpus" -m "$mem" -nic none "${bios[@]}"
    -kernel "$kernel" -initrd "$ART/initrd.img"
    -append "console=ttyS0 quiet panic=-1 mitigations=off cryptomgr.notests acpi=noirq rdinit=/init ${VCAN_VM_APPEND:-}"
    -chardev "file,id=con,path=$(qemu_path "$JOB/console.log")" -serial chardev:con
    -device virtio-serial-pci
    -chardev "pipe,id=out,path=$(qemu_path "$JOB/out")" -device virtserialport,chardev=out,name=stdout,nr=1
    -chardev "pipe,id=err,path=$(qemu_path "$JOB/err")" -device virtserialport,chardev=err,name=stderr,nr=2
    -fsdev local,id=hostroot,path=/,security_model=none,readonly=on,multidevs=remap
    -device virtio-9p-pci,fsdev=hostroot,mount_tag=hostroot
    -fsdev "local,id=job,path=$(qemu_path "$JOB"),security_model=none"
    -device virtio-9p-pci,fsdev=job,mount_tag=vcanjob
  )
  # extra QEMU options (word-split), e.g. VCAN_VM_QEMU_ARGS="-cpu Nehalem"
  # shellcheck disable=SC2206
  [ -z "${VCAN_VM_QEMU_ARGS:-}" ] || qargs+=(${VCAN_VM_QEMU_ARGS})
  local i
  for i in "${!rwdirs[@]}"; do
    qargs+=(-fsdev "local,id=rw$i,path=$(qemu_path "${rwdirs[$i]}"),security_model=none,multidevs=remap"
            -device "virtio-9p-pci,fsdev=rw$i,mount_tag=vcanrw$i")
  done
  rm -f "$JOB/exit-code"
  : >"$JOB/console.log"
  vsay "booting guest ($acc, $cpus vCPU, $mem MiB, ${kernel##*/})"
  if [ "$timeout_s" != 0 ]; then
    timeout -k 5 "$timeout_s" qemu-system-x86_64 "${qargs[@]}" </dev/null >"$JOB/qemu.log" 2>&1 5>&- 6>&- 9>&- &
  else
    qemu-system-x86_64 "${qargs[@]}" </dev/null >"$JOB/qemu.log" 2>&1 5>&- 6>&- 9>&- &
  fi
  qpid=$!
  # Watch the VM: boot watchdog (the guest's init prints VCAN-VM-READY before it
  # starts COMMAND), and stop it if a reader of its output died (e.g. "| head").
  booted=0 reader_gone=0
  deadline=$((SECONDS + boot_timeout))
  while kill -0 "$qpid" 2>/dev/null; do
    if [ "$booted" = 0 ]; then
      if grep -q 'VCAN-VM-READY' "$JOB/console.log" 2>/dev/null; then
        booted=1
      elif [ "$SECONDS" -ge "$deadline" ]; then
        say "guest did not come up within ${boot_timeout}s ($acc)"
        kill "$qpid" 2>/dev/null || true
        break
      fi
    fi
    if ! kill -0 "$opid" 2>/dev/null || ! kill -0 "$epid" 2>/dev/null; then
      vsay "output reader went away; stopping the VM"
      reader_gone=1
      kill "$qpid" 2>/dev/null || true
      break
    fi
    read -rt 0.1 <&9 || true   # a 0.1 s sleep without forking
  done
  set +e; wait "$qpid"; qrc=$?; set -e
  qpid=''
  grep -q 'VCAN-VM-READY' "$JOB/console.log" 2>/dev/null && booted=1
  return 0
}

t0=$(date +%s.%N)
run_vm "$accel"
if [ "$booted" = 0 ] && [ "$accel" = kvm ] && [ "$auto_accel" = 1 ]; then
  say "KVM boot failed, retrying with TCG software emulation"
  accel=tcg
  run_vm tcg
fi
exec 5>&- 6>&-
wait "$opid" 2>/dev/null || true; opid=''
wait "$epid" 2>/dev/null || true; epid=''
t1=$(date +%s.%N)
vsay "VM ran for $(awk -v a="$t0" -v b="$t1" 'BEGIN{printf "%.2f", b-a}') s ($accel, qemu exit $qrc)"

show_console() {
  say "---- guest console ----"
  tr -d '\r' <"$JOB/console.log" >&2 2>/dev/null || true
  say "---- qemu output ----"
  cat "$JOB/qemu.log" >&2 2>/dev/null || true
  say "----"
}
[ "${VCAN_VM_VERBOSE:-0}" = 1 ] && show_console

if [ "$reader_gone" = 1 ]; then
  exit 141   # like a writer killed by SIGPIPE
fi
if [ "$timeout_s" != 0 ] && { [ "$qrc" = 124 ] || [ "$qrc" = 137 ]; }; then
  say "timeout: VM killed after ${timeout_s}s (VCAN_VM_TIMEOUT)"
  [ "${VCAN_VM_VERBOSE:-0}" = 1 ] || show_console
  exit 124
fi
rc=''
[ -f "$JOB/exit-code" ] && rc=$(tr -dc '0-9' <"$JOB/exit-code")
if [ -z "$rc" ] && [ -f "$JOB/console.log" ]; then
  rc=$(tr -d '\r' <"$JOB/console.log" | sed -n 's/^VCAN-VM-EXIT-CODE=\([0-9]*\)$/\1/p' | tail -n1)
fi
if [ -z "$rc" ]; then
  say "the VM did not report an exit code (qemu exit status $qrc)"
  [ "${VCAN_VM_VERBOSE:-0}" = 1 ] || show_console
  exit 125
fi
if [ "$rc" = 125 ] && grep -q 'vcan-vm-init: FATAL' "$JOB/console.log" 2>/dev/null; then
  [ "${VCAN_VM_VERBOSE:-0}" = 1 ] || show_console
fi
exit "$rc"
