#!/usr/bin/env bash
# Creates (once) a venv with pyserial and python-can for the interoperability
# tests and examples, kubernetes-validate for scripts/k8s/validate.sh and genicam (the
# GenICam reference GenApi, which loads the GigE camera's XML in tests/serve/gige_xml.rs); prints the
# interpreter's path on stdout.
# Venv: $HILCAM_VENV (default ~/.cache/hilcam/venv). Installs python3-venv via
# apt-get when the venv module is missing and we are root.
set -euo pipefail
venv=${HILCAM_VENV:-$HOME/.cache/hilcam/venv}
py=$venv/bin/python
pkgs=(pyserial python-can kubernetes-validate genicam)
imports="import serial, can, kubernetes_validate, genicam.genapi"
if [ -x "$py" ] && "$py" -c "$imports" 2>/dev/null; then
  echo "$py"; exit 0
fi
if [ -x "$py" ]; then
  echo "setup-python: adding ${pkgs[*]} to $venv" >&2
  "$py" -m pip install --quiet "${pkgs[@]}" >&2
  "$py" -c "$imports" >&2
  echo "$py"; exit 0
fi
source "$(dirname "$0")/python-base.sh"
base=$(python_base setup-python)
echo "setup-python: creating $venv with ${pkgs[*]}" >&2
"$base" -m venv "$venv" >&2
"$py" -m pip install --quiet "${pkgs[@]}" >&2
"$py" -c "$imports" >&2
echo "$py"
