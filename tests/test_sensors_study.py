"""The sensors study (harness/studies/sensors.py) through the built FMUs, on its smallest grid: the
linear plant, ISO C at 40 km/h, one seed, 12 s; ideal sensors, a body accelerometer bias of
+0.1 m/s2 and a body accelerometer gain of 1.03, each told to one estimator and not to the other."""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.harness.studies import load
from suspension_estimation.harness.studies.runner import SENSOR_ERROR_KEYS, run_all
from suspension_estimation.harness.studies.sensors import CASES, IDEAL, PLANTS, Sensors, errors_of
from suspension_estimation.harness.studies.suite import PaperStudy

BIAS, SCALE = "body acc bias +0.1 m/s2", "body acc scale 1.03"


def test_the_grids_without_running(tmp_path):
    study = load("sensors")
    assert study.cases == CASES and study.plants == tuple(PLANTS)
    small = PaperStudy(studies=("sensors",), dist=tmp_path, **study.defaults)  # what --study sensors alone runs
    assert len(small.specs()) == len(CASES) * len(PLANTS) * 2  # 2 seeds, ISO C, 40 km/h
    full = PaperStudy(studies=("sensors",), seeds=1, classes=(2, 3, 4), dist=tmp_path)
    assert len(full.specs()) == len(CASES) * len(PLANTS) * 3 * 2  # classes B, C, D at 40 and 80 km/h
    assert dict(zip(SENSOR_ERROR_KEYS, errors_of(BIAS)))["acc_sprung_bias"] == 0.1 and errors_of(IDEAL) == ()
    with pytest.raises(ValueError, match="whole number of the 10 ms steps"):
        PaperStudy(studies=("sensors",), duration=30.005, dist=tmp_path).check()


def test_smallest_grid_through_the_fmus(dist, capsys):
    study = Sensors(cases=(IDEAL, BIAS, SCALE), plants=("linear",))
    suite = PaperStudy(seeds=1, duration=12.0, warmup=4.0, classes=(3,), speeds=(40.0,), dist=dist)
    study.check(suite)
    suite.results = run_all(study.specs(suite), workers=2, progress=False, runs=study.runs)
    assert all(r["ok"] for r in suite.results), [r.get("error") for r in suite.results]
    lines = study.markdown(suite)
    print("\n".join(lines))
    rows = [line.split(" | ") for line in lines if line.startswith("| linear |")]
    assert [(r[3], r[4]) for r in rows] == [(IDEAL, "default (= told)"), (BIAS, "default"), (BIAS, "told"),
                                           (SCALE, "default"), (SCALE, "told")]
    for r in rows:  # HP, coverage, mass: each judged
        assert all(v.strip(" |") in ("PASS", "MISS") for v in r[-3:]), r
    assert "PASS" in capsys.readouterr().out

    cells = study.runs_by_cell(suite)
    ideal = cells[("linear", 3, 40, IDEAL)][1]["default"]
    bias = cells[("linear", 3, 40, BIAS)][1]
    scale = cells[("linear", 3, 40, SCALE)][1]
    # told the calibration, the estimator removes it: the HP road error of ideal sensors
    for told in (bias["told"], scale["told"]):
        assert told["err_std_hp_pct"] == pytest.approx(ideal["err_std_hp_pct"], rel=0.02)
    # not told, a 0.1 m/s2 body bias drifts the road: the raw error over 10x that of ideal sensors
    # (the known defect: the default integrates the bias)
    assert bias["default"]["rmse_raw_mm"] > 10 * ideal["rmse_raw_mm"], (bias["default"], ideal)
    assert np.isfinite([v for e in (ideal, *bias.values(), *scale.values()) for v in e.values()]).all()


def test_logging_rates_through_the_fmus(dist):
    """The logging cases: road and plant at 1 ms with the road moving linearly over the step, the
    estimator stepped every 1, 5 or 10 ms on the plant's outputs then (CoSimulation rates), scored
    at its own steps. Targets (issue): 200 Hz within 1.1x and 100 Hz within 1.5x of the 1 kHz HP
    error; measured on the cores with the car simulated at 0.5 ms (benchmarks/logging_rates.py):
    1.15x and 1.20x; here bounds 1.3x and 1.5x, the mass within 0.5 %, covered."""
    from suspension_estimation.harness.studies.sensors import LOGGING, ONE_KHZ

    study = Sensors(cases=tuple(LOGGING), plants=("linear",))
    suite = PaperStudy(seeds=1, duration=20.0, warmup=8.0, classes=(3,), speeds=(40.0,), dist=dist)
    study.check(suite)
    specs = study.specs(suite)
    assert [(s.log_every, s.road_input, s.step) for s in specs] == [(1, 1, 1e-3), (5, 1, 1e-3), (10, 1, 1e-3)]
    suite.results = run_all(specs, workers=2, progress=False, runs=study.runs)
    assert all(r["ok"] for r in suite.results), [r.get("error") for r in suite.results]
    cells = study.runs_by_cell(suite)
    one = cells[("linear", 3, 40, ONE_KHZ)][1]["default"]
    r200 = cells[("linear", 3, 40, "200 Hz logging")][1]["default"]
    r100 = cells[("linear", 3, 40, "100 Hz logging")][1]["default"]
    print(one["err_std_hp_pct"], r200["err_std_hp_pct"], r100["err_std_hp_pct"])
    assert r200["err_std_hp_pct"] < 1.3 * one["err_std_hp_pct"]
    assert r100["err_std_hp_pct"] < 1.5 * one["err_std_hp_pct"]
    for r in (one, r200, r100):
        assert abs(r["mass_err_mean_pct"]) < 0.5 and r["coverage_2sigma"] > 0.9, r
    assert "sensors HP at 200 / 100 Hz vs 1 kHz logging" in [t[0] for t in study.targets(suite)]
