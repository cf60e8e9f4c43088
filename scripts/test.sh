#!/usr/bin/env bash
# The whole test suite (README's second command). Installs what it needs itself.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --all-targets
