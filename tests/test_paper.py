"""``python -m harness paper`` (harness/studies/): a quick study through the built FMUs.

One seed, 12 s runs, 2 s warm-up, ISO C, plus the 10 ms study and the vehicle-mass case: the
structure of the tables, JSON and plots, and loose, seed-robust behaviour (a KF with the wrong mass
is clearly worse than one with the true mass; joint road + mass estimation is close to the latter;
the mass estimate is within 5 % at the end of every payload segment). The targets of the issue are
the paper command's to report, not this test's to assert.
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from harness.studies.paper000 import MASSES
from harness.studies.paper001 import mass_segments
from harness.studies.runner import ESTIMATORS, RunSpec, parse_classes, run_all
from harness.studies.suite import PaperStudy

ROOT = Path(__file__).resolve().parents[1]
METRICS = ("err_std_raw_pct", "err_std_hp_pct", "gain_hp", "rmse_raw_mm", "rmse_hp_mm", "coverage_2sigma",
           "mass_err_end_pct")


@pytest.fixture(scope="module")
def quick(dist, tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    proc = subprocess.run([sys.executable, "-m", "harness", "paper", "--seeds", "1", "--duration", "12",
                           "--warmup", "2", "--classes", "C", "--workers", "2", "--study10ms", "-q",
                           "--dist", str(dist), "--out", str(out)],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc, out, json.loads((out / "paper_runs.json").read_text())


def _section(md: str, title: str) -> list[list[str]]:
    """Rows (as cell lists) of the first markdown table after the heading that starts with ``title``."""
    lines = md.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("#") and title in line)
    rows, seen = [], False
    for line in lines[start + 1:]:
        if line.startswith("|"):
            seen = True
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
        elif seen:
            break
    return rows[2:]  # without header and separator


def test_tables_printed_and_written_with_every_cell(quick):
    proc, out, _ = quick
    md = (out / "paper_tables.md").read_text()
    assert md in proc.stdout
    cell = re.compile(r"^-?\d+\.\d+ ± \d+\.\d+$")
    for title in ("(a) MME&KF paper, Table 2", "10 ms, accelerations point-sampled",
                  "10 ms, accelerations averaged"):
        rows = _section(md, title)
        assert len(rows) == len(MASSES) * len(ESTIMATORS)
        for r in rows:
            assert len(r) == 12 and r[0] == "C" and r[-1] == "1", r
            for c in r[4:10]:  # HP, raw, gain, RMSE HP, RMSE raw, coverage: all numbers, mean ± std
                assert cell.match(c), r
            assert r[10] == "–" or cell.match(r[10]), r
        kf = {float(r[1]): r[3] for r in rows if r[2] == "KF"}
        assert kf == {410.0: "8.1", 590.0: "9.5", 230.0: "12.1"}  # the paper's Table 2, ISO C
    assert len(_section(md, "(c) 10 ms study")) == len(MASSES) * len(ESTIMATORS)
    mass_rows = _section(md, "(b) Vehicle-mass paper")
    assert len(mass_rows) == 2 + 3 + 3 and all("±" in r[2] for r in mass_rows)
    targets = _section(md, "Targets")
    assert targets and all(r[1] in ("PASS", "MISS", "n/a") for r in targets)
    assert _section(md, "Where the time goes")
    assert "## Failed runs\n\nnone" in md
    for f in ("road_C_590kg.png", "road_C_230kg.png", "mass_paper001.png"):
        assert (out / f).stat().st_size > 10_000


def test_json_holds_every_run_and_metric(quick):
    _, _, data = quick
    runs = data["runs"]
    assert data["config"]["classes"] == ["C"] and data["config"]["seeds"] == 1
    studies = [r["spec"]["study"] for r in runs]
    assert studies.count("table2") == 3 and studies.count("table2_10ms") == 6 and studies.count("mass") == 1
    assert all(r["ok"] for r in runs)
    for r in runs:
        if r["spec"]["study"] != "mass":
            assert set(r["estimators"]) == {e.instance for e in ESTIMATORS}
            for s in r["estimators"].values():
                assert all(isinstance(s[k], float) and math.isfinite(s[k]) for k in METRICS)
        assert r["timing"]["us_per_step"] > 0
    assert len(data["targets"]) > 5


def test_behaviour_is_that_of_the_papers(quick):
    _, _, data = quick
    t2 = {r["spec"]["mass"]: r["estimators"] for r in data["runs"] if r["spec"]["study"] == "table2"}
    # same road, same plant, same parameters: KF and KF-with-true-mass are the same filter at 410 kg
    assert t2[410.0]["KF"] == t2[410.0]["KF_true"]
    for m in (590.0, 230.0):
        e = t2[m]
        hp = {k: v["err_std_hp_pct"] for k, v in e.items()}
        assert hp["KF"] > 2 * hp["KF_true"] + 5, hp  # the wrong mass costs tens of points
        assert hp["joint"] < 1.5 * hp["KF_true"] + 1, hp  # estimating the mass recovers nearly all of it
        assert abs(e["joint"]["mass_err_end_pct"]) < 5
        assert 0.8 < e["KF_true"]["gain_hp"] < 1.2
    (mass,) = [r for r in data["runs"] if r["spec"]["study"] == "mass"]
    assert [s["mass_kg"] for s in mass["segments"]] == [m for _, _, m in mass_segments()]
    for s in mass["segments"]:
        assert abs(s["end_err_pct"]) < 5, s


def test_a_failed_run_is_reported_and_the_others_go_on(dist, tmp_path):
    good = RunSpec("table2", 3, 1, 0.3, 0.1, 1e-3, str(dist), mass=410.0)
    refused = RunSpec("table2", 9, 1, 0.3, 0.1, 1e-3, str(dist), mass=410.0)  # no ISO class 9
    missing = RunSpec("table2", 3, 1, 0.3, 0.1, 1e-3, str(tmp_path / "nowhere"), mass=590.0)
    results = run_all([good, refused, missing], workers=1, progress=False, log=lambda s: None)
    assert [r["ok"] for r in results] == [True, False, False]
    assert "ISORoad" in results[1]["error"] and "road_class" in results[1]["error"]
    assert "does not exist" in results[2]["error"]
    study = PaperStudy(seeds=1, duration=0.3, warmup=0.1, classes=(3,), dist=dist, results=results)
    md = study.markdown()
    rows = {(r[1], r[2]): r for r in _section(md, "(a) MME&KF paper, Table 2")}
    assert rows[("590", "KF")][4] == "failed" and rows[("590", "KF")][-1] == "0 (1 failed)"
    assert rows[("410", "KF")][-1] == "1"
    assert results[1]["error"] in md and results[2]["error"] in md
    files = study.write(tmp_path / "out")
    data = json.loads(files[1].read_text())
    assert [r["ok"] for r in data["runs"]] == [True, False, False]


def test_classes_and_arguments_are_checked(dist):
    assert parse_classes("b, C,d") == (2, 3, 4)
    with pytest.raises(ValueError, match="--classes"):
        parse_classes("B,X")
    with pytest.raises(ValueError, match="--warmup"):
        PaperStudy(duration=5, warmup=5, dist=dist).check()
    with pytest.raises(ValueError, match="whole number"):
        PaperStudy(duration=10.0005, dist=dist).check()


def test_the_workers_leave_the_fmus_their_own_packages():
    """All FMUs of a process share one module cache: a worker that imported the source tree's
    ``plant`` or ``estimators`` would run them instead of the copies bundled in the FMUs."""
    code = ("import sys, harness.studies.suite, harness.studies.paper000, harness.studies.paper001, "
            "harness.studies.road_class; print(sorted(m for m in ('plant', 'estimators') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == "[]", proc.stdout + proc.stderr


def test_the_online_class_study_identifies_the_class(dist):
    from harness.studies import road_class
    from harness.studies.runner import run_one

    r = run_one(RunSpec("class", 4, 2, 15.0, 2.0, 2e-3, str(dist), speed=20.0), run=road_class.run)
    assert r["ok"], r.get("error")
    assert r["class_first_s"] < 10.0  # a 102.4 m window at 20 m/s
    assert r["class_right"] >= 0.95 and set(r["class_counts"]) <= {3, 4, 5}


_ORPHAN_SCRIPT = """
import os, sys, time
sys.path.insert(0, sys.argv[1])
from harness.studies.runner import process_pool
if __name__ == "__main__":
    ex = process_pool(1)
    print(ex.submit(os.getpid).result(), flush=True)
    ex.submit(time.sleep, 120)
    time.sleep(120)
"""


def test_pool_workers_end_when_the_study_is_killed(tmp_path):
    """`python -m harness paper` killed outright (SIGKILL, no clean-up): its spawned workers
    leave within seconds instead of finishing their run and blocking on a dead pipe."""
    import os
    import signal
    import time

    script = tmp_path / "study.py"
    script.write_text(_ORPHAN_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), str(Path(__file__).resolve().parents[1])],
                            stdout=subprocess.PIPE, text=True)
    try:
        worker = int(proc.stdout.readline())
        os.kill(worker, 0)  # alive, busy with the 120 s task
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        for _ in range(100):
            try:
                os.kill(worker, 0)
            except ProcessLookupError:
                break
            try:  # reap it if this process is its subreaper
                os.waitpid(worker, os.WNOHANG)
            except ChildProcessError:
                pass
            time.sleep(0.1)
        else:
            os.kill(worker, signal.SIGKILL)
            pytest.fail("the pool worker outlived its killed parent by 10 s")
    finally:
        if proc.poll() is None:
            proc.kill()
