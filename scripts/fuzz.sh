#!/usr/bin/env bash
# Runs every cargo-fuzz target in fuzz/ for N seconds (default 10).
# Installs cargo-fuzz once into ~/.cache/hilcam/cargo-fuzz. The stable
# toolchain is used with RUSTC_BOOTSTRAP=1 (cargo-fuzz passes -Z flags).
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-10}
if [ "$secs" = 0 ]; then
  echo "fuzz.sh: SKIPPED fuzzing (HILCAM_FUZZ_SECONDS=0); the 10^6-byte randomized test still ran"
  exit 0
fi
root=${HILCAM_CARGO_FUZZ_ROOT:-$HOME/.cache/hilcam/cargo-fuzz}
if [ ! -x "$root/bin/cargo-fuzz" ]; then
  echo "fuzz.sh: installing cargo-fuzz into $root"
  cargo install --locked --root "$root" cargo-fuzz
fi
export PATH="$root/bin:$PATH" RUSTC_BOOTSTRAP=1
cd fuzz
mkdir -p corpus target
# One build of every target (their links run in parallel), then the targets two at a
# time: a libFuzzer run uses one core, and this machine has two (HILCAM_FUZZ_JOBS).
cargo fuzz build -O
jobs=${HILCAM_FUZZ_JOBS:-2}
run_target() {
  local t=$1
  mkdir -p "corpus/$t"
  cargo fuzz run -O "$t" "corpus/$t" -- -max_total_time="$secs" -print_final_stats=1 \
    >"target/fuzz-$t.log" 2>&1
}
report() {   # prints a finished target's stats, or its log's tail when it failed
  local t=$1 rc=$2
  if [ "$rc" != 0 ]; then
    tail -n 60 "target/fuzz-$t.log"
    echo "fuzz.sh: $t FAILED (crash input under fuzz/artifacts/$t/)"
    return 1
  fi
  grep -E '^(Done [0-9]+ runs|stat::number_of_executed_units)' "target/fuzz-$t.log" | sed "s/^/fuzz.sh: $t: /" || true
}
targets=($(cargo fuzz list))
failed=0
for ((i = 0; i < ${#targets[@]}; i += jobs)); do
  batch=("${targets[@]:i:jobs}")
  pids=()
  for t in "${batch[@]}"; do
    echo "fuzz.sh: $t for ${secs}s"
    run_target "$t" &
    pids+=($!)
  done
  for k in "${!batch[@]}"; do
    rc=0
    wait "${pids[$k]}" || rc=$?
    report "${batch[$k]}" "$rc" || failed=1
  done
  [ "$failed" = 0 ] || exit 1
done
