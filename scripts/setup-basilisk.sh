#!/usr/bin/env bash
# Creates (once) a venv with Basilisk (bsk and bsk-opnav 2.12.1 from the package index),
# pyserial and numpy for the closed-loop examples (examples/bsk_loop.py,
# examples/bsk_serial_loop.py; docs/python.md); then installs the hilcam wheel given as
# the argument into it (replacing the one there) and prints the venv's interpreter.
#
#   scripts/setup-basilisk.sh target/wheels/hilcam-*.whl
#
# Venv: $HILCAM_BSK_VENV (default ~/.cache/hilcam/py-bsk; kept: Basilisk is ~90 MB of
# wheels). The wheel is built by scripts/build-python.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] && [ -f "$1" ] || { echo "usage: $0 WHEEL (from scripts/build-python.sh)" >&2; exit 2; }
venv=${HILCAM_BSK_VENV:-$HOME/.cache/hilcam/py-bsk}
py=$venv/bin/python
pkgs=(bsk==2.12.1 bsk-opnav==2.12.1 pyserial numpy)
imports="import Basilisk, serial, numpy; from Basilisk.simulation import spacecraft"
if ! { [ -x "$py" ] && "$py" -c "$imports" 2>/dev/null; }; then
  if [ ! -x "$py" ]; then
    source scripts/python-base.sh
    base=$(python_base setup-basilisk)
    echo "setup-basilisk: creating $venv with ${pkgs[*]}" >&2
    "$base" -m venv "$venv" >&2
  fi
  start=$SECONDS
  "$py" -m pip install --quiet "${pkgs[@]}" >&2
  "$py" -c "$imports" >&2
  echo "setup-basilisk: installed in $((SECONDS - start)) s" >&2
fi
"$py" -m pip install --quiet --force-reinstall --no-deps "$1" >&2
"$py" -c "import hilcam" >&2
echo "$py"
