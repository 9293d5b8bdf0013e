"""Step-size jitter: ``fmpy.simulate_fmu`` (like fmusim and libcosim) steps by t_(n+1) - t_n with
t_n = n*dt, a dozen values of h that differ in the last bits. The plant and the estimator treat
them as one step (plant.step_size): they discretise once and give what the harness gives at an
exact constant step. Work is counted (discretisations in the FMU state), not timed."""
from __future__ import annotations

import tempfile

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

from suspension_estimation.estimators.state_classes import STATE_CLASSES
from suspension_estimation.estimators.suspension import SuspensionEstimator
from suspension_estimation.harness.cosim import CoSimulation, LogSink, System
from suspension_estimation.harness.ssp import read_ssp
from suspension_estimation.suspension_fmi import state as fmu_state
from suspension_estimation.plant.quarter_car import QuarterCar
from suspension_estimation.plant.state_classes import QUARTER_CAR_STATE
from suspension_estimation.plant.step_size import STEP_RTOL, same_step
from suspension_estimation.plant.vehicle import Vehicle

H = 1e-3  # s
V = 11.1111  # m/s
N = 2000
MEASURED = ("acc_sprung", "acc_unsprung", "susp_deflection")
ESTIMATES = ("road_height_est", "road_height_std", "z_s_est", "v_u_est", "sprung_mass_est", "nis")
PLANT_OUT = ("acc_sprung", "acc_unsprung", "susp_deflection", "z_s", "v_u", "tire_force")


def test_fmpys_steps_jitter():
    t = 0.0 + np.arange(N + 1) * H  # how simulate_fmu makes its communication points
    steps = np.diff(t)
    assert len(set(steps.tolist())) > 5 and np.mean(steps != H) > 0.3
    assert np.max(np.abs(steps - H)) < STEP_RTOL * H  # what the tolerance must absorb


def test_same_step():
    assert same_step(H * (1 + 1e-12), H) == H and same_step(H, None) == H
    assert same_step(5 * H, H) == 5 * H and same_step(H * (1 + 2 * STEP_RTOL), H) != H


def _road_and_plant(dist) -> np.ndarray:
    system = read_ssp(dist / "RoadPlant.ssp", fmu_dir=dist)
    record = ["ISORoad.road_height"] + [f"QuarterCar.{m}" for m in MEASURED]
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=record) as sim:
        return sim.run(N * H, H)


CLASSES = {"QuarterCar": QUARTER_CAR_STATE, "SuspensionEstimator": STATE_CLASSES}


def _state(fmu: FMU2Slave, classes: tuple[type, ...]) -> dict:
    """The variables and core objects of the serialized FMU state."""
    state = fmu.getFMUstate()
    try:
        blob = fmu.serializeFMUstate(state)
    finally:
        fmu.freeFMUstate(state)
    return fmu_state.load(bytes(blob), classes)


def _simulate(path, inputs: dict[str, np.ndarray], outputs, start_values=None):
    """simulate_fmu at 1 ms with the inputs at t_k = k H; returns (result, FMU state snapshot)."""
    md = read_model_description(str(path))
    unzip = extract(str(path), unzipdir=tempfile.mkdtemp())
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="jitter")
    log = LogSink()
    fmu.instantiate(loggingOn=True, callbacks=log.callbacks)
    signal = np.zeros(N + 1, dtype=[("time", float)] + [(k, float) for k in inputs])
    signal["time"] = np.arange(N + 1) * H
    for k, v in inputs.items():
        signal[k] = np.r_[v, v[-1]]
    try:
        res = simulate_fmu(str(path), stop_time=N * H, step_size=H, output_interval=H, input=signal,
                           output=list(outputs), start_values=start_values or {}, fmu_instance=fmu)
        assert len(res) == N + 1, log.messages
        return res, _state(fmu, CLASSES[md.coSimulation.modelIdentifier])
    finally:
        fmu.terminate()
        fmu.freeInstance()
        log.close()


def _assert_same(got, want, name):
    scale = max(float(np.max(np.abs(want))), 1e-300)
    assert np.max(np.abs(got - want)) <= 1e-12 * scale, f"{name}: max |diff| {np.max(np.abs(got - want)):.3g}"


def test_plant_in_simulate_fmu_equals_the_harness_and_discretises_once(dist):
    gs = _road_and_plant(dist)
    road = gs["ISORoad.road_height"][1:]  # what the plant got at each step in the harness
    path = dist / "QuarterCar.fmu"
    res, snap = _simulate(path, {"road_height": road}, PLANT_OUT)
    with CoSimulation(System({"QuarterCar": path}), inputs={"QuarterCar.road_height": road},
                      record=[f"QuarterCar.{o}" for o in PLANT_OUT]) as sim:
        want = sim.run(N * H, H)
    for o in PLANT_OUT:
        _assert_same(res[o], want[f"QuarterCar.{o}"], o)
    assert snap["plant"].discretisations == 1


def test_estimator_in_simulate_fmu_equals_the_harness_and_builds_once(dist):
    gs = _road_and_plant(dist)
    meas = {m: gs[f"QuarterCar.{m}"][1:] for m in MEASURED}
    path = dist / "SuspensionEstimator.fmu"
    res, snap = _simulate(path, meas, ESTIMATES, {"vehicle_speed": V})
    inputs = {f"SuspensionEstimator.{m}": v for m, v in meas.items()}
    inputs["SuspensionEstimator.vehicle_speed"] = V
    with CoSimulation(System({"SuspensionEstimator": path}), inputs=inputs,
                      record=[f"SuspensionEstimator.{o}" for o in ESTIMATES]) as sim:
        want = sim.run(N * H, H)
    for o in ESTIMATES:
        _assert_same(res[o], want[f"SuspensionEstimator.{o}"], o)
    core = snap["core"]
    # one build at the first step, then one per change of the joint estimator's model mass
    assert core.model.h == H
    assert core.model_builds == 1 + core.mass_rebuilds


def test_a_real_step_change_still_rediscretises():
    """1 -> 5 -> 2 ms: three models, each built for its step exactly; jitter on each adds none."""
    est = SuspensionEstimator(mass_estimator=0)
    car = QuarterCar(Vehicle())
    rng = np.random.default_rng(3)
    for h in (1e-3, 5e-3, 2e-3):
        for k in range(50):
            hj = h * (1 + rng.uniform(-1, 1) * 1e-12)
            car.step(0.001 * np.sin(k / 7), hj)
            est.step(*car.measured, V, hj)
        assert est.model.h == car._key[1] and abs(est.model.h - h) <= 1e-12 * h
    assert est.model_builds == 3 and car.discretisations == 3


def test_idle_inputs_take_the_steady_path():
    """All-zero or constant inputs (a master before its connections carry data): the channels are
    frozen, the filter predicts through, and nothing is rebuilt or re-solved per step."""
    for value in ((0.0, 0.0, 0.0), (0.3, -0.2, 0.004)):
        est = SuspensionEstimator()
        for _ in range(3000):
            out = est.step(*value, V, H * (1 + 1e-13))
        assert out["status"] == 1 and np.isfinite(out["road_height_est"]) and np.isfinite(out["road_height_std"])
        assert est.model_builds == 1
