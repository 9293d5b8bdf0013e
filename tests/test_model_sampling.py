"""The step-averaged acceleration model (acc_sampling = 1) with the common-mode reference, and the
reference's step response (estimators/model.py, estimators/steady_state.py)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.linalg import expm

from suspension_estimation.estimators import SuspensionEstimator
from suspension_estimation.estimators.model import (IVS, IVS_PREV, IVU, DiscreteModel, RoadModel,
                              measurement_covariance, output_matrix,
                              state_matrix)
from suspension_estimation.estimators.steady_state import analyse, steady_gain
from suspension_estimation.harness.metrics import road_scores
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

SPEED = 40 / 3.6


def test_averaged_model_reports_physical_acceleration_with_reference():
    """With the 0.01 Hz reference, H x_k of the 8-state model is the step average of the PHYSICAL
    accelerations (no reference acceleration), checked noise-free against a fine quadrature of
    the continuous 6-state model. The previous design, (v_k - v_{k-1}) / h, fails this by the
    reference acceleration (2.6e-4 to 1.8e-2 m/s^2 here)."""
    h, road = 1e-2, RoadModel()
    m = DiscreteModel.build(DEFAULT_VEHICLE, SPEED, iso8608.class_psd_n0(6), h, road, acc_sampling=1)
    A = state_matrix(DEFAULT_VEHICLE, SPEED, road)
    Cp = output_matrix(DEFAULT_VEHICLE, deflection=False)
    x6 = np.array([0.05, 0.2, 0.03, -0.4, 0.01, 0.3])  # m, m/s: far from equilibrium
    X = np.r_[x6, 0.0, 0.0]
    s = np.linspace(0.0, h, 2001)
    for _ in range(20):
        traj = np.array([expm(A * si) @ x6 for si in s])  # (ns, 6)
        a = Cp @ traj.T
        avg = simpson(a, x=s, axis=1) / h
        X = m.Phi @ X
        x6 = X[:6]
        np.testing.assert_allclose(m.H[:2] @ X, avg, rtol=1e-9, atol=1e-9)
        old = (traj[-1, [IVS, IVU]] - traj[0, [IVS, IVU]]) / h  # the previous design's H x
        assert np.max(np.abs(old - avg)) > 1e-4  # the reference acceleration it included


@pytest.mark.parametrize("hold", [False, True])
def test_averaged_model_noise_covariance_is_van_loan_of_augmented_system(hold):
    """Q of the 8-state model is positive semi-definite and the increments' block is nonzero:
    the noise of the step moves z_s, v_s and hence the reference's velocity increment."""
    m = DiscreteModel.build(DEFAULT_VEHICLE, SPEED, iso8608.class_psd_n0(6), 1e-3, RoadModel(),
                            acc_sampling=1, road_hold=hold)
    assert np.min(np.linalg.eigvalsh(m.Q)) > -1e-12 * np.max(np.abs(m.Q))
    assert abs(m.Q[IVS_PREV, IVS]) > 0.0


def _steady_hp(h, acc, cls=2):
    Rm = measurement_covariance(0.02, 0.2, 1e-4)
    m = DiscreteModel.build(DEFAULT_VEHICLE, SPEED, iso8608.class_psd_n0(6), h, RoadModel(),
                            acc_sampling=acc, road_hold=acc == 1)
    K, _ = steady_gain(m, Rm)
    return analyse(m.Phi, m.H, K, Rm, h, iso8608.class_psd_n0(cls), SPEED,
                   f=np.geomspace(1e-3, 0.499 / h, 3000), acc_sampling=acc)


def test_averaged_sensor_at_least_as_good_as_point_samples_steady_state():
    """Each sensor with its matching model, the same noise per sample (ISO B, 40 km/h, 410 kg):
    at 10 ms the anti-aliased average is better (3.2 % against 3.6 % HP), at 1 ms equal within
    1 % (2.75 / 2.73). The old averaged model gave 8.2 % and 6.9 %."""
    p10, a10 = _steady_hp(1e-2, 0), _steady_hp(1e-2, 1)
    p1, a1 = _steady_hp(1e-3, 0), _steady_hp(1e-3, 1)
    assert a10["hp_pct"] < 0.95 * p10["hp_pct"], (a10["hp_pct"], p10["hp_pct"])
    assert a1["hp_pct"] < 1.02 * p1["hp_pct"], (a1["hp_pct"], p1["hp_pct"])
    assert a10["hp_noise_pct"] < p10["hp_noise_pct"]
    for a in (a10, a1):
        assert 0.99 < a["gain_hp"] < 1.02


def test_averaged_sensor_simulated_at_10ms_beats_point_samples():
    """Plain co-simulation order (road, plant with the road held, estimator), ISO B, 30 s at
    10 ms, KF at the true mass: matched acc_sampling 1 has the lower HP road error (road seeds
    1-6: 2.48-2.72 % against 2.92-3.25 % with point samples)."""
    h, n, seed = 1e-2, 3000, 4
    hp = {}
    for acc in (0, 1):
        road = SyntheticRoad(iso8608.class_psd_n0(2), seed=seed)
        car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=1000 + seed, acc_sampling=acc)
        car.settle(road.height(0.0))
        est = SuspensionEstimator(road_estimator=0, mass_estimator=0, acc_sampling=acc)
        r, e = np.empty(n), np.empty(n)
        for k in range(n):
            r[k] = road.height(SPEED * (k + 1) * h)
            car.step(r[k], h)
            e[k] = est.step(*car.measured, SPEED, h)["road_height_est"]
        t = np.arange(1, n + 1) * h
        hp[acc] = road_scores(t, e, r, warmup=10.0, distance=SPEED * t)["err_std_hp_pct"]
    assert hp[1] < hp[0] < 5.0, hp


@pytest.mark.parametrize("plant", ["linear", "air spring"])
def test_default_at_200_and_100_hz_with_averaged_accelerations(plant):
    """Logging at 5 and 10 ms with averaged (anti-aliased) accelerations, the default estimator
    (damping identified): the sprung mass within 1.5 % of the truth, and on the linear plant the HP
    road error within 3x (5 ms) and 6.5x (10 ms) of the same road logged at 1 ms. Road seeds 1-5
    (noise seed 1000 + seed): 1.5-1.75 % at 1 ms, 1.01-2.39x at 5 ms, 3.3-5.2x (5.0-9.0 %) at
    10 ms, the mass within 0.54-1.29 % at 10 ms. At 10 ms the damping is identified high (seed 2:
    2065 / 2175 N.s/m at 5 / 10 ms against the plant's 2000) and the default's road is
    sensitive to it there: told 2175 without identification 4-12 % per 2 s, told 2000 2.1 %
    (the exact-model KF at 10 ms: 1.9 %). The mass regression pairs the step average of the body
    acceleration with the mid-step deflection (with the end-of-step one the identified damping
    came out 21-24 % low, the mass 11-21 %), and its deflection-rate filter stays below 0.3 x the
    sampling rate (at 120 Hz, beyond Nyquist, the air-spring car's mass came out 9 / 49 % low).
    ISO C, 40 km/h; the air-spring car's mass at 1 / 5 / 10 ms, road seeds 1-3: 0.2 / 0.4 / -0.8,
    0.7 / 1.1 / 0.2, -1.4 / -1.8 / -3.8 % (the bound holds for the seed tested, 1, only)."""
    from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER

    hp, mass = {}, {}
    for h in (1e-3, 5e-3, 1e-2):
        road = SyntheticRoad(iso8608.class_psd_n0(3), seed=1)
        if plant == "linear":
            car, told = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=1001, acc_sampling=1), DEFAULT_VEHICLE
        else:
            car = NonlinearQuarterCar(DEFAULT_VEHICLE, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, noise=SensorNoise(),
                                      noise_seed=1001, acc_sampling=1)
            told = car.linearisation()
        car.settle(road.height(0.0))
        est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s,
                                  acc_sampling=1)
        n = int(round(24.0 / h))
        out = np.empty((n, 3))
        for k in range(n):
            car.step(road.height(SPEED * (k + 1) * h), h)
            o = est.step(*car.measured, SPEED, h)
            out[k] = o["road_height_est"], o["sprung_mass_est"], car.road
        t = np.arange(1, n + 1) * h
        hp[h] = road_scores(t, out[:, 0], out[:, 2], warmup=10.0, distance=SPEED * t)["err_std_hp_pct"]
        mass[h] = out[t > 10.0, 1].mean() / DEFAULT_VEHICLE.m_s - 1.0
    assert max(abs(m) for m in mass.values()) < 0.015, mass
    if plant == "linear":
        assert hp[5e-3] < 3.0 * hp[1e-3] and hp[1e-2] < 6.5 * hp[1e-3], hp


def _logging_rates():
    import importlib.util

    from conftest import ROOT

    spec = importlib.util.spec_from_file_location("logging_rates_for_test", ROOT / "benchmarks" / "logging_rates.py")
    rates = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rates)
    return rates


def test_point_samples_of_a_road_that_is_not_held_at_200_and_100_hz():
    """Issue targets on a car simulated at 0.5 ms with the road moving linearly (plant LINEAR) and
    logged at 1, 5 and 10 ms as point samples (benchmarks/logging_rates.py, seed 1, ISO C, 40 km/h),
    the default estimator: the HP road error at 200 / 100 Hz within 1.3x / 1.5x of that at 1 kHz
    (measured 1.12x / 1.21x) and the mass within 0.5 % at each rate (at most 0.06 % measured; +0.94 %
    at 10 ms with the mass regression's filters holding their inputs over the step)."""
    rates = _logging_rates()
    hp, mass = {}, {}
    for h in (1e-3, 5e-3, 1e-2):
        t, meas, zr, told = rates.log("exact", True, 3, SPEED, 24.0, 1, h, 0)
        s = rates.score(t, meas, zr, told, SPEED, h, 0)
        hp[h], mass[h] = s["err_std_hp_pct"], s["mass_pct"]
    assert hp[5e-3] < 1.3 * hp[1e-3] and hp[1e-2] < 1.5 * hp[1e-3], hp
    assert max(abs(m) for m in mass.values()) < 0.5, mass



@pytest.mark.parametrize("seed", [1, 2])
def test_the_air_spring_car_logged_at_100_hz_starts_on_the_road(seed):
    """The air-spring car simulated at 0.5 ms with the road moving linearly, logged at 10 ms as
    point samples (ISO C, 40 km/h). The linear anchor runs away there (its spring's mean force
    error: 0.22 m/s^2, metres in 4 s), and the velocity pull kept the force-error filter on it:
    the start's road and velocity tests, against that filter's decimetre std, saw no
    disagreement, and the profile was 0.22-0.50 m rms off over the first 4 s with a std of
    0.6 mm (coverage 0.23-0.72, seeds 1-3). Compared in the profile's band with the filter run
    without the pull (anchored_road.START_BAND_GATE), the anchor is dropped once the damping is
    identified: 2.1-3.1 mm rms over the first 4 s, 0.8-1.6 mm after, coverage 0.96-1.00."""
    from suspension_estimation.estimators.anchored_road import DROPPED
    from suspension_estimation.harness.metrics import reference_profile

    rates = _logging_rates()
    h = 1e-2
    t, meas, zr, told = rates.log("nonlinear", True, 3, SPEED, 12.0, seed, h, 0)
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s)
    out = np.array([[o["road_height_est"], o["road_height_std"]] for o in (est.step(*z, SPEED, h) for z in meas)])
    err = out[:, 0] - reference_profile(SPEED * t, zr, est.cfg.profile_cutoff)
    assert est.road.mode == DROPPED
    for part in (t <= 4.0, t > 4.0):
        assert np.sqrt(np.mean(err[part] ** 2)) < 10e-3
        assert np.mean(np.abs(err[part]) <= 2 * out[part, 1]) > 0.9


@pytest.mark.parametrize("seed", [1, 2])
def test_logged_at_100_hz_the_road_follows_the_anchor_up_to_30_hz(seed):
    """The car simulated at 0.5 ms with the road moving linearly, logged at 1 and 10 ms as point
    samples (ISO C, 80 km/h), the estimator told the exact vehicle, and c_s +30 % with k_s -15 %.
    At 10 ms the force-error filter, which integrates the body accelerometer's point samples, is
    worse than the anchor over the whole band, so above Tuning.blend_coarse_step the output
    follows the anchor up to blend_coarse_hz. Seed 1 with the 1 Hz blend at every step: exact
    vehicle 4.11 % at 10 ms against 1.68 % at 1 ms (2.4x); vehicle off 16.1 % with 2-sigma
    coverage 0.42. With 30 Hz: 2.18 % (1.3x); 6.5 %, 0.99."""
    rates = _logging_rates()
    v = 80 / 3.6
    hp = {}
    for h in (1e-3, 1e-2):
        t, meas, zr, told = rates.log("exact", True, 3, v, 24.0, seed, h, 0)
        for case, (c, k) in {"exact": (1.0, 1.0), "off": (1.3, 0.85)}.items():
            if h == 1e-3 and case == "off":
                continue
            est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=k * told.k_s, k_t=told.k_t,
                                      c_s=c * told.c_s)
            out = np.array([[o["road_height_est"], o["road_height_std"]] for o in (est.step(*z, v, h) for z in meas)])
            hp[h, case] = road_scores(t, out[:, 0], zr, out[:, 1], warmup=10.0, distance=v * t)
    assert hp[1e-2, "exact"]["err_std_hp_pct"] < 1.6 * hp[1e-3, "exact"]["err_std_hp_pct"], hp
    assert hp[1e-2, "off"]["err_std_hp_pct"] < 10.0, hp
    assert hp[1e-2, "off"]["coverage_2sigma"] > 0.9, hp
