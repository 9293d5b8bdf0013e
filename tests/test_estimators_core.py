"""Plain-core tests of estimators/ and harness/metrics.py (no FMU). Loose, seed-robust bounds.

road_height_est is the road profile (harness.metrics.reference_profile of the true elevation at the
distance travelled, here V t): ``road_scores`` scores it against that profile."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import welch

from suspension_estimation.estimators import EstimatorConfig, SuspensionEstimator, validate
from suspension_estimation.estimators.kalman import LinearKF
from suspension_estimation.estimators.mass import ForgettingRLS, MassEstimator
from suspension_estimation.estimators.model import (DiscreteModel, RoadModel, discretise, noise_intensity, output_matrix,
                              road_intensity, state_matrix)
from suspension_estimation.estimators.road_class import grade_index_from_profile, welch_psd
from suspension_estimation.harness.metrics import road_scores, settling_time
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise, state_matrices
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE, PAPER001_VEHICLE


def simulate(road_class=3, speed=40 / 3.6, T=12.0, h=1e-3, seed=1, vehicle=DEFAULT_VEHICLE, mass=None,
             noise=SensorNoise()):
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    car = QuarterCar(vehicle, noise, noise_seed=100 + seed)
    n = int(round(T / h))
    meas, truth, ms = np.empty((n, 3)), np.empty((n, 5)), np.empty(n)
    for k in range(n):
        m = vehicle.m_s if mass is None else (mass(k * h) if callable(mass) else mass)
        car.step(road.height(speed * k * h), h, m)
        meas[k], truth[k, :4], truth[k, 4], ms[k] = car.measured, car.x, car.road, m
    return np.arange(1, n + 1) * h, meas, truth, ms


def run(meas, speed=40 / 3.6, h=1e-3, **kw):
    est = SuspensionEstimator(**kw)
    keys = ("road_height_est", "road_height_std", "sprung_mass_est", "road_class_est", "status")
    out = {k: np.empty(len(meas)) for k in keys}
    for k, z in enumerate(meas):
        o = est.step(z[0], z[1], z[2], speed, h)
        for key in keys:
            out[key][k] = o[key]
    return est, out


# --- model -----------------------------------------------------------------------------------
@pytest.mark.parametrize("vehicle", [DEFAULT_VEHICLE, PAPER001_VEHICLE])
def test_model_matches_plant_equations(vehicle):
    A = state_matrix(vehicle, 11.0, RoadModel(f_ref=0.0))
    A4, B4 = state_matrices(vehicle)
    np.testing.assert_allclose(A[:4, :4], A4, rtol=1e-14)
    np.testing.assert_allclose(A[:4, 4], B4, rtol=1e-14)
    assert A[1, 0] == pytest.approx(-vehicle.k_s / vehicle.m_s)  # the paper's sign slip, corrected
    # the common-mode reference adds the SAME acceleration to body, wheel and road: the relative
    # dynamics (and hence every output) are those of the plant
    Aref = state_matrix(vehicle, 11.0)
    D = np.array([[1, 0, -1, 0, 0, 0], [0, 1, 0, -1, 0, 0], [0, 0, 1, 0, -1, 0], [0, 0, 0, 1, 0, -1.0]])
    np.testing.assert_allclose(D @ Aref, D @ A, rtol=0, atol=1e-12)
    assert not np.allclose(Aref, A)
    # outputs reproduce the plant's noise-free accelerations and deflection from its true state
    car = QuarterCar(vehicle, SensorNoise(0.0, 0.0, 0.0))
    road = SyntheticRoad(iso8608.class_psd_n0(4), seed=3)
    H = output_matrix(vehicle)
    for k in range(500):
        car.step(road.height(11.0 * k * 1e-3), 1e-3)
        x = np.r_[car.x, car.road, 0.0]
        np.testing.assert_allclose(H @ x, car.measured, atol=1e-9)


def test_exact_discretisation_and_van_loan():
    A = state_matrix(DEFAULT_VEHICLE, 20.0)
    Qc = noise_intensity(iso8608.class_psd_n0(3), 20.0)
    h = 2e-3
    Phi, Qd = discretise(A, Qc, h)
    np.testing.assert_allclose(Phi, expm(A * h), rtol=1e-12, atol=1e-14)
    # Q_d = int_0^h e^{As} Qc e^{A's} ds by a fine midpoint rule
    s = (np.arange(2000) + 0.5) * h / 2000
    ref = sum(expm(A * si) @ Qc @ expm(A * si).T for si in s) * h / 2000
    np.testing.assert_allclose(Qd, ref, rtol=1e-5, atol=1e-18)


def test_road_model_level_follows_iso():
    # low-frequency v_r PSD 2 q / a2^2 equals the ISO road-velocity PSD 4 pi^2 n0^2 Gd V
    for cls, v in ((1, 10.0), (3, 11.1), (5, 30.0)):
        gd = iso8608.class_psd_n0(cls)
        a2 = 2 * np.pi * RoadModel().n_hi * v
        assert 2 * road_intensity(gd, v) / a2 ** 2 == pytest.approx(4 * np.pi ** 2 * iso8608.N0 ** 2 * gd * v)


def test_step_change_rediscretises():
    est = SuspensionEstimator(mass_estimator=0)
    est.step(0.0, 0.0, 0.0, 10.0, 1e-3)
    assert est.model.h == 1e-3
    est.step(0.0, 0.0, 0.0, 10.0, 5e-3)
    assert est.model.h == 5e-3
    np.testing.assert_allclose(est.kf.F, expm(est.model.A * 5e-3), rtol=1e-12, atol=1e-14)


# --- Kalman filter ---------------------------------------------------------------------------
def test_linear_kf_equals_filterpy():
    from filterpy.kalman import KalmanFilter

    m = DiscreteModel.build(DEFAULT_VEHICLE, 11.1, iso8608.class_psd_n0(3), 1e-3)
    R = np.diag([0.02, 0.2, 1e-4]) ** 2
    fp = KalmanFilter(6, 3)
    fp.F, fp.Q, fp.H, fp.R = m.Phi, m.Q, m.H, R
    fp.x = np.zeros(6)
    fp.P = np.eye(6) * 1e-4
    kf = LinearKF(6, 3)
    kf.F, kf.Q, kf.H, kf.R = m.Phi, m.Q, m.H, R
    kf.P = np.eye(6) * 1e-4
    _, meas, _, _ = simulate(T=2.0)
    for z in meas:
        fp.predict()
        fp.update(z)
        kf.predict()
        kf.update(z)
        np.testing.assert_allclose(kf.x, fp.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(kf.P, fp.P, rtol=1e-9, atol=1e-18)


def test_frozen_gain_identical_to_full_filter():
    # an observable, stable system whose Riccati recursion converges: the 4-state quarter car
    A4, B4 = state_matrices(DEFAULT_VEHICLE)
    Phi, Q = discretise(A4, np.outer(B4, B4) * 1e-6, 1e-3)
    H = output_matrix(DEFAULT_VEHICLE)[:, :4]
    R = np.diag([0.02, 0.2, 1e-4]) ** 2
    rng = np.random.default_rng(0)
    full, fast = LinearKF(4, 3), LinearKF(4, 3, freeze_tol=1e-13, freeze_steps=20)
    for f in (full, fast):
        f.F, f.Q, f.H, f.R = Phi, Q, H, R
    for _ in range(20000):
        z = rng.standard_normal(3) * [0.1, 1.0, 1e-3]
        for f in (full, fast):
            f.predict()
            f.update(z)
    assert fast.frozen
    np.testing.assert_allclose(fast.x, full.x, rtol=0, atol=1e-9)


# --- mass --------------------------------------------------------------------------------------
def test_rls_converges_on_exact_regression():
    rng = np.random.default_rng(1)
    theta = np.array([450.0, 1300.0])
    rls = ForgettingRLS(np.array([260.0, 1000.0]), np.eye(2) * 1e6, lam=0.995)
    for _ in range(3000):
        phi = rng.standard_normal(2)
        rls.update(phi, float(phi @ theta))
    np.testing.assert_allclose(rls.theta, theta, rtol=1e-6)


def test_mass_estimator_regressor_independent_of_nominal_mass():
    _, meas, _, _ = simulate(T=4.0, mass=560.0, seed=2)
    for nominal in (250.0, 410.0, 700.0):
        me = MassEstimator(nominal, DEFAULT_VEHICLE.k_s, DEFAULT_VEHICLE.c_s, lam=0.995)
        for z in meas:
            me.update(z[0], z[2], 1e-3)
        assert me.mass == pytest.approx(560.0, rel=0.03)


def test_mass_step_tracked():
    mass = lambda t: 260.0 if t < 1.5 else 450.0  # noqa: E731
    t, meas, _, _ = simulate(T=3.5, vehicle=PAPER001_VEHICLE, mass=mass, seed=3)
    _, out = run(meas, m_s_nominal=260.0, m_u=40.0, k_s=16000.0, c_s=1200.0, road_class=3)
    assert settling_time(t, out["sprung_mass_est"], 450.0, 1.5) < 1.0
    assert abs(np.mean(out["sprung_mass_est"][t > 2.5]) - 450.0) < 0.02 * 450.0


# --- road estimation, end to end -----------------------------------------------------------------
def test_kf_road_estimate_iso_c():
    """ISO C, 40 km/h, 14 s, the default estimator at the true mass, scored after 4 s. Measured
    over seeds 1-8 (the test: 4): HP error 1.6-2.1 %, gain 1.002-1.007, raw error against the
    profile 0.14-0.22 mm rms (profile 13-16 mm rms); road_height_std 0.66 mm with the default
    calibration allowance (2-sigma coverage 1.0), 0.16 mm without it (calibration_gain_std =
    calibration_delay_std = 0: the filter alone on these ideal sensors), coverage 0.87-0.98."""
    t, meas, truth, _ = simulate(T=14.0, seed=4)
    _, out = run(meas, mass_estimator=0, road_class=3)
    sc = road_scores(t, out["road_height_est"], truth[:, 4], out["road_height_std"], warmup=4.0, distance=40 / 3.6 * t)
    assert sc["err_std_hp_pct"] < 3.0, sc
    assert 0.97 < sc["gain_hp"] < 1.03, sc
    assert sc["rmse_raw_mm"] < 0.4, sc
    assert sc["coverage_2sigma"] > 0.95, sc
    _, ideal = run(meas, mass_estimator=0, road_class=3, calibration_gain_std=0.0, calibration_delay_std=0.0)
    np.testing.assert_array_equal(ideal["road_height_est"], out["road_height_est"])  # the std alone changes
    assert np.all(ideal["road_height_std"] < out["road_height_std"])
    cov = road_scores(t, ideal["road_height_est"], truth[:, 4], ideal["road_height_std"], warmup=4.0,
                      distance=40 / 3.6 * t)["coverage_2sigma"]
    assert 0.8 < cov < 1.0, cov


def test_joint_estimation_recovers_wrong_mass():
    """True 590 kg, told 410 kg. Measured over seeds 1-8 (the test: 5): HP error 8.9-11.8 % at
    410 kg, 2.0-2.5 % joint (ratio 0.21-0.26); final mass 587.7-593.1 kg."""
    t, meas, truth, _ = simulate(T=14.0, seed=5, mass=590.0)
    _, kf = run(meas, mass_estimator=0, road_class=3)
    _, joint = run(meas, road_class=3)
    e_kf = road_scores(t, kf["road_height_est"], truth[:, 4], warmup=4.0, distance=40 / 3.6 * t)["err_std_hp_pct"]
    e_joint = road_scores(t, joint["road_height_est"], truth[:, 4], warmup=4.0, distance=40 / 3.6 * t)["err_std_hp_pct"]
    assert e_joint < 0.5 * e_kf
    assert joint["sprung_mass_est"][-1] == pytest.approx(590.0, rel=0.03)


def test_mme_kf_runs_and_stays_finite():
    """MME&KF, 6 s scored after 2 s: HP error 11.9-13.5 %, gain 0.96-0.99 over seeds 1-8 (the
    test: 6)."""
    t, meas, truth, _ = simulate(T=6.0, seed=6)
    _, out = run(meas, road_estimator=1, mass_estimator=0, road_class=3)
    assert np.all(np.isfinite(out["road_height_est"]))
    sc = road_scores(t, out["road_height_est"], truth[:, 4], warmup=2.0, distance=40 / 3.6 * t)
    assert sc["err_std_hp_pct"] < 20.0 and 0.9 < sc["gain_hp"] < 1.1, sc


# --- ISO class ---------------------------------------------------------------------------------
def test_welch_psd_equals_scipy():
    q = np.random.default_rng(2).standard_normal(2048).cumsum() * 1e-3
    n, P = welch_psd(q, 0.1, 256)
    n2, P2 = welch(q, fs=10.0, window="hann", nperseg=256, noverlap=128, detrend="linear")
    np.testing.assert_allclose(n, n2)
    np.testing.assert_allclose(P, P2, rtol=1e-10)


@pytest.mark.parametrize("cls", [1, 2, 3, 4, 5, 6])
def test_class_from_true_iso_road(cls):
    for seed in (1, 2):
        road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
        q = np.array([road.height(s) for s in np.arange(1024) * 0.1 + 37.0])
        d = grade_index_from_profile(q, 0.1)
        assert abs(d - iso8608.grade_index(iso8608.class_psd_n0(cls))) < 0.5
        assert iso8608.class_from_grade_index(d) == cls


def test_online_class_from_estimated_road():
    t, meas, truth, _ = simulate(road_class=2, speed=20.0, T=12.0, seed=7)
    _, out = run(meas, speed=20.0, mass_estimator=0)
    c = out["road_class_est"]
    assert c[0] == 0  # nothing seen yet
    seen = c > 0
    assert seen.any()
    assert np.mean(c[seen] == 2) > 0.9


# --- validation and bad input ------------------------------------------------------------------
@pytest.mark.parametrize("name,value,needle", [
    ("forgetting_factor", 0.9, "forgetting_factor = 0.9 is outside the allowed range (0.9, 1]"),
    ("forgetting_factor", 1.01, "forgetting_factor"),
    ("m_u", -1.0, "m_u = -1.0 is outside the allowed range [1, 5000]"),
    ("k_s", 0.0, "k_s"),
    ("road_estimator", 99, "road_estimator = 99 is outside the allowed values {0 = Kalman filter"),
    ("mass_estimator", -1, "mass_estimator"),
    ("road_class", 9, "road_class = 9 is outside the allowed range [0, 8]"),
    ("defl_noise_std", 0.0, "defl_noise_std"),
    ("acc_sampling", 2, "acc_sampling = 2 is outside the allowed range [0, 1]"),
])
def test_validation_messages(name, value, needle):
    cfg = EstimatorConfig(**{name: value})
    msgs = validate(cfg)
    assert any(needle in m for m in msgs), msgs
    with pytest.raises(ValueError, match=name):
        SuspensionEstimator(cfg)
    assert validate(EstimatorConfig()) == []


def test_non_finite_measurement_rejected_and_outputs_finite():
    _, meas, _, _ = simulate(T=1.0)
    est = SuspensionEstimator(road_class=3)
    for k, z in enumerate(meas):
        if k in (300, 301, 302):
            z = [math.nan, z[1], math.inf]
        out = est.step(z[0], z[1], z[2], 11.1, 1e-3)
        if k in (300, 301, 302):
            assert out["status"] == 1
        assert all(math.isfinite(v) for v in out.values())
    assert out["status"] == 0


def test_outlier_rejected():
    _, meas, _, _ = simulate(T=1.0)
    est = SuspensionEstimator(road_class=3, mass_estimator=0)
    for z in meas[:500]:
        est.step(*z, 11.1, 1e-3)
    out = est.step(meas[500, 0] + 1e3, meas[500, 1], meas[500, 2], 11.1, 1e-3)
    assert out["status"] == 1
    assert abs(out["road_height_est"]) < 0.1


# --- robustness: bursts, frozen sensors, changing step ----------------------------------------------
_CACHE: dict = {}


@pytest.mark.parametrize("channel,bad", [(0, math.nan), (1, math.inf), (0, 981.0), (1, math.nan)])
def test_burst_on_an_acceleration_predicted_through(channel, bad):
    # 50 ms of NaN / Inf / +100 g on one acceleration: status 1 throughout, outputs finite, no
    # re-initialisation, and 1 s later the road estimate differs from the undisturbed run by no
    # more than an offset + drift (the unobservable common mode), i.e. nothing in band.
    if "burst" not in _CACHE:
        t, meas, truth, _ = simulate(T=6.0, seed=8)
        _CACHE["burst"] = (t, meas, truth, run(meas, road_class=3)[1])
    t, meas, truth, clean = _CACHE["burst"]
    m = meas.copy()
    k0, k1 = 3000, 3050
    m[k0:k1, channel] = bad if bad != 981.0 else m[k0:k1, channel] + bad
    _, out = run(m, road_class=3)
    assert np.all(out["status"][k0:k1] == 1)
    assert np.all(out["status"][k1 + 10:] == 0)
    for key in out:
        assert np.all(np.isfinite(out[key]))
    s = (t >= t[k1] + 1.0) & (t < t[k1] + 3.0)
    d = out["road_height_est"][s] - clean["road_height_est"][s]
    resid = d - np.polyval(np.polyfit(t[s], d, 1), t[s])
    hp_truth = np.std(road_scores.__globals__["highpass"](truth[:, 4], 1e-3)[t > 2.0])
    assert np.std(resid) < 0.01 * hp_truth
    assert abs(out["sprung_mass_est"][-1] - clean["sprung_mass_est"][-1]) < 0.01 * 410.0


def test_frozen_sensor_flagged():
    _, meas, _, _ = simulate(T=3.0, seed=9)
    m = meas.copy()
    m[1500:, 0] = m[1500, 0]  # body accelerometer stuck
    _, out = run(m, road_class=3, mass_estimator=0)
    assert np.all(out["status"][:1500] == 0)
    assert np.all(out["status"][1600:] == 1)  # flagged after frozen_time (50 ms)
    assert np.all(np.isfinite(out["road_height_est"]))


def test_changing_step_size_rediscretises_accurately():
    """Plant and estimator at 1 ms, then 5 ms, then 2 ms: HP road error within 30 % of the
    fixed-1-ms run over the same stretch of road (the 5 ms part is sampled more coarsely, so
    both are scored on the 10 ms grid common to all segments). Measured over road seeds 1-5 and
    10 (the test: 10): 1.71-2.01 % fixed, ratio 1.00-1.17 (1.05 on seed 10)."""
    speed, T = 40 / 3.6, 12.0
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=10)

    def drive(steps):
        car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=110)
        est = SuspensionEstimator(road_class=3, mass_estimator=0)
        t, ts, zs, rs = 0.0, [], [], []
        for h in steps:
            r = road.height(speed * t)
            car.step(r, h)
            t += h
            o = est.step(*car.measured, speed, h)
            ts.append(t), zs.append(o["road_height_est"]), rs.append(r)
        ts, zs, rs = map(np.array, (ts, zs, rs))
        grid = np.arange(0.01, ts[-1] - 1e-9, 0.01)
        idx = np.searchsorted(ts, grid - 1e-9)
        return grid, zs[idx], rs[idx]

    fixed = [1e-3] * int(T / 1e-3)
    varying = [1e-3] * 4000 + [5e-3] * 800 + [2e-3] * 2000
    g1, z1, r1 = drive(fixed)
    g2, z2, r2 = drive(varying)
    e1 = road_scores(g1, z1, r1, warmup=3.0, distance=speed * g1)["err_std_hp_pct"]
    e2 = road_scores(g2, z2, r2, warmup=3.0, distance=speed * g2)["err_std_hp_pct"]
    assert e2 < 1.3 * e1, (e1, e2)


# --- steady state (the filter must be good AFTER its covariance has settled) -------------------
def test_steady_state_filter_keeps_the_band_and_is_honest():
    # the frozen (DARE) gain, analysed in frequency against the exact plant on an ISO C road at
    # 40 km/h: in-band estimate/truth transfer ~1 (no shrinkage), HP error small, and the
    # filter's own sqrt(P[z_r, z_r]) close to the true raw error (honest road_height_std)
    from suspension_estimation.estimators.steady_state import analyse, steady_gain
    from suspension_estimation.estimators.model import measurement_covariance

    h, V = 1e-3, 40 / 3.6
    R = measurement_covariance(0.02, 0.2, 1e-4)
    m = DiscreteModel.build(DEFAULT_VEHICLE, V, iso8608.class_psd_n0(6), h)
    K, P = steady_gain(m, R)
    f = np.array([0.2, 0.3, 0.5, 1.0, 3.0, 10.0])
    a = analyse(m.Phi, m.H, K, R, h, iso8608.class_psd_n0(3), V)
    T = np.interp(f, a["f"], np.abs(a["T"]))
    assert np.all(np.abs(T - 1) < 0.05), T
    assert a["hp_pct"] < 5.0 and 0.97 < a["gain_hp"] < 1.03
    assert 0.8 < math.sqrt(P[4, 4] / a["err_var_raw"]) < 1.5
    # the old design (no common-mode reference) shrinks the band at steady state
    old = DiscreteModel.build(DEFAULT_VEHICLE, V, iso8608.class_psd_n0(3), h, RoadModel(n_lo=0.011, f_ref=0.0))
    K0, _ = steady_gain(old, R)
    assert analyse(old.Phi, old.H, K0, R, h, iso8608.class_psd_n0(3), V)["gain_hp"] < 0.92



@pytest.mark.parametrize("acc_sampling", [0, 1])
def test_raw_error_variance_is_the_spectral_error(acc_sampling):
    """raw_error_variance (Lyapunov sensor part + vectorised road integral; the estimator no
    longer reports it: road_height_std is the error in the profile's band) equals analyse's
    error spectrum integrated down to 1e-5 Hz (an independent loop over 20000 frequencies)
    within 1 %, for point-sampled and averaged accelerations; it grows
    with the road class and stays below the filter's own P[z_r, z_r], which also carries the
    model noise."""
    from suspension_estimation.estimators.kalman import stationary_covariance
    from suspension_estimation.estimators.model import measurement_covariance
    from suspension_estimation.estimators.steady_state import analyse, raw_error_variance

    h, V = 1e-3, 40 / 3.6
    R = measurement_covariance(0.02, 0.2, 1e-4)
    m = DiscreteModel.build(DEFAULT_VEHICLE, V, iso8608.class_psd_n0(6), h, acc_sampling=acc_sampling,
                            road_hold=acc_sampling == 1)
    Pp, P = stationary_covariance(m.Phi, m.Q, m.H, R)
    K = Pp @ m.H.T @ np.linalg.inv(m.H @ Pp @ m.H.T + R)
    f = np.geomspace(1e-5, 0.999 / (2 * h), 20000)
    got = []
    for c in (2, 3, 4):
        v = raw_error_variance(m.Phi, m.H, K, R, h, iso8608.class_psd_n0(c), V, acc_sampling=acc_sampling)
        ref = analyse(m.Phi, m.H, K, R, h, iso8608.class_psd_n0(c), V, f=f, acc_sampling=acc_sampling)
        assert v == pytest.approx(ref["err_var_raw"], rel=0.01), c
        got.append(v)
    assert got[0] < got[1] < got[2] < P[4, 4]


def test_covariance_converges_and_stays_spd_over_a_long_run():
    # 20 min at 10 ms (50x the common-mode reference's time constant; at 1 ms this would be
    # slow): P converges to the DARE solution and stays symmetric PD (the old design's common-
    # mode covariance grew for many minutes and never settled)
    from suspension_estimation.estimators.steady_state import steady_gain

    h = 1e-2
    m = DiscreteModel.build(DEFAULT_VEHICLE, 20.0, iso8608.class_psd_n0(6), h)
    R = np.diag([0.02, 0.2, 1e-4]) ** 2
    kf = LinearKF(6, 3)
    kf.F, kf.Q, kf.H, kf.R = m.Phi, m.Q, m.H, R
    kf.P = np.diag([1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-1]) ** 2
    z = np.zeros(3)
    for _ in range(int(1200 / h)):
        kf.predict()
        kf.update(z)
    _, Pss = steady_gain(m, R)
    np.testing.assert_allclose(kf.P, kf.P.T, rtol=0, atol=1e-14 * np.abs(kf.P).max())
    assert np.linalg.eigvalsh(kf.P).min() > 0
    np.testing.assert_allclose(np.diag(kf.P), np.diag(Pss), rtol=1e-3)


# --- wrong starting mass: re-filtering after the mass rebuild --------------------------------------
def test_wrong_start_mass_refiltered_raw_error_and_coverage():
    """True 590 kg, model starts at 410: the ~0.3 s before the first mass rebuild push the
    unobservable common mode off, and what the profile keeps of that is a raw error of 1.7-4.5 mm
    rms (2-sigma coverage 0.53-0.65) without re-filtering; the re-filter from the start with the
    new model removes it: 0.19-0.61 mm (the true-mass KF 0.19-0.24 mm), coverage 0.92-1.0, HP
    error within 3 % of the true-mass KF's. Measured over seeds 1-8 (the test: 5, 0.20 / 2.9 /
    0.20 mm). (The exact-model KF: the force-error state of road_estimator 2 absorbs the wrong
    mass's force mismatch, so without re-filtering it is barely pushed off.)"""
    t, meas, truth, _ = simulate(T=14.0, seed=5, mass=590.0)
    est, joint = run(meas, road_class=3, road_estimator=0)
    _, old = run(meas, road_class=3, refilter_span=0.0, road_estimator=0)
    _, true_kf = run(meas, road_class=3, mass_estimator=0, m_s_nominal=590.0, road_estimator=0)
    sc = {k: road_scores(t, o["road_height_est"], truth[:, 4], o["road_height_std"], warmup=4.0, distance=40 / 3.6 * t)
          for k, o in (("joint", joint), ("old", old), ("true", true_kf))}
    assert est.refilters >= 1
    assert sc["joint"]["rmse_raw_mm"] < 2.0 * sc["true"]["rmse_raw_mm"] + 0.5, sc
    assert sc["old"]["rmse_raw_mm"] > 2.0 * sc["joint"]["rmse_raw_mm"], sc
    assert sc["joint"]["coverage_2sigma"] > 0.85 > sc["old"]["coverage_2sigma"], sc
    assert sc["joint"]["err_std_hp_pct"] < 1.1 * sc["true"]["err_std_hp_pct"], sc


# --- averaged accelerations (acc_sampling = 1) ------------------------------------------------------
@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_averaged_measurement_model_matches_plant_exactly(h):
    from suspension_estimation.estimators.model import IVS_PREV, IVU_PREV
    from suspension_estimation.plant.quarter_car import discretise as plant_discretise

    for hold in (False, True):
        m = DiscreteModel.build(DEFAULT_VEHICLE, 11.0, iso8608.class_psd_n0(6), h, RoadModel(f_ref=0.0),
                                acc_sampling=1, road_hold=hold)
        car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(0.0, 0.0, 0.0), acc_sampling=1)
        road = SyntheticRoad(iso8608.class_psd_n0(4), seed=3)
        Ad, Bd = plant_discretise(*state_matrices(DEFAULT_VEHICLE), h)
        prev, xlast = np.zeros(4), np.zeros(2)
        for k in range(300):
            car.step(road.height(11.0 * k * h), h)
            x = np.r_[car.x, car.road, 0.0, prev[1], prev[3]]
            np.testing.assert_allclose(m.H @ x, car.measured, rtol=0, atol=1e-9)
            if hold and k:  # the held-road dynamics reproduce the plant's vehicle step exactly
                xp = m.Phi @ np.r_[prev, xlast, 0.0, 0.0]
                np.testing.assert_allclose(xp[:4], Ad @ prev + Bd * xp[4], rtol=0, atol=1e-12)
            prev, xlast = car.x.copy(), np.array([car.road, 0.0])
        assert m.Phi[IVS_PREV, 1] == 1.0 and m.Phi[IVU_PREV, 3] == 1.0


def test_averaged_sensor_at_10ms_matched_beats_point_model():
    """Accelerations averaged over 10 ms steps, 40 s scored after 10 s: the matched model
    (acc_sampling 1) against the point-sample one. Measured over road seeds 1-5 and 11 (the test:
    11): HP error 1.8-2.2 % matched, 9.6-10.9 % point (ratio 0.17-0.21)."""
    speed, h, T = 40 / 3.6, 1e-2, 40.0
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=11)
    car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=111, acc_sampling=1)
    n = int(T / h)
    meas, r = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        car.step(road.height(speed * k * h), h)
        meas[k], r[k] = car.measured, car.road
    t = np.arange(1, n + 1) * h
    hp = {}
    for acc in (0, 1):
        _, out = run(meas, speed=speed, h=h, road_class=3, mass_estimator=0, acc_sampling=acc)
        assert np.all(np.isfinite(out["road_height_est"]))
        hp[acc] = road_scores(t, out["road_height_est"], r, warmup=10.0, distance=speed * t)["err_std_hp_pct"]
    assert hp[1] < 0.4 * hp[0], hp
    assert hp[1] < 3.5, hp
