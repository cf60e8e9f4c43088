#!/usr/bin/env bash
# Builds the Python module (crates/hilcam-py, maturin + pyo3, an abi3 wheel for CPython
# >= 3.9), installs it into a fresh venv and prints that venv's interpreter on stdout.
#
#   scripts/build-python.sh            # dev profile (opt-level 2, as the tests' binaries)
#   scripts/build-python.sh --release  # the release profile (benchmarks)
#
# Venvs: $HILCAM_PY_BUILD_VENV (default ~/.cache/hilcam/py-build: maturin, numpy; kept)
# and $HILCAM_PY_VENV (default ~/.cache/hilcam/py-hilcam: numpy, pytest and the wheel;
# made anew each run, so the wheel is tested as `pip install` leaves it). The wheel goes
# to target/wheels/; the build shares the workspace's target/ (hilcam-core is not built
# from scratch when it is already there).
set -euo pipefail
cd "$(dirname "$0")/.."
profile=dev
case "${1:-}" in
  --release) profile=release ;;
  "") ;;
  *) echo "usage: $0 [--release]" >&2; exit 2 ;;
esac
build_venv=${HILCAM_PY_BUILD_VENV:-$HOME/.cache/hilcam/py-build}
test_venv=${HILCAM_PY_VENV:-$HOME/.cache/hilcam/py-hilcam}
source "$(dirname "$0")/python-base.sh"
base=$(python_base build-python)
if ! "$build_venv/bin/python" -c "import maturin, numpy" 2>/dev/null; then
  echo "build-python: creating $build_venv with maturin, numpy" >&2
  "$base" -m venv "$build_venv" >&2
  "$build_venv/bin/python" -m pip install --quiet "maturin>=1.5,<2" numpy >&2
fi
start=$SECONDS
rm -f target/wheels/hilcam-*.whl
# --target-dir: the workspace's, so that hilcam-core's build is shared with cargo's.
"$build_venv/bin/maturin" build --quiet --profile "$profile" \
  --manifest-path crates/hilcam-py/Cargo.toml --target-dir target --out target/wheels \
  --interpreter "$build_venv/bin/python" >&2
wheel=$(ls target/wheels/hilcam-*.whl)
echo "build-python: $wheel built in $((SECONDS - start)) s ($profile profile)" >&2
rm -rf "$test_venv"
"$base" -m venv "$test_venv" >&2
"$test_venv/bin/python" -m pip install --quiet "$wheel" pytest >&2
"$test_venv/bin/python" -c "import hilcam; hilcam.Camera.preset('nav1024')" >&2
echo "$test_venv/bin/python"
