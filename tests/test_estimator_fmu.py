"""SuspensionEstimator.fmu through FMPy: joint road + mass estimation in the co-simulated loop,
rejected measurements, refused parameters, changed step sizes."""
from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from fmu_driver import Driven
from suspension_estimation.suspension_fmi.contract import SUSPENSION_ESTIMATOR
from suspension_estimation.harness.cosim import CoSimulation, System
from suspension_estimation.harness.metrics import reference_profile, road_scores

V = 11.1111  # m/s, 40 km/h
OUTPUTS = [v.name for v in SUSPENSION_ESTIMATOR if v.causality == "output"]
REAL_OUTPUTS = [v.name for v in SUSPENSION_ESTIMATOR if v.causality == "output" and v.type == "Real"]
WIRES = ("acc_sprung", "acc_unsprung", "susp_deflection")


def loop(dist, estimators: dict[str, dict], true_mass: float, stop: float, road_class: int = 3,
         step: float = 1e-3, seed: int = 1, plant: dict | None = None) -> np.ndarray:
    """Road -> plant (parameters ``plant``) -> several estimator instances fed by the same plant."""
    components = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu",
                  **{name: dist / "SuspensionEstimator.fmu" for name in estimators}}
    connections = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height")]
    for name in estimators:
        connections += [(f"plant.{w}", f"{name}.{w}") for w in WIRES] + [("vehicle_speed", f"{name}.vehicle_speed")]
    parameters = {"road.road_class": road_class, "road.seed": seed, "plant.noise_seed": seed,
                  **{f"plant.{k}": v for k, v in (plant or {}).items()}}
    for name, params in estimators.items():
        parameters.update({f"{name}.{k}": v for k, v in params.items()})
    record = ["road.road_height", "road.distance", "plant.z_s"] + [f"{n}.{o}" for n in estimators for o in OUTPUTS]
    with CoSimulation(System(components, connections), parameters=parameters,
                      inputs={"vehicle_speed": V, "plant.sprung_mass": true_mass}, record=record) as sim:
        return sim.run(stop, step)


def test_joint_road_and_mass_recovers_a_heavier_body(dist):
    """590 kg told 410 kg, ISO C at 40 km/h, 12 s: the joint estimator finds the mass, and its road
    profile's HP error (against reference_profile) is under half that of the KF that keeps 410 kg
    (seeds 1-4: 2.2-2.5 % against 9.9-11.3 %, 0.21-0.24 of it; in-band gain 1.005-1.007)."""
    res = loop(dist, {"kf": {"mass_estimator": 0}, "joint": {}}, true_mass=590.0, stop=12.0)
    t = res["time"]
    mass = res["joint.sprung_mass_est"]
    assert abs(mass[t > 2.0] / 590.0 - 1).max() < 0.05
    assert np.all(res["kf.sprung_mass_est"] == 410.0)
    kf = road_scores(t, res["kf.road_height_est"], res["road.road_height"], warmup=4.0, distance=res["road.distance"])
    joint = road_scores(t, res["joint.road_height_est"], res["road.road_height"], warmup=4.0,
                        distance=res["road.distance"])
    # the filter that keeps 410 kg misses the road in band (its in-band gain stays ~1); the joint one does not
    assert joint["err_std_hp_pct"] < 0.5 * kf["err_std_hp_pct"]
    assert 0.85 < joint["gain_hp"] < 1.15
    for name in REAL_OUTPUTS:
        assert np.all(np.isfinite(res[f"joint.{name}"])), name


def test_outputs_are_consistent_with_each_other(dist):
    """The deflections are differences of the states; road_height_est is the profile of the
    filter's road z_u_est - tire_deflection_est made as harness.smoothing.profile_of makes it (freed
    of the reference, high-passed in distance), but for the lag correction that z_u_est carries
    (steady_state.reference_lag): rms difference under 0.5 % of the profile's rms (seeds 1-3:
    0.04-0.07 %; the filter's road itself differs from it by 67-216 %)."""
    from suspension_estimation.estimators.suspension import EstimatorConfig
    from suspension_estimation.harness.smoothing import profile_of

    res = loop(dist, {"e": {"road_class": 3}}, true_mass=410.0, stop=3.0)
    e = {o: res[f"e.{o}"][1:] for o in OUTPUTS}
    assert np.allclose(e["susp_deflection_est"], e["z_s_est"] - e["z_u_est"], atol=1e-12)
    cfg = EstimatorConfig(road_class=3)
    rm = cfg.tuning.road_model
    road = e["z_u_est"] - e["tire_deflection_est"]
    profile = profile_of(road, np.full(len(road), V), 1e-3, cfg.profile_cutoff, cfg.tuning.standstill_speed,
                         (rm.f_ref, rm.zeta_ref))
    y = e["road_height_est"]
    assert np.sqrt(np.mean((profile - y) ** 2)) < 5e-3 * np.sqrt(np.mean(y ** 2))
    assert np.all(e["road_height_std"] > 0) and np.all(e["nis"] >= 0)
    assert np.all(e["status"] == 0)
    assert np.all(e["road_class_est"] == 0)  # a 3 s run at 40 km/h is shorter than the class window


def test_online_road_class_is_identified(dist):
    res = loop(dist, {"e": {}}, true_mass=410.0, stop=30.0, road_class=4, step=2e-3)
    cls = res["e.road_class_est"]
    seen = cls[cls > 0]
    assert len(seen) > 0, "no class identified within 330 m"
    assert np.mean(seen == 4) > 0.9


def test_non_finite_measurement_is_rejected_and_the_filter_predicts_through(dist):
    e = Driven(dist / "SuspensionEstimator.fmu", {"road_class": 3})
    try:
        e.run(1e-3, 200, REAL_OUTPUTS, acc_sprung=0.0, acc_unsprung=0.0, susp_deflection=0.0)
        for bad in (float("nan"), float("inf"), -float("inf")):
            e.step(1e-3, acc_sprung=bad)
            assert e.get("status") == 1
            assert all(math.isfinite(e.get(o)) for o in REAL_OUTPUTS)
            e.step(1e-3, acc_sprung=0.0, acc_unsprung=bad)
            assert e.get("status") == 1
            e.step(1e-3, acc_unsprung=0.0, susp_deflection=bad)
            assert e.get("status") == 1
            e.step(1e-3, susp_deflection=0.0)
            assert e.get("status") == 0
        assert not any(status >= 3 for status, _ in e.messages), e.messages
    finally:
        e.close()


@pytest.mark.parametrize("channel", WIRES)
def test_non_finite_burst_is_logged_once_and_skipped(dist, channel):
    """Two bursts of 20 NaN samples on one measurement among noisy live ones: one warning per
    burst naming the channel (none naming another), one line when it is finite again with the
    count, status 1 on the burst's steps, 0 before it, every output finite."""
    rng = np.random.default_rng(1)
    n, bursts, length = 400, (150, 270), 20
    noise = {"acc_sprung": 0.02, "acc_unsprung": 0.2, "susp_deflection": 1e-4}  # the contract's sensor stds
    meas = {w: rng.normal(0.0, noise[w], n) for w in WIRES}
    bad = np.zeros(n, bool)
    for k in bursts:
        bad[k:k + length] = True
    meas[channel][bad] = np.nan
    e = Driven(dist / "SuspensionEstimator.fmu", {"road_class": 3})
    try:
        status = np.empty(n, int)
        for k in range(n):
            e.step(1e-3, **{w: meas[w][k] for w in WIRES})
            status[k] = e.get("status")
            assert all(math.isfinite(e.get(o)) for o in REAL_OUTPUTS), k
        messages = e.messages
    finally:
        e.close()
    assert np.all(status[bad] == 1)
    assert np.all(status[:bursts[0]] == 0)
    warnings = [m for s, m in messages if s == 1]
    assert len(warnings) == len(bursts), messages
    assert all(channel in m and not any(w in m for w in WIRES if w != channel) for m in warnings), warnings
    finite_again = [m for s, m in messages if s == 0 and channel in m and f"after {length} non-finite" in m]
    assert len(finite_again) == len(bursts), messages
    assert not any(s >= 2 for s, _ in messages), messages


@pytest.mark.parametrize("params, name", [
    ({"forgetting_factor": 0.9}, "forgetting_factor"), ({"forgetting_factor": 1.01}, "forgetting_factor"),
    ({"m_s_nominal": 0.0}, "m_s_nominal"), ({"k_t": -1.0}, "k_t"), ({"c_s": float("nan")}, "c_s"),
    ({"road_estimator": 9}, "road_estimator"), ({"mass_estimator": -1}, "mass_estimator"),
    ({"road_class": 9}, "road_class"), ({"acc_sprung_noise_std": 0.0}, "acc_sprung_noise_std"),
    ({"defl_noise_std": -1e-4}, "defl_noise_std"),
])
def test_bad_parameter_is_refused_naming_it_and_its_range(dist, params, name):
    assert_refused(dist, params, name)


def assert_refused(dist, params: dict, name: str) -> None:
    """The FMU logs an error naming ``name`` and its range, and every step is then discarded."""
    e = Driven(dist / "SuspensionEstimator.fmu", params)
    try:
        assert any(s == 3 and name in m and "range" in m for s, m in e.messages), e.messages
        with pytest.raises(FMICallException, match="discard"):
            e.step(1e-3)
    finally:
        e.close()


@pytest.mark.parametrize("speed", [-3.0, float("nan")])
def test_bad_speed_is_refused_at_the_step(dist, speed):
    """vehicle_speed has a range: a speed outside it, or not finite, is refused (unlike a measurement)."""
    e = Driven(dist / "SuspensionEstimator.fmu", {})
    try:
        e.step(1e-3)
        with pytest.raises(FMICallException, match="discard"):
            e.step(1e-3, vehicle_speed=speed)
        assert any(s == 3 and "vehicle_speed" in m and "range" in m for s, m in e.messages), e.messages
    finally:
        e.close()


def test_a_changed_step_size_is_followed(dist):
    """1 -> 5 -> 2 ms mid-run: the FMU re-discretises and keeps estimating the road profile: in each
    stretch the std of its error against reference_profile (its mean left out) under 0.15 of the
    profile's std (the default road and seeds 1-3: 0.015-0.022, 0.033-0.037, 0.027-0.047)."""
    steps = np.concatenate([np.full(4000, 1e-3), np.full(1600, 5e-3), np.full(4000, 2e-3)])  # 20 s
    components = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu",
                  "e": dist / "SuspensionEstimator.fmu"}
    connections = [("vehicle_speed", "road.vehicle_speed"), ("vehicle_speed", "e.vehicle_speed"),
                   ("road.road_height", "plant.road_height")] + [(f"plant.{w}", f"e.{w}") for w in WIRES]
    with CoSimulation(System(components, connections), parameters={"plant.acc_sampling": 1},
                      inputs={"vehicle_speed": V}, record=["road.road_height", "road.distance", "e.road_height_est"]
                      ) as sim:
        res = sim.run(float(steps.sum()), steps)
    t = res["time"]
    profile = reference_profile(res["road.distance"], res["road.road_height"])
    for lo, hi in ((2.0, 4.0), (6.0, 12.0), (14.0, 20.0)):
        part = (t >= lo) & (t <= hi)
        err = res["e.road_height_est"][part] - profile[part]
        assert np.std(err - err.mean()) < 0.15 * np.std(profile[part]), (lo, hi)


@pytest.mark.parametrize("seed", [1, 2])
def test_stop_and_go_holds_the_mass(dist, seed):
    """40 km/h, braking to a stand for 5 s, off again (ISO C): through the FMU the mass stays
    within 2 % of the truth at every instant after the first second, and holds while the car
    stands (before Tuning.standstill_speed the RLS fitted noise to noise: 410 kg -> 41 kg)."""
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    def speed(t: float) -> float:  # m/s
        return 11.1111 * min(max(abs(t - 6.5) - 2.5, 0.0), 1.0)

    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=seed)
    car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=seed)
    car.settle(road.height(0.0))
    d = Driven(dist / "SuspensionEstimator.fmu", {})
    try:
        s, mass, standing = 0.0, [], []
        for k in range(12000):
            t = k * 1e-3
            v = speed(t)
            s += v * 1e-3
            car.step(road.height(s), 1e-3)
            d.step(1e-3, acc_sprung=car.measured[0], acc_unsprung=car.measured[1],
                   susp_deflection=car.measured[2], vehicle_speed=v)
            if t >= 1.0:
                mass.append(d.get("sprung_mass_est"))
                standing.append(v == 0.0)
        mass = np.array(mass)
        assert np.abs(mass / DEFAULT_VEHICLE.m_s - 1.0).max() < 0.02, mass.min()
        stand = mass[np.array(standing)]
        assert stand.max() - stand.min() < 1e-9 * stand.max()
    finally:
        d.close()
