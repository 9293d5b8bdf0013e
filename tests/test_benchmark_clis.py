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


def _load(name: str):
    script = ROOT / "benchmarks" / name
    spec = importlib.util.spec_from_file_location(f"bench_cli_{script.stem}", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_robust_cores_std_scales(capsys):
    """--std-scales: the coverage of +-2 k std at k = 1 is the cov column, and it cannot fall as k grows."""
    mod = _load("robust_cores.py")
    assert mod.main(["--classes", "C", "--speeds", "40", "--cases", "exact", "--duration", "14",
                     "--estimators", "default", "--std-scales", "0.3,1,3"]) == 0
    row = [c.strip() for c in capsys.readouterr().out.splitlines()[-1].strip("|").split("|")]
    cov, k03, k1, k3 = float(row[8]), float(row[10]), float(row[11]), float(row[12])
    assert k1 == cov and k03 <= k1 <= k3 and k03 < k3
    fast, slow = (float(v) for v in row[13].split(","))
    assert 0 < fast < 1 and 0 < slow < 1  # the exact vehicle: the force-error states inside their prior
    assert mod.main(["--std-scales", "0,1"]) == 1
    assert "--std-scales" in capsys.readouterr().err


def test_robust_cores_spread(capsys):
    """--spread: the cell's coverage is the mean of its seeds', inside their range and at the
    centre of the mean +- 2 standard errors."""
    mod = _load("robust_cores.py")
    assert mod.main(["--classes", "B", "--speeds", "40", "--cases", "c_s -30%", "--duration", "12",
                     "--seeds", "2", "--estimators", "KF (0)", "--spread"]) == 0
    row = [c.strip() for c in capsys.readouterr().out.splitlines()[-1].strip("|").split("|")]
    cov = float(row[8])
    lo, hi = (float(v) for v in row[10].split(" to "))
    a, b = (float(v) for v in row[11].split(" to "))
    assert lo <= cov <= hi and lo < hi  # the KF told the wrong damper: the seeds differ
    assert a <= cov <= b and (a + b) / 2 == pytest.approx(cov, abs=1e-3)


def test_half_car_loop_grid_subset_and_plant_error(capsys):
    """One condition of the grid on a plant with softer springs runs and exits 0; a plant error
    that names no parameter, or a scale that is not positive, is refused in one line."""
    mod = _load("half_car_loop_grid.py")
    assert mod.main(["--speeds", "10", "--classes", "A", "--masses", "672", "--duration", "1",
                     "--plant-error", "k_f=0.85,k_r=0.85"]) == 0
    assert "| 10 | A | 672 |" in capsys.readouterr().out
    for bad in ("k_x=0.8", "k_f=-1", "m_s=0.8"):
        assert mod.main(["--plant-error", bad]) == 1
        assert "--plant-error" in capsys.readouterr().err
    assert mod.main(["--classes", "E"]) == 1
    assert "--classes" in capsys.readouterr().err


def test_half_car_corners_refuses_a_noise_factor_out_of_range(capsys):
    mod = _load("half_car_corners.py")
    for bad in (["--told-noise", "0"], ["--noise", "-1"]):
        assert mod.main(bad) == 1
        assert "--told-noise" in capsys.readouterr().err
