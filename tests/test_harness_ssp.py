"""The SSP files build.py writes (harness/ssp.py): read back with FMPy's SSP reader, run with
FMPy's SSP runner and compared with the harness, allowing for that runner's lag per connection."""
from __future__ import annotations

import zipfile

import numpy as np
import pytest
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import read_ssd

from harness.cosim import CoSimulation, System
from harness.ssp import ROAD_PLANT, ROAD_PLANT_ESTIMATOR, SYSTEMS, read_ssp, write_system_ssps

H = 1e-3  # s
V = 11.1111  # m/s


def _systems(dist):
    return [n for n in SYSTEMS if all((dist / f"{c}.fmu").is_file() for c in SYSTEMS[n][0])]


def test_build_writes_the_system_ssps(dist):
    assert (dist / f"{ROAD_PLANT}.ssp").is_file()
    has_estimator = (dist / "SuspensionEstimator.fmu").is_file()
    assert (dist / f"{ROAD_PLANT_ESTIMATOR}.ssp").is_file() == has_estimator


def test_the_estimator_system_is_skipped_without_its_fmu(dist, tmp_path):
    for c in ("ISORoad", "QuarterCar"):
        (tmp_path / f"{c}.fmu").write_bytes((dist / f"{c}.fmu").read_bytes())
    assert [p.name for p in write_system_ssps(tmp_path)] == [f"{ROAD_PLANT}.ssp"]


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_ssp_round_trip(dist, name):
    if name not in _systems(dist):
        pytest.skip(f"FMUs of {name} are not built yet")
    path = dist / f"{name}.ssp"
    order, connections, _ = SYSTEMS[name]
    ssd = read_ssd(str(path))  # validates SystemStructure.ssd against the SSP 1.0 schema
    assert ssd.name == name and ssd.system.name == name
    assert [(c.name, c.source) for c in ssd.system.elements] == [(c, f"resources/{c}.fmu") for c in order]
    assert [(c.name, c.kind) for c in ssd.system.connectors] == [("vehicle_speed", "input")]
    got = {(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections}
    want = {(s.split(".")[0] if "." in s else None, s.split(".")[-1], *e.split(".")) for s, e in connections}
    assert got == want
    with zipfile.ZipFile(path) as z:  # the FMUs inside are the built ones
        for c in order:
            assert z.read(f"resources/{c}.fmu") == (dist / f"{c}.fmu").read_bytes()
    system = read_ssp(path)  # the harness's view, FMUs taken from the SSP itself
    assert system.order == order and system.connections == connections
    assert system.inputs == ["vehicle_speed"]


def test_fmpy_ssp_runner_matches_the_harness_up_to_its_lag(dist):
    """FMPy's runner steps all FMUs, then moves every connection: each connection lags one step,
    connections start at 0.0, rows carry the step's start time. So (rows k, n steps):

    - ISORoad gets the speed one step late and starts at speed 0: its row k (after k+1 steps)
      has travelled k steps, which is the harness's road at t_k exactly;
    - QuarterCar sees the road two steps late, after a 0.0 first: it is the harness's plant driven
      alone with road inputs [0, r(t_0), r(t_1), ...], its row k the harness's row k+1.
    """
    n = 500
    ssp = simulate_ssp(str(dist / f"{ROAD_PLANT}.ssp"), stop_time=n * H, step_size=H,
                       input={"vehicle_speed": lambda t: V})
    assert len(ssp) == n and ssp["time"][0] == 0.0
    system = read_ssp(dist / f"{ROAD_PLANT}.ssp", fmu_dir=dist)
    rec = ["ISORoad.road_height", "ISORoad.distance"]
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=rec) as sim:
        gs = sim.run(n * H, H)
    for name in rec:
        assert np.array_equal(ssp[name], gs[name][:n]), name

    plant = System({"QuarterCar": system.components["QuarterCar"]})
    lagged_road = np.r_[0.0, gs["ISORoad.road_height"][:n - 1]]
    states = ["QuarterCar.z_s", "QuarterCar.z_u", "QuarterCar.acc_sprung_true", "QuarterCar.tire_force"]
    with CoSimulation(plant, inputs={"QuarterCar.road_height": lagged_road}, record=states) as sim:
        alone = sim.run(n * H, H)
    for name in states:
        assert np.allclose(ssp[name], alone[name][1:], rtol=1e-12, atol=1e-15 * np.max(np.abs(alone[name]))), name
    assert np.ptp(ssp["QuarterCar.z_s"]) > 1e-4  # the plant moved

    # and the Gauss-Seidel plant, which starts at rest on the road's first height where the SSP
    # runner's starts at 0.0, is that response without the lead-in: close once it has decayed
    m = 3000
    ssp = simulate_ssp(str(dist / f"{ROAD_PLANT}.ssp"), stop_time=m * H, step_size=H,
                       input={"vehicle_speed": lambda t: V})
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=["QuarterCar.z_s"]) as sim:
        z = sim.run(m * H, H)["QuarterCar.z_s"]
    late = slice(m - 1000, m - 1)
    assert np.max(np.abs(ssp["QuarterCar.z_s"][1:][late] - z[:m - 1][late])) < 0.02 * np.max(np.abs(z))


def test_fmpy_ssp_runner_runs_the_estimator_system(dist):
    if ROAD_PLANT_ESTIMATOR not in _systems(dist):
        pytest.skip("SuspensionEstimator.fmu is not built yet")
    r = simulate_ssp(str(dist / f"{ROAD_PLANT_ESTIMATOR}.ssp"), stop_time=0.1, step_size=H,
                     input={"vehicle_speed": lambda t: V})
    assert len(r) == 100
    assert np.all(np.isfinite(r["SuspensionEstimator.road_height_est"]))
    assert np.ptp(r["SuspensionEstimator.road_height_est"]) > 0
