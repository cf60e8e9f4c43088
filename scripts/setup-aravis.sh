#!/usr/bin/env bash
# Installs (once) Debian's Aravis command-line tools and Python bindings, the
# third-party GigE Vision client the tests in tests/serve/gige.rs drive: arv-tool-0.8,
# arv-camera-test-0.8 and `gi.repository.Aravis` for /usr/bin/python3.
# Idempotent: does nothing when all three are there. Needs root (apt-get).
set -euo pipefail
have() {
  command -v arv-tool-0.8 >/dev/null 2>&1 && command -v arv-camera-test-0.8 >/dev/null 2>&1 &&
    /usr/bin/python3 -c 'import gi; gi.require_version("Aravis", "0.8"); from gi.repository import Aravis' 2>/dev/null
}
if have; then exit 0; fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
  echo "setup-aravis: Aravis is missing and apt-get cannot run here (need root on Debian)" >&2
  exit 1
fi
pkgs=(aravis-tools-cli aravis-tools gir1.2-aravis-0.8 python3-gi)
echo "setup-aravis: installing ${pkgs[*]} (apt-get)" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get install -y --no-install-recommends "${pkgs[@]}" >&2 ||
  { apt-get update >&2 && apt-get install -y --no-install-recommends "${pkgs[@]}" >&2; }
have || { echo "setup-aravis: installed, but arv-tool-0.8 / arv-camera-test-0.8 / Aravis GI still missing" >&2; exit 1; }
