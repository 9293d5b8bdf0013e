"""Shared fixtures: the FMUs are built once per test session, into a temporary folder, from the
current sources, and the tests load them from there (not from the source tree)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"


@pytest.fixture(scope="session")
def dist(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, str(ROOT / "build.py"), "--dist", str(out)],
                          capture_output=True, text=True, cwd=tmp_path_factory.getbasetemp())
    if proc.returncode != 0:
        pytest.fail(f"build.py failed:\n{proc.stdout}\n{proc.stderr}")
    return out
