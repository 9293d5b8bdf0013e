"""A 2-minute version of benchmarks/soak.py through the built FMUs (the hour-long run is manual)."""
from __future__ import annotations

import importlib.util
import math

from conftest import ROOT


def _soak_module():
    spec = importlib.util.spec_from_file_location("soak", ROOT / "benchmarks" / "soak.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_two_minute_soak_passes_its_checks(dist):
    """120 s at 1 ms of road -> plant -> estimator: no divergence (outputs finite, no
    re-initialisation, P symmetric positive definite at the end), HP road error of the last 60 s
    within 10 % of that of 10-70 s, RSS growth below 10 MB over the last 50 s."""
    soak = _soak_module()
    res = soak.soak(duration=120.0, dist=dist)
    assert res["ok"], soak.summary(res)
    assert res["steps"] == 120_000
    assert [(w["start"], w["end"]) for w in res["windows"]] == [(10.0, 70.0), (60.0, 120.0)]
    # the scores are real scores of a working filter, not a vacuous comparison
    assert 0.5 < res["hp_first_pct"] < 10.0 and 0.9 < res["windows"][0]["gain_hp"] < 1.1
    assert res["rejected_samples"] == 0
    assert res["P_min_eig"] > 0 and math.isfinite(res["P_max_eig"])
    assert abs(res["mass_last_mean_kg"] - 410.0) < 0.05 * 410.0


def test_stepper_in_chunks_equals_cosimulation_run(dist):
    """harness.streaming.Stepper advanced in two chunks gives CoSimulation.run's record bit for
    bit (1 s of road -> plant -> estimator at 1 ms), and its clock ends at 1 s exactly."""
    import numpy as np

    from suspension_estimation.harness.cosim import CoSimulation, System
    from suspension_estimation.harness.streaming import Stepper

    wires = ("acc_sprung", "acc_unsprung", "susp_deflection")
    system = System({"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu",
                     "e": dist / "SuspensionEstimator.fmu"},
                    [("vehicle_speed", "road.vehicle_speed"), ("vehicle_speed", "e.vehicle_speed"),
                     ("road.road_height", "plant.road_height")] + [(f"plant.{w}", f"e.{w}") for w in wires])
    record = ["road.road_height", "plant.acc_sprung", "e.road_height_est", "e.status"]
    kw = {"parameters": {"road.seed": 3}, "inputs": {"vehicle_speed": 11.1111}, "record": record}
    with CoSimulation(system, **kw) as sim:
        whole = sim.run(1.0, 1e-3)
    with Stepper(system, **kw) as sim:
        first = sim.initialize()
        chunks = np.vstack([sim.advance(400, 1e-3), sim.advance(600, 1e-3)])
        assert sim.time == 1.0 and sim.steps_done == 1000
    for j, name in enumerate(record):
        assert first[j] == whole[name][0], name
        np.testing.assert_array_equal(chunks[:, j], whole[name][1:].astype(float), err_msg=name)
