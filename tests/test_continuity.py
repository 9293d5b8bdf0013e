"""No step in road_height_est at a class change, and class decisions with hysteresis
(estimators/road_class.py)."""
from __future__ import annotations

import numpy as np

from suspension_estimation.estimators.road_class import RoadClassifier
from suspension_estimation.harness.cosim import CoSimulation, System
from suspension_estimation.harness.testroads import add_sag, joined_iso, write_profile
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.road import SyntheticRoad

TOL = 0.5e-3  # m: largest allowed step of the estimate beyond the road's own change


def _boundary_profile(length: float, seed: int) -> np.ndarray:
    """An ISO road whose Gd(n0) sits on the B/C boundary (grade index 7), every 0.1 m."""
    road = SyntheticRoad(2 * iso8608.class_psd_n0(2), seed=seed)
    return np.array([road.height(s) for s in np.arange(0.0, length, 0.1)])


def test_a_road_on_a_class_boundary_does_not_flip():
    for seed in (1, 2):
        q = _boundary_profile(2500.0, seed)
        runs = {}
        for hyst in (0.0, 0.5):
            c = RoadClassifier(hysteresis=hyst)
            seen = []
            for i, z in enumerate(q):
                seen.append(c.update(0.1 * i, z, 20.0))
            seen = np.array(seen)
            seen = seen[seen > 0]
            runs[hyst] = int(np.count_nonzero(np.diff(seen)))
        assert runs[0.0] >= 3, runs  # the road does sit on the boundary: without the margin it flips
        assert runs[0.5] <= 1, runs


def test_no_step_in_the_road_estimate_when_the_class_changes(dist, tmp_path):
    """Through the FMUs at 40 km/h on a measured-style file (ISO A joined to ISO C, a 1.1 m sag
    over 100-400 m, absolute level 583 m): the online
    class changes from A upwards, and after the start transient (50 m) the estimate never moves
    more than TOL beyond the road's own change in one step."""
    s, h = joined_iso([1, 3], [250.0, 300.0])  # ISO A joined to ISO C at 250 m
    f = write_profile(tmp_path / "a_to_c.csv", s, add_sag(s, h, 100.0, 300.0, 1.1), level=583.0)
    wires = ("acc_sprung", "acc_unsprung", "susp_deflection")
    comps = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu", "e": dist / "SuspensionEstimator.fmu"}
    conn = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height"),
            ("vehicle_speed", "e.vehicle_speed")] + [(f"plant.{w}", f"e.{w}") for w in wires]
    v = 40 / 3.6
    with CoSimulation(System(comps, conn), parameters={"road.profile_file": str(f)},
                      inputs={"vehicle_speed": v, "plant.sprung_mass": 410.0},
                      record=["road.road_height", "road.distance", "e.road_height_est", "e.road_class_est"]) as sim:
        rec = sim.run(round(540.0 / v / 1e-3) * 1e-3, 1e-3)
    cls = rec["e.road_class_est"]
    assert cls[rec["road.distance"] < 240].max() == 1 and cls[-1] >= 3, np.unique(cls)
    step = np.abs(np.diff(rec["e.road_height_est"]) - np.diff(rec["road.road_height"]))
    late = rec["road.distance"][1:] > 50.0
    assert step[late].max() < TOL, step[late].max()
