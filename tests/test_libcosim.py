"""libcosim and Ecos as second and third masters: each FMU alone and the shipped SSP systems run in
them and give the harness's numbers once their coupling is accounted for.

libcosim's fixed-step algorithm steps every FMU on the inputs it holds, then moves each
connection's value: every connection lags one step. Ecos (ecos_driver) does the same, and its
numbers are libcosim's to the same tolerances. It initializes the FMUs with the connected
inputs at the values the outputs have in initialization mode (0.0 for these FMUs, which compute
their outputs when initialization ends), then moves the values once before the first step. So
for n steps, with the harness's road r_0 (after initialization) .. r_n:

- ISORoad, fed by nothing (vehicle_speed keeps its start value), is the harness's road: its row
  k (after step k) is r_(k+1);
- QuarterCar settles on road height 0.0 and steps on r_0, r_1, ..., r_(n-1);
- SuspensionEstimator steps on the plant's measurements after initialization, after step 0, ...

libcosim passes the step as integer nanoseconds, so the FMUs see h = 1e-3 s up to rounding:
equal to 1e-9 of each signal's scale (in fact 1e-14 and below).
"""
from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import read_ssd

from fmu_driver import Driven
from suspension_estimation.harness.cosim import CoSimulation
from suspension_estimation.harness.ssp import ROAD_PLANT, ROAD_PLANT_ESTIMATOR, SYSTEMS, read_ssp
from ecos_driver import Ecos
from libcosim_driver import Libcosim

H = 1e-3  # s
V = 11.1111  # m/s, vehicle_speed's start value
REL = 1e-9
# The joint estimator in a closed loop: its mass feedback rebuilds the road filter at discrete
# instants (12 times in the first 0.6 s from rest), which amplifies input differences of 1e-13
# (relative) to ~5e-11 m of road in 0.6 s, ~3e-9 of the estimate's scale (measured on the cores);
# a one-step coupling error would differ by ~1e-2.
REL_CLOSED_LOOP_ESTIMATOR = 1e-8
MEASURED = ("acc_sprung", "acc_unsprung", "susp_deflection")
MASTERS = {"libcosim": Libcosim, "Ecos": Ecos}
# the quarter-car systems; HalfCarLoop has its own tests (test_paper002.py)
QUARTER_CAR_SYSTEMS = [n for n in SYSTEMS if "QuarterCar" in SYSTEMS[n][0]]


def _outputs(fmu) -> list[str]:
    return [v.name for v in read_model_description(str(fmu), validate=False).modelVariables
            if v.causality == "output"]


def _assert_close(got: np.ndarray, want: np.ndarray, name: str, rel: float = REL) -> None:
    scale = max(np.max(np.abs(want)), 1e-300)
    diff = np.max(np.abs(got - want))
    assert diff <= rel * scale, f"{name}: max |libcosim - reference| = {diff:.3g} (scale {scale:.3g})"


def _live_inputs(dist, n: int) -> dict[str, dict[str, np.ndarray]]:
    """Inputs of each FMU alone, one value per step: a speed ramp for the road, the harness's road
    and a payload step for the plant, the harness's plant measurements and speed for the estimator."""
    system = read_ssp(dist / f"{ROAD_PLANT}.ssp", fmu_dir=dist)
    record = ["ISORoad.road_height"] + [f"QuarterCar.{m}" for m in MEASURED]
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=record) as sim:
        gs = sim.run(n * H, H)
    return {"ISORoad": {"vehicle_speed": np.linspace(5.0, 30.0, n)},
            "QuarterCar": {"road_height": gs["ISORoad.road_height"][1:],
                           "sprung_mass": np.where(np.arange(n) < n // 2, 410.0, 480.0)},
            "SuspensionEstimator": {**{m: gs[f"QuarterCar.{m}"][1:] for m in MEASURED},
                                    "vehicle_speed": np.full(n, V)}}


@pytest.mark.parametrize("master", MASTERS)
@pytest.mark.parametrize("name", ["ISORoad", "QuarterCar", "SuspensionEstimator"])
def test_each_fmu_alone_in_a_master_equals_the_fmu_driven_directly(dist, name, master):
    fmu = dist / f"{name}.fmu"
    n = 400
    inputs = _live_inputs(dist, n)[name]
    outputs = _outputs(fmu)
    sim = MASTERS[master].from_fmus({name: fmu}, H)
    got = sim.run(n, [f"{name}.{o}" for o in outputs], {f"{name}.{k}": v for k, v in inputs.items()})
    assert sim.time == pytest.approx(n * H, abs=1e-12)
    d = Driven(fmu, {})
    try:
        want = []
        for k in range(n):
            d.step(H, **{i: v[k] for i, v in inputs.items()})
            want.append([d.get(o) for o in outputs])
        assert not [m for s, m in d.messages if s >= 2]
    finally:
        d.close()
    want = np.array(want, dtype=float)
    for j, o in enumerate(outputs):
        _assert_close(got[:, j], want[:, j], o)
    assert max(np.ptp(want[:, j]) for j in range(len(outputs))) > 0  # something moved


def _harness_road(dist, n: int) -> np.ndarray:
    system = read_ssp(dist / f"{ROAD_PLANT}.ssp", fmu_dir=dist)
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=["ISORoad.road_height"]) as sim:
        return sim.run(n * H, H)["ISORoad.road_height"]  # rows 0..n


def _lagged_plant(dist, road: np.ndarray, n: int) -> tuple[np.ndarray, list[str], np.ndarray]:
    """The plant settled on 0.0 and stepped on road[0..n-1]: its outputs after each step, and its
    measurements after initialization and after each step (rows 0..n)."""
    outputs = _outputs(dist / "QuarterCar.fmu")
    d = Driven(dist / "QuarterCar.fmu", {"road_height": 0.0})
    try:
        measured = [[d.get(m) for m in MEASURED]]
        rows = []
        for k in range(n):
            d.step(H, road_height=road[k])
            rows.append([d.get(o) for o in outputs])
            measured.append([d.get(m) for m in MEASURED])
    finally:
        d.close()
    return np.array(rows), outputs, np.array(measured)


@pytest.mark.parametrize("master", MASTERS)
@pytest.mark.parametrize("name", QUARTER_CAR_SYSTEMS)
def test_shipped_ssp_in_a_master_matches_the_harness_up_to_its_lag(dist, name, master):
    n = 600
    order = SYSTEMS[name][0]
    # libcosim takes its 1 ms step from the SSP's default experiment; Ecos is given it
    sim = Libcosim.from_ssp(dist / f"{name}.ssp") if master == "libcosim" else Ecos.from_ssp(dist / f"{name}.ssp", H)
    plant_out = _outputs(dist / "QuarterCar.fmu")
    est_out = _outputs(dist / "SuspensionEstimator.fmu") if "SuspensionEstimator" in order else []
    names = (["ISORoad.road_height", "ISORoad.distance"] + [f"QuarterCar.{o}" for o in plant_out]
             + [f"SuspensionEstimator.{o}" for o in est_out])
    got = dict(zip(names, sim.run(n, names).T))
    assert sim.time == pytest.approx(n * H, abs=1e-12)

    road = _harness_road(dist, n)
    _assert_close(got["ISORoad.road_height"], road[1:], "ISORoad.road_height")
    _assert_close(got["ISORoad.distance"], V * H * np.arange(1, n + 1), "ISORoad.distance")
    plant, outputs, measured = _lagged_plant(dist, road, n)
    for j, o in enumerate(outputs):
        _assert_close(got[f"QuarterCar.{o}"], plant[:, j], f"QuarterCar.{o}")
    assert np.ptp(got["QuarterCar.z_s"]) > 1e-4
    if not est_out:
        return
    d = Driven(dist / "SuspensionEstimator.fmu", {})
    try:
        est = []
        for k in range(n):
            d.step(H, vehicle_speed=V, **dict(zip(MEASURED, measured[k])))
            est.append([d.get(o) for o in est_out])
        assert not [m for s, m in d.messages if s >= 2]
    finally:
        d.close()
    est = np.array(est)
    for j, o in enumerate(est_out):
        _assert_close(got[f"SuspensionEstimator.{o}"], est[:, j], f"SuspensionEstimator.{o}",
                      REL_CLOSED_LOOP_ESTIMATOR)
    assert np.ptp(got["SuspensionEstimator.road_height_est"]) > 1e-3
    assert np.ptp(got["SuspensionEstimator.sprung_mass_est"]) > 1.0


@pytest.mark.parametrize("name", QUARTER_CAR_SYSTEMS)
def test_shipped_ssps_are_accepted_by_libcosim_and_by_fmpy(dist, name):
    """Every connection of the SSD starts at an element (libcosim requires it); the system inputs
    are read back from the annotation by the harness; FMPy's reader validates the SSD against the
    SSP 1.0 schema and its runner runs it."""
    ssp = dist / f"{name}.ssp"
    ssd = read_ssd(str(ssp))
    assert all(c.startElement is not None for c in ssd.system.connections)
    assert read_ssp(ssp).inputs == ["vehicle_speed"]
    result = simulate_ssp(str(ssp), stop_time=20 * H, step_size=H)
    assert len(result) == 20 and np.all(np.isfinite(result["QuarterCar.z_s"]))
    assert Libcosim.from_ssp(ssp).run(5, ["ISORoad.distance"])[-1, 0] == pytest.approx(5 * H * V, rel=1e-12)
