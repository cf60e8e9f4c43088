#!/usr/bin/env bash
# The whole test suite (README's second command). Installs what it needs itself.
set -euo pipefail
cd "$(dirname "$0")/.."

# --quick: the inner loop — the setup (cached after the first run), `cargo test` and the
# docs' examples; not the Python module, the vcan VM, fuzzing, the bench build or the
# Slurm cluster (docs/testing.md).
quick=false
case "${1:-}" in
  --quick) quick=true ;;
  "") ;;
  *) echo "usage: scripts/test.sh [--quick]" >&2; exit 2 ;;
esac

# Wall time of each step, printed at the end (also when a step fails).
laps=()
lap_start=$SECONDS
lap() {
  laps+=("$(printf '%-44s %5ds' "$1" $((SECONDS - lap_start)))")
  lap_start=$SECONDS
}
print_laps() {
  local rc=$?
  bg_stop
  echo "test.sh: wall time by step"
  printf '  %s\n' "${laps[@]}"
  printf '  %-44s %5ds (exit %d)\n' "total" "$SECONDS" "$rc"
}
bg_pids=()
bg_stop() { :; }
trap print_laps EXIT

# --- pose input (issue 4) -------------------------------------------------
# Python with pyserial + python-can for the interoperability tests (a venv,
# created once; see scripts/setup-python.sh).
HILCAM_PYTHON=$(scripts/setup-python.sh)
export HILCAM_PYTHON
# SocketCAN tests (tests/can_socketcan.rs, #[ignore]d in a plain cargo test)
# need vcan0 and vcan1. Use the host's if it has them or can create them;
# otherwise run that one test binary inside the vcan VM (scripts/vcan-vm.sh).
vcan_host() {
  local i
  for i in vcan0 vcan1; do
    [ -e "/sys/class/net/$i" ] && continue
    ip link add dev "$i" type vcan 2>/dev/null && ip link set up "$i" 2>/dev/null || return 1
  done
}
if vcan_host; then
  vcan_mode=host
  echo "test.sh: SocketCAN tests run on the host's vcan0/vcan1"
else
  vcan_mode=vm
  echo "test.sh: this kernel cannot create vcan0; SocketCAN tests run in the vcan VM (scripts/vcan-vm.sh)"
fi
# ---------------------------------------------------------------------------

# GigE Vision (tests/serve/gige.rs): a real third-party client, Debian's Aravis tools and
# its Python bindings.
scripts/setup-aravis.sh
# The live page (tests/serve/live.rs): Debian's chromium driven by Playwright for Python.
HILCAM_CHROMIUM=$(scripts/setup-chromium.sh)
export HILCAM_CHROMIUM
lap "setup (python venv, vcan check, Aravis, chromium)"

# The docs' own examples (tests/cli/docs.rs) run as a step of their own below, so that
# their count and time show; the rest of the suite skips them here.
cargo test --all-targets -- --skip docs::
lap "cargo test --all-targets (build + run)"

# Docs that run: every code block of README.md and docs/*.md against the program (the cli
# binary is built above; docs/testing.md, "Docs that run").
cargo test --test cli docs:: -- --nocapture
lap "docs' examples (tests/cli/docs.rs)"
if $quick; then
  echo "test.sh: --quick: skipped the Python module, SocketCAN, fuzzing, the bench build and Slurm"
  exit 0
fi

# The tail runs in two lanes. Background: fuzzing (its own target dir, fuzz/target) from
# here, and the bench build once the wheel is built (both need target/'s lock). Foreground:
# SocketCAN, the Python module, Slurm. Each background step writes a log, printed when
# it ends; a failed one fails the run. The foreground steps use a copy of the lab binary
# `cargo test` built ($lab_bin), since the bench build replaces target/debug/hilcam.
lab_keep=$(mktemp -d)
cp -p target/debug/hilcam "$lab_keep/hilcam"
lab_bin=$lab_keep/hilcam
bg_logs=$(mktemp -d)
bg_pids=() bg_names=()
bg_start() {   # bg_start NAME COMMAND...: COMMAND in the background, its own process group
  local name=$1
  shift
  local n=${#bg_pids[@]}
  set -m
  # (The inner subshell keeps set -e in force inside a function given as COMMAND.)
  ( start=$SECONDS; set +e; ( set -e; "$@" ); rc=$?
    printf '%s\n' "$((SECONDS - start))" >"$bg_logs/$n.secs"; exit "$rc" ) \
    </dev/null >"$bg_logs/$n.log" 2>&1 &
  set +m
  bg_pids+=($!)
  bg_names+=("$name")
  echo "test.sh: started in the background: $name"
}
bg_stop() {   # on an early exit: stop the background steps still running
  local p
  for p in "${bg_pids[@]}"; do kill -- "-$p" 2>/dev/null || true; done
}
bg_wait() {   # waits for every background step, prints its log and time; fails if one did
  local i rc failed=0
  for i in "${!bg_pids[@]}"; do
    rc=0
    wait "${bg_pids[$i]}" || rc=$?
    echo "test.sh: --- ${bg_names[$i]} (background, exit $rc) ---"
    cat "$bg_logs/$i.log"
    laps+=("$(printf '%-44s %5ds' "${bg_names[$i]} [bg]" "$(cat "$bg_logs/$i.secs" 2>/dev/null || echo 0)")")
    [ "$rc" = 0 ] || failed=1
  done
  bg_pids=()
  return "$failed"
}

# Fuzz each decoder briefly (cargo-fuzz needs nightly features: RUSTC_BOOTSTRAP
# lets the stable toolchain use them). HILCAM_FUZZ_SECONDS=0 skips, with a note.
bg_start "fuzz targets (build + ${HILCAM_FUZZ_SECONDS:-10} s each)" scripts/fuzz.sh "${HILCAM_FUZZ_SECONDS:-10}"

# --- pose input (issue 4), continued --------------------------------------
if [ "$vcan_mode" = vm ]; then
  scripts/vcan-vm.sh --prepare
  # One VM boot for the whole binary; --test keeps doc-tests out of the VM.
  VCAN_VM_IFACES="vcan0 vcan1" \
    CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER="$PWD/scripts/vcan-vm.sh" \
    cargo test --test can_socketcan -- --include-ignored
else
  cargo test --test can_socketcan -- --include-ignored
fi
lap "SocketCAN tests ($vcan_mode)"
# ---------------------------------------------------------------------------

# The bench build: the binary without the lab (--no-default-features) builds, and its
# command line has no lab subcommand. Without the lab hilcam-core's features differ, so it
# is compiled again: unoptimised here, the binary too (the checks below render nothing),
# which takes a third of the time; dependencies keep their artifacts and are reused.
# `cargo test` built target/debug/hilcam (the lab build, its dependencies' features
# unified with the tests'); it is kept aside ($lab_bin) and put back after, rather than
# rebuilt: a plain `cargo build` unifies features without the dev-dependencies and
# recompiled half the tree (~150 s).
bench_build() {
  CARGO_PROFILE_DEV_OPT_LEVEL=0 cargo build --quiet --no-default-features --bin hilcam \
    --config 'profile.dev.package.hilcam.opt-level=0'
  local dir
  dir=$(mktemp -d)
  cp -p target/debug/hilcam "$dir/hilcam"
  # target/debug/hilcam is the optimised lab build again.
  cp -p --remove-destination "$lab_bin" target/debug/hilcam  # not through cargo's hard link
  local bench=$dir/hilcam
  if "$bench" bench --help >/dev/null 2>&1; then
    echo "test.sh: the --no-default-features binary still has the lab's 'bench' subcommand" >&2
    return 1
  fi
  "$bench" serve --help >/dev/null
  # Its BVH is bvh8 only: a scene asking for a lab layout is refused by file, line, field
  # and the feature to build with (not an unknown name, not a silent fallback).
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' >"$dir/t.obj"
  printf '[[mesh]]\nobj = "t.obj"\nmaterial = "paint"\n[materials.paint]\nmodel = "lambert"\nrho = 0.5\n[camera]\nwidth = 8\nheight = 8\npitch_um = 10.0\nfocal_mm = 20.0\n[render]\nbvh = "bvh4"\n' \
    >"$dir/s.toml"
  local err
  if err=$("$bench" render "$dir/s.toml" --out "$dir/out.png" 2>&1); then
    echo "test.sh: the --no-default-features binary rendered a scene asking for bvh4" >&2
    return 1
  fi
  local expected="$dir/s.toml:13: render.bvh: this build has only bvh8; bvh4 is a lab layout, build with the \`lab\` feature"
  if [[ "$err" != *"$expected"* ]]; then
    printf 'test.sh: bench build: bvh4 refusal reads\n%s\nnot\n%s\n' "$err" "$expected" >&2
    return 1
  fi
  rm -r "$dir"
  echo "test.sh: bench build (--no-default-features) OK: serve present, lab subcommands and BVH layouts absent"
}

# The Python module (issue 38): the wheel built by the project's own script (maturin, the
# dev profile, sharing target/ with the build above), pip-installed into a fresh venv; its
# tests compare it with the CLI binary built above (docs/python.md).
# The Basilisk closed-loop examples run in their own cached venv (bsk, bsk-opnav 2.12.1)
# with the same wheel installed (python/tests/test_basilisk.py).
HILCAM_PY=$(scripts/build-python.sh)
# The wheel is built: target/ is free for the bench build.
bg_start "bench build (--no-default-features) + checks" bench_build
HILCAM_BSK_PY=$(scripts/setup-basilisk.sh target/wheels/hilcam-*.whl)
HILCAM_BSK_PY="$HILCAM_BSK_PY" HILCAM_BIN="$lab_bin" \
  "$HILCAM_PY" -m pytest python/tests -q -p no:cacheprovider
lap "Python module (wheel build + pytest, Basilisk loops)"

# --- clusters (issue 25) -----------------------------------------------------
# A real single-node Slurm cluster (installs slurm-wlm + munge, starts and stops its own
# daemons, fails if one is left), an array with a scancel'd and resubmitted task, merged
# and compared byte for byte with a local replay; the Kubernetes manifest against the
# schema, offline (docs/cluster.md).
HILCAM_BIN=$lab_bin scripts/slurm/test-cluster.sh
scripts/k8s/validate.sh
lap "Slurm cluster + Kubernetes manifest"

bg_wait
lap "waiting for the background steps"
rm -r "$lab_keep" "$bg_logs"
