"""The SSP files build.py writes (harness/ssp.py): read back with FMPy's SSP reader, run with
FMPy's SSP runner and compared with the harness, allowing for that runner's lag per connection."""
from __future__ import annotations

import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import read_ssd

from fmu_driver import Driven
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
    # libcosim takes no connection from a system connector: the system input is an annotation
    assert ssd.system.connectors == []
    got = {(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections}
    want = {(*s.split("."), *e.split(".")) for s, e in connections if "." in s}
    assert got == want
    with zipfile.ZipFile(path) as z:  # the FMUs inside are the built ones
        for c in order:
            assert z.read(f"resources/{c}.fmu") == (dist / f"{c}.fmu").read_bytes()
    system = read_ssp(path)  # the harness's view, FMUs taken from the SSP itself
    assert system.order == order and system.connections == connections
    assert system.inputs == ["vehicle_speed"]


def _assert_same(got: np.ndarray, want: np.ndarray, name: str) -> None:
    """Equal to 1e-12 of the signal's scale (the same FMU fed the same numbers: in fact bit-identical)."""
    scale = np.max(np.abs(want))
    assert np.max(np.abs(got - want)) <= 1e-12 * scale, f"{name}: max |diff| {np.max(np.abs(got - want)):.3g}"


def _plant_outputs(system) -> list[str]:
    return [f"QuarterCar.{v.name}" for v in read_model_description(str(system.components["QuarterCar"]),
                                                                   validate=False).modelVariables
            if v.causality == "output"]


def _lagged_road_and_plant(dist, system, ssp, n):
    """The harness's road at t_1..t_n, and the harness's plant driven alone with the road the SSP
    runner gives it ([0, r(t_1), r(t_2), ...]); its rows 1..n are the SSP runner's rows 0..n-1."""
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=["ISORoad.road_height", "ISORoad.road_velocity",
                                                                   "ISORoad.distance"]) as sim:
        gs = sim.run(n * H, H)
    plant = System({"QuarterCar": system.components["QuarterCar"]})
    lagged_road = np.r_[0.0, gs["ISORoad.road_height"][1:n]]
    with CoSimulation(plant, inputs={"QuarterCar.road_height": lagged_road}, record=_plant_outputs(system)) as sim:
        alone = sim.run(n * H, H)
    for name in ("ISORoad.road_height", "ISORoad.road_velocity", "ISORoad.distance"):
        assert np.array_equal(ssp[name], gs[name][1:n + 1]), name
    assert np.array_equal(ssp["QuarterCar.road_height"], gs["ISORoad.road_height"][1:n + 1])  # fed at the next step
    for name in _plant_outputs(system):
        if name in ssp.dtype.names:
            _assert_same(ssp[name], alone[name][1:], name)
    assert np.ptp(ssp["QuarterCar.z_s"]) > 1e-4  # the plant moved
    return gs, alone


def test_fmpy_ssp_runner_matches_the_harness_up_to_its_lag(dist):
    """FMPy's runner steps all FMUs, then moves every connection: each connection lags one step,
    connections start at 0.0, rows carry the step's start time. The SSP wires no system input
    (see harness.ssp), so vehicle_speed keeps its start value V. So (rows k, n steps):

    - ISORoad runs at V from the start: its row k (after k+1 steps) is the harness's road at t_(k+1);
    - QuarterCar sees the road one step late, after a 0.0 first: it is the harness's plant driven
      alone with road inputs [0, r(t_1), r(t_2), ...], its row k the harness's row k+1.
    """
    n = 500
    ssp = simulate_ssp(str(dist / f"{ROAD_PLANT}.ssp"), stop_time=n * H, step_size=H)
    assert len(ssp) == n and ssp["time"][0] == 0.0
    assert np.allclose(ssp["time"], H * np.arange(n), rtol=0, atol=1e-12)
    system = read_ssp(dist / f"{ROAD_PLANT}.ssp", fmu_dir=dist)
    _lagged_road_and_plant(dist, system, ssp, n)

    # and the Gauss-Seidel plant, which starts at rest on the road's first height where the SSP
    # runner's starts at 0.0, is that response without the lead-in: close once it has decayed
    m = 3000
    ssp = simulate_ssp(str(dist / f"{ROAD_PLANT}.ssp"), stop_time=m * H, step_size=H)
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=["QuarterCar.z_s"]) as sim:
        z = sim.run(m * H, H)["QuarterCar.z_s"]
    late = slice(m - 1000, m - 1)
    assert np.max(np.abs(ssp["QuarterCar.z_s"][1:][late] - z[:m - 1][late])) < 0.02 * np.max(np.abs(z))


def test_fmpy_ssp_runner_matches_the_harness_up_to_its_lag_with_the_estimator(dist):
    """RoadPlantEstimator.ssp in FMPy's runner: road and plant as above; SuspensionEstimator,
    initialized at its start values, keeps vehicle_speed V and gets at step k the measurements
    one step late (0.0 at step 0): it is the estimator driven alone with the measurements
    [0, y_1, ..., y_(n-1)] of the harness's plant of the lagged road (rows 1..), and its
    outputs after step k are the runner's row k."""
    if ROAD_PLANT_ESTIMATOR not in _systems(dist):
        pytest.skip("SuspensionEstimator.fmu is not built yet")
    n = 1000
    ssp = simulate_ssp(str(dist / f"{ROAD_PLANT_ESTIMATOR}.ssp"), stop_time=n * H, step_size=H)
    assert len(ssp) == n
    system = read_ssp(dist / f"{ROAD_PLANT_ESTIMATOR}.ssp", fmu_dir=dist)
    _, alone = _lagged_road_and_plant(dist, system, ssp, n)

    measured = ("acc_sprung", "acc_unsprung", "susp_deflection")
    speed = np.full(n, V)
    inputs = {m: np.r_[0.0, alone[f"QuarterCar.{m}"][1:n]] for m in measured}
    element = {e.name: e for e in read_ssd(str(dist / f"{ROAD_PLANT_ESTIMATOR}.ssp")).system.elements}
    outputs = [c.name for c in element["SuspensionEstimator"].connectors if c.kind == "output"]
    assert {"road_height_est", "road_height_std", "sprung_mass_est", "road_class_est", "status"} <= set(outputs)
    est = Driven(system.components["SuspensionEstimator"], {})
    try:
        rows = []
        for k in range(n):
            est.step(H, vehicle_speed=speed[k], **{m: inputs[m][k] for m in measured})
            rows.append([est.get(o) for o in outputs])
        assert not [m for s, m in est.messages if s >= 2]
    finally:
        est.close()
    rows = np.array(rows, dtype=float)
    for m in measured:
        assert np.array_equal(ssp[f"SuspensionEstimator.{m}"][:n - 1], inputs[m][1:]), m
    for j, o in enumerate(outputs):
        name = f"SuspensionEstimator.{o}"
        assert np.max(np.abs(ssp[name] - rows[:, j])) <= 1e-9, f"{name}: max |diff| {np.max(np.abs(ssp[name] - rows[:, j])):.3g}"
    assert np.ptp(rows[:, outputs.index("road_height_est")]) > 1e-3
    assert np.ptp(rows[:, outputs.index("sprung_mass_est")]) > 1.0
