# Sourced by scripts/setup-python.sh and scripts/build-python.sh: `python_base NAME` prints
# a python3 that has the venv module (NAME prefixes its messages). A real interpreter is
# preferred over a pyenv shim (shims fork bash scripts, which is slow inside the vcan VM);
# python3-venv is installed with apt-get when the module is missing and we are root.
python_base() {
  local base
  base=$(command -v pyenv >/dev/null 2>&1 && pyenv which python3 2>/dev/null || command -v python3)
  if ! "$base" -m venv --help >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
      echo "$1: installing python3-venv (apt-get)" >&2
      apt-get install -y --no-install-recommends python3-venv >&2 || { apt-get update >&2 && apt-get install -y --no-install-recommends python3-venv >&2; }
      base=/usr/bin/python3
    else
      echo "$1: python3 has no venv module and cannot install python3-venv" >&2
      return 1
    fi
  fi
  echo "$base"
}
