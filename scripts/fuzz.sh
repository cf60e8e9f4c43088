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
mkdir -p corpus
for t in $(cargo fuzz list); do
  mkdir -p "corpus/$t"
  echo "fuzz.sh: $t for ${secs}s"
  log="target/fuzz-$t.log"
  mkdir -p target
  if ! cargo fuzz run -O "$t" "corpus/$t" -- -max_total_time="$secs" -print_final_stats=1 >"$log" 2>&1; then
    tail -n 60 "$log"
    echo "fuzz.sh: $t FAILED (crash input under fuzz/artifacts/$t/)"
    exit 1
  fi
  grep -E '^(Done [0-9]+ runs|stat::number_of_executed_units)' "$log" | sed "s/^/fuzz.sh: $t: /" || true
done
