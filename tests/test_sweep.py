"""``python -m harness sweep`` (harness/sweep.py): small grids through the built FMUs, on a Dask
LocalCluster of two worker processes and in this process; skipping what is done, failures
recorded with their reason, the same numbers as ``python -m harness paper``, the sweep files."""
from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from harness.studies import runner
from harness.studies.suite import PaperStudy
from harness.sweep import SweepError, load_sweep, read_results, run_sweep

ROOT = Path(__file__).resolve().parents[1]

TINY = """
duration = 1.0
step = 0.001
warmup = 0.2
[grid]
road_class = ["C"]
mass = [410.0, 590.0]
seed = [1]
[estimators.KF]
road_estimator = 0
mass_estimator = 0
[estimators.bad]
mass_estimator = 1
forgetting_factor = 2.0
"""


def _sweep(tmp_path: Path, text: str, name: str = "tiny"):
    f = tmp_path / f"{name}.toml"
    f.write_text(text)
    return load_sweep(f)


@pytest.fixture(scope="module")
def cluster():
    from distributed import Client

    from harness.sweep import local_cluster

    c = local_cluster(2)
    client = Client(c)
    yield c, client
    client.close()
    c.close()


@pytest.fixture(scope="module")
def on_dask(dist, cluster, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sweep")
    sweep = _sweep(tmp, TINY)
    rep = run_sweep(sweep, dist, out=tmp / "out", scheduler=cluster[0].scheduler_address, progress=False,
                    log=lambda s: None)
    return sweep, rep, tmp / "out"


def test_a_grid_on_dask_gives_a_row_per_run_and_records_the_refusal(on_dask):
    sweep, rep, out = on_dask
    assert (rep.rows, rep.done_before, rep.runs, rep.written, rep.failed) == (4, 0, 2, 4, 2)
    rows = read_results(out).to_pylist()
    assert len(rows) == 4 and len({r["key"] for r in rows}) == 4
    for r in rows:
        assert r["worker"] not in (os.getpid(), -1)  # in a worker process
        if r["estimator"] == "KF":
            assert r["ok"] and r["error"] is None
            assert 0 < r["err_std_hp_pct"] < 100 and math.isfinite(r["rmse_raw_mm"])
        else:
            assert not r["ok"] and "forgetting_factor" in r["error"] and "bad" in r["error"]
            assert r["err_std_hp_pct"] is None
    assert sorted(r["mass"] for r in rows if r["ok"]) == [410.0, 590.0]


def test_the_workers_run_the_packages_bundled_in_the_fmus(on_dask, cluster):
    """All FMUs of a process share one module cache: a worker that imported the source tree's
    ``plant`` would run it instead of the copy bundled in the FMUs."""
    files = cluster[1].run(lambda: getattr(sys.modules.get("plant"), "__file__", None))
    assert files and all(f is not None and not f.startswith(str(ROOT / "plant")) and "resources" in f
                         for f in files.values()), files


def test_a_rerun_skips_what_is_done_and_retries_failures_unless_told(on_dask, dist):
    sweep, _, out = on_dask
    parts = sorted(out.glob("part-*.parquet"))
    rep = run_sweep(sweep, dist, out=out, workers=0, skip_failed=True, progress=False)
    assert (rep.done_before, rep.runs, rep.written) == (4, 0, 0)
    assert sorted(out.glob("part-*.parquet")) == parts and read_results(out, latest=False).num_rows == 4
    rep = run_sweep(sweep, dist, out=out, workers=0, progress=False, log=lambda s: None)
    assert (rep.done_before, rep.runs, rep.written, rep.failed) == (2, 2, 2, 2)  # the refused estimator only
    assert read_results(out, latest=False).num_rows == 6
    latest = read_results(out).to_pylist()
    assert len(latest) == 4 and sum(not r["ok"] for r in latest) == 2


def test_an_interrupted_sweep_resumes_and_reuses_the_fmus_with_the_numbers_of_paper(dist, tmp_path):
    sweep = _sweep(tmp_path, TINY.replace("seed = [1]", "seed = [1, 2, 3]").split("[estimators.bad]")[0])
    out = tmp_path / "out"
    first = run_sweep(sweep, dist, out=out, workers=0, limit=1, progress=False)
    (out / "part-99999999T999999-1-00000.parquet.tmp").write_bytes(b"PAR1 cut short")  # a write cut short
    rest = run_sweep(sweep, dist, out=out, workers=0, progress=False)
    assert (first.runs, rest.done_before, rest.runs, rest.failed) == (1, 1, 5, 0)
    rows = read_results(out).to_pylist()
    assert len(rows) == 6 and len({r["worker"] for r in rows}) == 1
    assert sorted(r["worker_run"] for r in rows) == [1, 1, 2, 3, 4, 5]  # one CoSimulation per call, reset
    kf = next(e for e in runner.ESTIMATORS if e.instance == "KF")
    for r in [r for r in rows if r["worker_run"] >= 4]:  # after resets, against fresh instances
        spec = runner.RunSpec("table2", r["road_class"], r["seed"], 1.0, 0.2, 1e-3, str(dist), mass=r["mass"])
        fresh = runner.run_one(spec, (kf,))["estimators"]["KF"]
        for k, v in fresh.items():
            assert r[k] == v or (math.isnan(v) and math.isnan(r[k])), k


def test_the_table2_sweep_is_the_paper_table2(dist):
    sweep = load_sweep("paper_table2")
    study = PaperStudy(dist=dist)
    want = {(s.road_class, s.mass, s.seed, s.duration, s.warmup, s.step, s.speed, s.vehicle, s.noise, s.nominal_mass)
            for s in study.specs() if s.study == "table2"}
    got = {(s.road_class, s.mass, s.seed, s.duration, s.warmup, s.step, s.speed, s.vehicle, s.noise, s.nominal_mass)
           for s in (t.spec for t in sweep.tasks(dist))}
    assert got == want and len(got) == 90
    assert [(e.instance, e.parameters, e.true_mass) for e in sweep.estimators] == \
        [(e.instance, e.parameters, e.true_mass) for e in runner.ESTIMATORS]


def test_monte_carlo_draws_are_seeded_and_in_range():
    a, b = load_sweep("monte_carlo"), load_sweep("monte_carlo")
    assert a.points == b.points and len(a.points) == 24
    assert [p["seed"] for p in a.points] == list(range(1, 25))
    assert all(8 <= p["speed"] <= 25 and 230 <= p["mass"] <= 590 and p["road_class"] in (2, 3, 4) for p in a.points)
    assert len({p["mass"] for p in a.points}) == 24


def test_sweep_file_errors_name_the_key(tmp_path, dist):
    with pytest.raises(SweepError, match="grid.masses"):
        _sweep(tmp_path, TINY.replace("mass = [", "masses = ["))
    with pytest.raises(SweepError, match="no .estimators"):
        _sweep(tmp_path, TINY.split("[estimators.KF]")[0])
    with pytest.raises(SweepError, match="estimators.KF.no_such"):
        _sweep(tmp_path, TINY.replace("[estimators.bad]", "no_such = 1\n[estimators.bad]")).check(dist)
    proc = subprocess.run([sys.executable, "-m", "harness", "sweep", "no_such_sweep"], capture_output=True,
                          text=True, cwd=tmp_path, timeout=60)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "no_such_sweep" in proc.stderr


def test_paper_runs_on_dask_reuse_the_workers_fmus_with_the_same_numbers(dist, cluster):
    from harness.sweep import run_specs

    specs = [runner.RunSpec("table2", 3, s, 0.5, 0.1, 1e-3, str(dist), mass=590.0) for s in (1, 2, 3)]
    specs.insert(1, runner.RunSpec("table2", 9, 1, 0.5, 0.1, 1e-3, str(dist)))  # no ISO class 9
    got = run_specs(specs, scheduler=cluster[0].scheduler_address, progress=False, log=lambda s: None)
    assert [r["ok"] for r in got] == [True, False, True, True]
    assert "ISORoad" in got[1]["error"] and "road_class" in got[1]["error"]
    fresh = runner.run_one(specs[3])["estimators"]
    assert got[3]["estimators"].keys() == fresh.keys()
    for inst, scores in fresh.items():
        for k, v in scores.items():
            assert got[3]["estimators"][inst][k] == v or (math.isnan(v) and math.isnan(got[3]["estimators"][inst][k]))
    assert set(got[3]["timing"]["do_step_us"]) == {e.instance for e in runner.ESTIMATORS} | {"ISORoad", "QuarterCar"}


@pytest.mark.parametrize("argv, missing", [
    (["sweep", "small_grid", "--workers", "0"], "pyarrow"),
    (["sweep", "small_grid", "--workers", "2"], "distributed"),
    (["paper", "--dask", "--seeds", "1"], "distributed"),
])
def test_without_the_sweep_extra_the_commands_name_it(argv, missing, dist, tmp_path, monkeypatch, capsys):
    from harness.cli import main

    monkeypatch.setitem(sys.modules, missing, None)  # as if not installed
    assert main([*argv, "--dist", str(dist), "--out", str(tmp_path / "out"), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{missing} is not installed" in err and '".[sweep]"' in err, err
    assert not (tmp_path / "out").exists()
