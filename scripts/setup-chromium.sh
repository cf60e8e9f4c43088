#!/usr/bin/env bash
# Installs (once) what tests/live/browser.py drives: Debian's headless-capable
# `chromium` (apt) and Playwright for Python in the project venv (pip; its own browser
# downloads are never used: the test passes chromium's path as executable_path).
# Prints the chromium path on stdout. Idempotent and quiet when all is there; needs
# root (apt-get) the first time.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
py=$("$here/setup-python.sh")
chromium=$(command -v chromium || true)
if [ -z "$chromium" ]; then
  if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
    echo "setup-chromium: chromium is missing and apt-get cannot run here (need root on Debian)" >&2
    exit 1
  fi
  echo "setup-chromium: installing chromium (apt-get)" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y --no-install-recommends chromium >&2 ||
    { apt-get update >&2 && apt-get install -y --no-install-recommends chromium >&2; }
  chromium=$(command -v chromium)
fi
if ! "$py" -c 'import playwright.sync_api' 2>/dev/null; then
  echo "setup-chromium: installing playwright into $(dirname "$(dirname "$py")") (pip)" >&2
  "$py" -m pip install --quiet playwright >&2
  "$py" -c 'import playwright.sync_api' >&2
fi
echo "$chromium"
