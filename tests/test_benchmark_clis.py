"""Every benchmark script with a command line prints its help (a literal % in a help text, e.g.
a case name such as "c_s -30%", made argparse raise instead)."""
from __future__ import annotations

import importlib.util

import pytest

from conftest import ROOT

SCRIPTS = sorted(p for p in (ROOT / "benchmarks").glob("*.py") if "def main(argv" in p.read_text())


def test_the_scripts_are_found():
    assert {"real_roads.py", "robust_cores.py", "run.py"} <= {p.name for p in SCRIPTS}


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_help(script, capsys):
    spec = importlib.util.spec_from_file_location(f"bench_cli_{script.stem}", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # the scripts run only under __main__
    with pytest.raises(SystemExit) as e:
        mod.main(["--help"])
    assert e.value.code == 0
    assert "usage:" in capsys.readouterr().out
