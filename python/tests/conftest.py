"""Fixtures for the Python module's tests (docs/python.md; run by scripts/test.sh).

The module under test is the installed wheel (scripts/build-python.sh installs it into a
fresh venv and prints its python); the CLI is the workspace's `hilcam` binary
($HILCAM_BIN, default target/debug/hilcam, which `cargo test` builds)."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def cli():
    """Run the CLI from the repository root; returns the CompletedProcess."""
    binary = os.environ.get("HILCAM_BIN", str(ROOT / "target" / "debug" / "hilcam"))
    assert os.access(binary, os.X_OK), f"{binary} is missing: build it (cargo build) or set HILCAM_BIN"

    def run(*args, check=True):
        p = subprocess.run([binary, "--log", "warn", *args], cwd=ROOT, capture_output=True, text=True)
        if check:
            assert p.returncode == 0, p.stderr
        return p

    return run
