#!/usr/bin/env bash
# hilcam vs Mitsuba 3 side by side (benchmark only; Mitsuba is never a runtime dependency).
# Builds hilcam in release, then runs benches/vs_mitsuba.py, which creates
# target/mitsuba-venv (pinned mitsuba + drjit from PyPI), apt-get installs libllvm19 if no
# libLLVM >= 16 is present, checks the conventions, and times both renderers alternately.
#   scripts/bench-vs-mitsuba.sh                                   # sphere + plate, defaults
#   scripts/bench-vs-mitsuba.sh scenes/sphere.toml --depth 4 --depth 2
#   scripts/bench-vs-mitsuba.sh --quick                           # 128×128, ~30 s after setup
#   scripts/bench-vs-mitsuba.sh --criterion                       # equal sensor criterion (issue 36)
#   scripts/bench-vs-mitsuba.sh --criterion --quick               # the same at 128×128, ~2 min
# Results: target/vs-mitsuba/<scene>_<W>x<H>_d<depth>_<sampler>.{csv,png}
#          (--criterion: <scene>_<W>x<H>_d<depth>_criterion_<samplers>.{csv,png})
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --bin hilcam
python3 -c 'import tomllib' 2>/dev/null || { echo "bench-vs-mitsuba: needs Python >= 3.11" >&2; exit 2; }
exec python3 benches/vs_mitsuba.py "$@"
