"""mass_estimator 2 (paper 002's IMM) and 4 (the moving bank) through the built
SuspensionEstimator.fmu: equal to filterpy's IMMEstimator on the same data, the mass on and off
the bank's grid and with the damping 20 % off in the co-simulated loop (loose bounds), bad
parameters refused by name, the FMU state restored."""
from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import IMMEstimator, KalmanFilter
from fmpy.fmi1 import FMICallException

from fmu_driver import Driven
from suspension_estimation.estimators.imm import transition_matrix
from suspension_estimation.estimators.imm_filter import P_START
from suspension_estimation.estimators.model import DiscreteModel, RoadModel
from suspension_estimation.estimators.suspension import SuspensionEstimator
from suspension_estimation.harness.metrics import reference_profile
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE
from suspension_estimation.harness.cosim import CoSimulation, System
from suspension_estimation.harness.scenario import Profile

H = 1e-3
V = 11.1111  # m/s
STD = (0.02, 0.2, 1e-4)  # the contract's default sensor noise: m/s2, m/s2, m
WIRES = ("acc_sprung", "acc_unsprung", "susp_deflection")


def _bank_data(masses, gd, n_hi, steps, seed=11):
    """Measurements of the 400 kg sub-model (its own Phi, Q, H and the sensor noise)."""
    true = DiscreteModel.build(DEFAULT_VEHICLE.with_(m_s=400.0), V, gd, H, RoadModel(n_hi=n_hi))
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(true.Q + 1e-30 * np.eye(6))
    x, out = np.zeros(6), []
    for _ in range(steps):
        x = true.Phi @ x + L @ rng.standard_normal(6)
        out.append(true.H @ x + np.array(STD) * rng.standard_normal(3))
    return np.array(out)


def test_imm_estimator_equals_filterpy_imm_on_the_same_data():
    """SuspensionEstimator with mass_estimator 2 (paper 002's bank: 5 models 300..500 kg; stay
    0.995) and filterpy's IMMEstimator of 5 KalmanFilters built from the same discretised models, on data of the 400 kg
    sub-model: road (the filter's, z_u_est - tire_deflection_est), body and mass (the mean of
    sum_i mu_i m_i over the last imm_window s) equal to 1e-9 of their scale at every step, and
    road_height_est the profile of filterpy's road (high-passed in distance, no reference taken
    off: the IMM is a filter of the registry). The sub-models'
    road here is ISO C with n_hi 3 1/m: with the default (ISO F, 30 1/m) the first S has a
    condition of ~1e11 and scipy's logpdf inside filterpy returns likelihoods at the floor
    (2.2e-308) while ours stay within 1e-13 of exact arithmetic (docs/imm.md)."""
    masses = np.linspace(300.0, 500.0, 5)
    gd = iso8608.class_psd_n0(3)
    R = np.diag(np.square(STD))
    filters = []
    for m in masses:
        d = DiscreteModel.build(DEFAULT_VEHICLE.with_(m_s=float(m)), V, gd, H, RoadModel(n_hi=3.0))
        f = KalmanFilter(6, 3)
        f.F, f.Q, f.H, f.R = d.Phi.copy(), d.Q.copy(), d.H.copy(), R.copy()
        f.x, f.P = np.zeros((6, 1)), P_START.copy()
        filters.append(f)
    ref = IMMEstimator(filters, np.full(5, 1 / 5), transition_matrix(5, 0.995))
    est = SuspensionEstimator(road_estimator=0, mass_estimator=2, imm_mass_min=300.0, imm_mass_max=500.0,
                              imm_models=5, imm_stay=0.995, road_class=3, q_class_min=3, imm_road_n_hi=3.0,
                              m_s_nominal=float(DEFAULT_VEHICLE.m_s))
    worst = np.zeros(3)
    ref_mass, ref_road, profile, scale = [], [], [], 0.0
    n = int(round(est.cfg.tuning.imm_window / H))  # the mass: mean over the last imm_window s
    for z in _bank_data(masses, gd, 3.0, 600):
        o = est.step(z[0], z[1], z[2], V, H)
        ref.predict()
        ref.update(z.reshape(3, 1))
        assert ref.likelihood.min() > 1e-300  # filterpy's likelihoods not at their floor
        xr = ref.x[:, 0]
        ref_mass.append(ref.mu @ masses)
        ref_road.append(xr[4])
        profile.append(o["road_height_est"])
        scale = max(scale, np.abs(xr).max())
        worst = np.maximum(worst, [abs(o["z_u_est"] - o["tire_deflection_est"] - xr[4]) / np.abs(xr).max(),
                                   abs(o["z_s_est"] - xr[0]) / np.abs(xr).max(),
                                   abs(o["sprung_mass_est"] - np.mean(ref_mass[-n:])) / 400.0])
    assert worst.max() < 1e-9, worst
    distance = V * H * np.arange(1, len(profile) + 1)
    np.testing.assert_allclose(profile, reference_profile(distance, np.array(ref_road)), rtol=0, atol=1e-9 * scale)
    assert np.std(profile) > 0.1 * np.std(ref_road)  # (the profile is not nothing: 600 steps are 6.7 m)
    assert ref.mu.max() > 0.9  # the comparison saw the probabilities settle on a model


@pytest.mark.parametrize("code", [2, 4])
def test_fmu_runs_the_same_imm(dist, code):
    """The built FMU (contract defaults, mass_estimator ``code``) gives the same outputs as the
    Python estimator of the same configuration on the same data, with a speed change mid-run
    (one re-discretisation of the bank: counted, not timed)."""
    data = _bank_data(None, iso8608.class_psd_n0(6), 30.0, 1500)
    est = SuspensionEstimator(road_estimator=0, mass_estimator=code)
    e = Driven(dist / "SuspensionEstimator.fmu", {"road_estimator": 0, "mass_estimator": code})
    try:
        for k, z in enumerate(data):
            v = V if k < 800 else 2 * V
            o = est.step(z[0], z[1], z[2], v, H)
            e.step(H, acc_sprung=z[0], acc_unsprung=z[1], susp_deflection=z[2], vehicle_speed=v)
            for name in ("road_height_est", "z_s_est", "sprung_mass_est", "road_height_std"):
                assert e.get(name) == o[name], (k, name)
            assert e.get("status") == 0
    finally:
        e.close()
    assert est.composed.model_builds == 2


def loop(dist, estimators: dict[str, dict], mass, stop: float, road_class: int = 3, seed: int = 1,
         plant: dict | None = None) -> dict:
    components = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu",
                  **{n: dist / "SuspensionEstimator.fmu" for n in estimators}}
    connections = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height")]
    for n in estimators:
        connections += [(f"plant.{w}", f"{n}.{w}") for w in WIRES] + [("vehicle_speed", f"{n}.vehicle_speed")]
    parameters = {"road.road_class": road_class, "road.seed": seed, "plant.noise_seed": 1000 + seed,
                  **{f"plant.{k}": v for k, v in (plant or {}).items()}}
    for n, p in estimators.items():
        parameters.update({f"{n}.{k}": v for k, v in {"road_estimator": 0, **p}.items()})
    record = ["road.road_height", "plant.sprung_mass"] + [f"{n}.{o}" for n in estimators
                                                          for o in ("sprung_mass_est", "road_height_est", "status")]
    with CoSimulation(System(components, connections), parameters=parameters,
                      inputs={"vehicle_speed": V, "plant.sprung_mass": mass}, record=record) as sim:
        return sim.run(stop, H)


def _segments(res, name, bounds):
    """(mean |error| % over the last 40 %, last time s after the segment start outside ±5 %)."""
    t, m, true = res["time"], res[f"{name}.sprung_mass_est"], res["plant.sprung_mass"]
    out = []
    for a, b in bounds:
        seg = (t > a + 1e-9) & (t <= b + 1e-9)
        err = 100 * (m[seg] - true[seg]) / true[seg]
        tail = t[seg] > b - 0.4 * (b - a)
        bad = np.nonzero(np.abs(err) > 5.0)[0]
        out.append((float(np.mean(np.abs(err[tail]))), float(t[seg][bad[-1]] - a) if len(bad) else 0.0))
    return out


@pytest.mark.parametrize("seed", [1, 2])
def test_moving_bank_off_the_grid_and_the_fixed_bank_on_it(dist, seed):
    """ISO C, 40 km/h, 412.5 kg then 312.5 kg at 3 s (off the 50 kg grid) for the moving bank,
    400 then 300 kg for the fixed one. Targets 1 % steady / 0.5 s settling; loose bounds here
    (2 %, 1 s): benchmarks/imm_offgrid.py and the imm study measure the targets."""
    off = loop(dist, {"mov": {"mass_estimator": 4}}, Profile(np.array([0.0, 3.0]), np.array([412.5, 312.5]), "step"),
               6.0, seed=seed)
    on = loop(dist, {"fix": {"mass_estimator": 2}}, Profile(np.array([0.0, 3.0]), np.array([400.0, 300.0]), "step"),
              6.0, seed=seed)
    for res, name in ((off, "mov"), (on, "fix")):
        (s1, _), (s2, settle) = _segments(res, name, ((0.0, 3.0), (3.0, 6.0)))
        assert s1 < 2.0 and s2 < 2.0 and settle < 1.0, (name, s1, s2, settle)
        assert np.all(res[f"{name}.status"][1:] == 0)


def test_damping_20_percent_off_is_identified(dist):
    """The plant's c_s 20 % below what the estimator is told: a bank over the mass alone is then
    14-19 % off (docs/imm.md); the sub-models re-built at the identified damping bring the moving
    bank within 3 % (target 2 %) once the damping is known (1 s of data)."""
    res = loop(dist, {"mov": {"mass_estimator": 4}}, 412.5, 5.0, plant={"c_s": 1600.0})
    (s, _), = _segments(res, "mov", ((2.0, 5.0),))
    assert s < 3.0, s


@pytest.mark.parametrize("params, name", [
    ({"mass_estimator": 2, "imm_stay": 1.0}, "imm_stay"),
    ({"mass_estimator": 2, "imm_models": 1}, "imm_models"),
    ({"mass_estimator": 2, "imm_mass_min": 600.0}, "imm_mass_min"),
    ({"mass_estimator": 2, "imm_mass_max": 0.0}, "imm_mass_max"),
])
def test_bad_imm_parameters_are_refused_by_name(dist, params, name):
    e = Driven(dist / "SuspensionEstimator.fmu", {"road_estimator": 0, **params})
    try:
        assert any(s == 3 and name in m for s, m in e.messages), e.messages
        with pytest.raises(FMICallException, match="discard"):
            e.step(H)
    finally:
        e.close()


def test_imm_needs_its_road_code(dist):
    e = Driven(dist / "SuspensionEstimator.fmu", {"mass_estimator": 2})  # road_estimator 2 (default)
    try:
        assert any(s == 3 and "mass_estimator = 2" in m and "road_estimator in {0}" in m for s, m in e.messages)
    finally:
        e.close()


@pytest.mark.parametrize("code", [2, 4])
def test_state_restored_replays_identically(dist, code):
    rng = np.random.default_rng(5)
    z = rng.normal(0, 1, (1200, 3)) * [1.0, 10.0, 0.005]

    def run(e, k0, k1):
        out = []
        for k in range(k0, k1):
            e.step(H, acc_sprung=z[k, 0], acc_unsprung=z[k, 1], susp_deflection=z[k, 2],
                   vehicle_speed=8.0 if k < 700 else 16.0)
            out.append([e.get("road_height_est"), e.get("sprung_mass_est")])
        return np.array(out)

    e = Driven(dist / "SuspensionEstimator.fmu", {"road_estimator": 0, "mass_estimator": code})
    try:
        run(e, 0, 500)
        t1, state = e.t, e.fmu.getFMUstate()
        first = run(e, 500, 1200)
        e.fmu.setFMUstate(state)
        e.t = t1
        assert np.array_equal(run(e, 500, 1200), first)
    finally:
        e.close()
