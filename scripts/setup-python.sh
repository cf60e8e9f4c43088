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
# Prefer a real interpreter over a pyenv shim: shims fork bash scripts, which is
# slow inside the vcan VM.
base=$(command -v pyenv >/dev/null 2>&1 && pyenv which python3 2>/dev/null || command -v python3)
if ! "$base" -m venv --help >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "setup-python: installing python3-venv (apt-get)" >&2
    apt-get install -y --no-install-recommends python3-venv >&2 || { apt-get update >&2 && apt-get install -y --no-install-recommends python3-venv >&2; }
    base=/usr/bin/python3
  else
    echo "setup-python: python3 has no venv module and cannot install python3-venv" >&2; exit 1
  fi
fi
echo "setup-python: creating $venv with ${pkgs[*]}" >&2
"$base" -m venv "$venv" >&2
"$py" -m pip install --quiet "${pkgs[@]}" >&2
"$py" -c "$imports" >&2
echo "$py"
