#!/usr/bin/env bash
# Cargo's workspace rustc wrapper (.cargo/config.toml): runs `rustc ARGS...` unchanged,
# except a workspace library's unit-test harness (--test on a src/lib.rs), which gets
# -C opt-level=${HILCAM_UNIT_TEST_OPT_LEVEL:-0} instead of its profile's level.
rustc=$1
shift
unit_test=false lib=false
for a in "$@"; do
  case $a in
    --test) unit_test=true ;;
    */src/lib.rs | src/lib.rs) lib=true ;;
  esac
done
if $unit_test && $lib; then
  args=()
  for a in "$@"; do
    case $a in
      opt-level=*) args+=("opt-level=${HILCAM_UNIT_TEST_OPT_LEVEL:-0}") ;;
      *) args+=("$a") ;;
    esac
  done
  exec "$rustc" "${args[@]}"
fi
exec "$rustc" "$@"
