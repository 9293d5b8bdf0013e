"""Shared fixtures: the FMUs are built once per test session, into a temporary folder, from the
current sources, and the tests load them from there (not from the source tree)."""
from __future__ import annotations

import os

# Small matrices: BLAS threads only cost time (and set before numpy is imported anywhere).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# optional sample data beside the checkout (tests that use it skip without it)
SHARED = ROOT.parent / "shared"


@pytest.fixture(scope="session")
def dist(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, str(ROOT / "build.py"), "--dist", str(out)],
                          capture_output=True, text=True, cwd=tmp_path_factory.getbasetemp())
    if proc.returncode != 0:
        pytest.fail(f"build.py failed:\n{proc.stdout}\n{proc.stderr}")
    return out


_EXIT = pytest.StashKey[int]()


def pytest_sessionfinish(session, exitstatus):
    session.config.stash[_EXIT] = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave without running the C-level exit handlers of the pythonfmu binaries loaded in this
    process: their destructor can touch the already finalized interpreter and abort the process
    after every result has been reported (PythonFMU issue 229). Results are flushed first."""
    status = config.stash.get(_EXIT, None)
    if status is None:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


@pytest.fixture
def driven(dist):
    """Factory of single FMU instances: ``driven("ISORoad", road_class=4)``; all closed at teardown."""
    from fmu_driver import Driven

    made = []

    def make(model: str, **params):
        d = Driven(dist / f"{model}.fmu", params)
        made.append(d)
        return d

    yield make
    for d in made:
        d.close()
