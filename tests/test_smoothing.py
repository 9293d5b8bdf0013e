"""harness.smoothing: the RTS smoother against filterpy's and against the exact fixed-interval
posterior (a joint Gaussian conditioned on the whole record)."""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.harness.smoothing import FilterRecord, rts_smooth
from suspension_estimation.harness.studies.vb import paper_model


def _data(K, seed, q=0.05, r=(0.01, 1e-4, 1e-3)):
    F, B, H = paper_model()
    rng = np.random.default_rng(seed)
    Q = q * np.outer(B, B)
    R = np.diag(r)
    x = np.zeros(4)
    Y = np.empty((K, 3))
    for k in range(K):
        if k:
            x = F @ x + B * rng.normal(0.0, np.sqrt(q))
        Y[k] = H @ x + rng.standard_normal(3) * np.sqrt(r)
    return F, Q, H, R, Y


def _filterpy_run(F, Q, H, R, Y, P0):
    from filterpy.kalman import KalmanFilter

    kf = KalmanFilter(4, 3)
    kf.F, kf.Q, kf.H, kf.R = F, Q, H, R
    kf.x, kf.P = np.zeros(4), P0.copy()
    kf.update(Y[0])
    xs, Ps = [kf.x.copy()], [kf.P.copy()]
    for z in Y[1:]:
        kf.predict()
        kf.update(z)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    return np.array(xs), np.array(Ps), kf


@pytest.mark.parametrize("per_step_q", [False, True])
def test_equals_filterpy_rts(per_step_q):
    F, Q, H, R, Y = _data(400, seed=1)
    x, P, kf = _filterpy_run(F, Q, H, R, Y, np.diag([1e-4, 1e-5, 1e-2, 1e-2]))
    Qs = np.array([Q * (1 + 0.5 * np.sin(k / 20)) for k in range(len(Y))]) if per_step_q else Q
    # Qs[k]: the transition into step k, filterpy's convention and FilterRecord's
    xf, Pf, _, _ = kf.rts_smoother(x, P, Fs=[F] * len(Y), Qs=list(Qs) if per_step_q else [Q] * len(Y))
    xs, Ps = rts_smooth(FilterRecord(x, P, F, Qs))
    np.testing.assert_allclose(xs, xf, rtol=0, atol=1e-9 * np.max(np.abs(xf)))
    np.testing.assert_allclose(Ps, Pf, rtol=0, atol=1e-9 * np.max(np.abs(Pf)))
    # it smooths: the covariance shrinks (not a copy of the filter)
    assert np.trace(Ps[200]) < 0.9 * np.trace(P[200])


def test_exact_fixed_interval_posterior_from_a_known_start():
    """x_0 = 0 known (P_0 = 0, the singular start of paper 004): the smoothed means equal
    E[x_1..K | y_0..K] of the joint Gaussian, solved directly."""
    K = 25
    F, Q, H, R, Y = _data(K, seed=2)
    x, P, _ = _filterpy_run(F, Q, H, R, Y, np.zeros((4, 4)))
    xs, Ps = rts_smooth(FilterRecord(x, P, F, Q))
    # x_k = sum_j F^(k-j) w_j: the joint prior covariance of the stacked states
    n = 4
    Phi = [np.linalg.matrix_power(F, i) for i in range(K)]
    C = np.zeros((K * n, K * n))
    for a in range(K):
        for b in range(K):
            C[a * n:(a + 1) * n, b * n:(b + 1) * n] = sum(
                Phi[a - j] @ Q @ Phi[b - j].T for j in range(1, min(a, b) + 1))
    Hb = np.kron(np.eye(K), H)
    S = Hb @ C @ Hb.T + np.kron(np.eye(K), R)
    mean = (C @ Hb.T @ np.linalg.solve(S, Y.reshape(-1))).reshape(K, n)
    cov = C - C @ Hb.T @ np.linalg.solve(S, Hb @ C)
    np.testing.assert_allclose(xs, mean, rtol=0, atol=1e-8 * np.max(np.abs(mean)))
    for k in range(K):
        np.testing.assert_allclose(Ps[k], cov[k * n:(k + 1) * n, k * n:(k + 1) * n],
                                   rtol=0, atol=1e-8 * np.max(np.abs(cov)))


def test_stack_of_runs_with_a_shared_covariance():
    F, Q, H, R, Y1 = _data(200, seed=3)
    Y2 = _data(200, seed=4)[4]
    P0 = np.eye(4) * 1e-3
    x1, P, _ = _filterpy_run(F, Q, H, R, Y1, P0)
    x2, _, _ = _filterpy_run(F, Q, H, R, Y2, P0)
    xs, Ps = rts_smooth(FilterRecord(np.stack([x1, x2]), P, F, Q))
    for i, x in enumerate((x1, x2)):
        np.testing.assert_allclose(xs[i], rts_smooth(FilterRecord(x, P, F, Q))[0], rtol=0, atol=1e-15)


def test_bad_record_is_refused():
    F, Q, _, _, _ = _data(3, seed=1)
    with pytest.raises(ValueError, match="P has shape"):
        FilterRecord(np.zeros((10, 4)), np.zeros((9, 4, 4)), F, Q)
    with pytest.raises(ValueError, match="Q has shape"):
        FilterRecord(np.zeros((10, 4)), np.zeros((10, 4, 4)), F, np.zeros((3, 3)))


def test_smoothing_fmu_outputs_is_the_kalman_filters_own_rts_smoother():
    """A KF run (road_estimator 0, stationary gain) smoothed from its outputs alone equals
    filterpy's rts_smoother fed the filter's own states, covariances and model, on the six states
    (the road: z_u_est - tire_deflection_est); and its road_height_est is that smoothed road made a
    profile exactly as the estimator makes its own from the filter's road (``profile_of``: the
    causal road_height_est from the causal states, to rounding)."""
    from filterpy.kalman import rts_smoother

    from suspension_estimation.estimators.model import IZR
    from suspension_estimation.estimators.suspension import SuspensionEstimator
    from suspension_estimation.harness.smoothing import FMU_STATES, profile_of, smooth_fmu_outputs
    from suspension_estimation.harness.studies.vb import loosening_measurements

    params = {"road_estimator": 0, "mass_estimator": 0, "road_class": 3, "k_s": 22000.0}
    v, h = 40 / 3.6, 1e-3
    meas, _ = loosening_measurements(4, T=1.5, factor=1.0)
    est = SuspensionEstimator(**params)
    outs, xs, Ps, causal = [], [], [], []
    for a, u, d in meas:
        o = est.step(a, u, d, v, h)
        # z_s_est and z_u_est carry the correction of the filter's lag behind its reference (a
        # common shift, steady_state.reference_lag): taken off, the outputs are the filter's own
        # states (tire_deflection_est, a difference, does not carry it)
        row = [o[k] - (est.road.z_shift if k in ("z_s_est", "z_u_est") else 0.0) for k in FMU_STATES]
        outs.append(row)
        xs.append(est.kf.x.copy())
        Ps.append(est.kf.P.copy())
        causal.append(o["road_height_est"])
    outs, xs, causal = np.array(outs), np.array(xs), np.array(causal)
    states = outs.copy()
    states[:, 4] = outs[:, 2] - outs[:, 4]  # the filter's road
    np.testing.assert_allclose(states, xs, rtol=0, atol=1e-15)
    rm = est.cfg.tuning.road_model
    prof = dict(cutoff=est.cfg.profile_cutoff, standstill=est.cfg.tuning.standstill_speed,
                reference=(rm.f_ref, rm.zeta_ref))
    K = len(xs)
    np.testing.assert_allclose(profile_of(xs[:, IZR], np.full(K, v), h, **prof), causal,
                               rtol=0, atol=1e-12 * np.max(np.abs(causal)))
    mine = smooth_fmu_outputs({k: outs[:, i] for i, k in enumerate(FMU_STATES)}, params, v, h)
    ref, *_ = rts_smoother(xs, np.array(Ps), [est.model.Phi] * K, [est.model.Q] * K)
    # the prior P_k+1|k of this model has a condition number ~1e10 (the 0.01 Hz common mode): its
    # pseudo-inverse (here) and inverse (filterpy) agree to ~1e-7, the smoothed states to ~1e-5
    got = {k: mine[k] for k in ("z_s_est", "v_s_est", "z_u_est", "v_u_est", "road_velocity_est")}
    got["road"] = mine["z_u_est"] - mine["tire_deflection_est"]
    for i, k in enumerate(("z_s_est", "v_s_est", "z_u_est", "v_u_est", "road", "road_velocity_est")):
        tol = 1e-4 * np.max(np.abs(ref[:, i]))
        np.testing.assert_allclose(got[k], ref[:, i], rtol=0, atol=tol, err_msg=k)
        if k in ("z_u_est", "road"):
            assert np.max(np.abs(got[k] - xs[:, i])) > 30 * tol, k  # the smoother did move them
    np.testing.assert_allclose(mine["susp_deflection_est"], mine["z_s_est"] - mine["z_u_est"], rtol=0, atol=1e-15)
    # the smoothed profile: the profile of filterpy's smoothed road, and not the causal one
    smoothed = profile_of(ref[:, IZR], np.full(K, v), h, **prof)
    tol = 1e-4 * np.max(np.abs(smoothed))
    np.testing.assert_allclose(mine["road_height_est"], smoothed, rtol=0, atol=tol)
    assert np.max(np.abs(mine["road_height_est"] - causal)) > 30 * tol


# --------------------------------------------------------------------------------------------------
# the default estimator, smoothed (smooth_default)
# --------------------------------------------------------------------------------------------------
def _drive(nonlinear: bool, cls: int, speed, duration: float, seed: int, h: float = 1e-3):
    """(t, measurements (K, 3), true road, the vehicle the estimator is told, speeds (K,), the road
    the car stood on at t = 0): the nominal quarter car or the air-spring plant (told its
    linearisation) on an ISO road, at rest at t = 0 (benchmarks/robust_cores.py's drive, with a
    speed per step)."""
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    if nonlinear:
        car = NonlinearQuarterCar(DEFAULT_VEHICLE, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, noise=SensorNoise(),
                                  noise_seed=1000 + seed)
        told = car.linearisation()
    else:
        car, told = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=1000 + seed), DEFAULT_VEHICLE
    z0 = road.height(0.0)
    car.settle(z0)
    n = int(round(duration / h))
    v = np.broadcast_to(np.asarray(speed, float), (n,))
    s = np.cumsum(v) * h
    meas, zr = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        car.step(road.height(s[k]), h)
        meas[k], zr[k] = car.measured, car.road
    params = {"m_s_nominal": told.m_s, "m_u": told.m_u, "k_s": told.k_s, "k_t": told.k_t, "c_s": told.c_s}
    return np.arange(1, n + 1) * h, meas, zr, params, np.array(v), z0


def _tracked_road(t, z):
    """What the filters' road tracks (m): the true road z (m) at times t (s), the car at rest on
    z[0] at t[0], through the common-mode reference's high-pass s^2 / (s^2 + 2 zeta w s + w^2)
    from rest (estimators.model.RoadModel; scipy.signal.lsim, exact for a road linear between
    samples): the road the smoothed heights are referred to (smoothing.reference_correction)."""
    from scipy.signal import lsim

    from suspension_estimation.estimators.model import RoadModel

    rm = RoadModel()
    w = 2 * np.pi * rm.f_ref
    _, y, _ = lsim(([1.0, 0.0, 0.0], [1.0, 2 * rm.zeta_ref * w, w * w]), z - z[0], t - t[0])
    return np.asarray(y, float)


def _scores(t, out, zr, v, z0):
    """Road scores of the causal and the smoothed default (``metrics.road_scores``: both profiles
    against ``reference_profile`` of the true road at the distance travelled, the sum of v h);
    with, after 10 s, the smoothed std's rms over the rms error of the profile (``std_over_err``)
    and over that of the smoothed road before the profile's high-pass (z_u_est -
    tire_deflection_est, against ``_tracked_road``: ``std_over_raw_err``), the error it is the std
    of."""
    from suspension_estimation.harness.metrics import reference_profile, road_scores

    h = float(t[1] - t[0])
    d = np.cumsum(v) * h
    c = road_scores(t, out["causal_road_height_est"], zr, out["causal_road_height_std"], distance=d)
    s = road_scores(t, out["road_height_est"], zr, out["road_height_std"], distance=d)
    late = t >= 10.0
    ms = np.mean(out["road_height_std"][late] ** 2)
    err = out["road_height_est"][late] - reference_profile(d, zr)[late]
    s["std_over_err"] = float(np.sqrt(ms / np.mean(err ** 2)))
    raw = out["z_u_est"] - out["tire_deflection_est"] - _tracked_road(np.r_[0.0, t], np.r_[z0, zr])[1:]
    s["std_over_raw_err"] = float(np.sqrt(ms / np.mean(raw[late] ** 2)))
    return c, s


@pytest.mark.parametrize("nonlinear", [False, True], ids=["exact vehicle", "air-spring plant"])
def test_the_smoothed_default_beats_the_causal_one_in_band(nonlinear):
    """30 s of ISO C at 40 km/h, both as profiles against reference_profile: the smoothed HP error
    at most half the causal default's (seeds 1-6: 0.25-0.30 of it on the exact vehicle, 0.34-0.37
    on the air-spring plant), its raw error below the causal one's on the exact vehicle (0.51-0.68
    of it) and about it on the air-spring plant (0.90-0.96). Its std is that of the smoothed road
    before the profile's high-pass (z_u_est - tire_deflection_est): honest for that road, the rms
    std 0.6 times its rms error or more (0.76-2.16 exact, 0.91-5.3 air spring), and on the exact
    vehicle at most 2.5 times (the build-up from rest makes it conservative over 10-30 s, as the
    causal one is; on the air-spring plant it is the force-error filter's fixed point times 1.2,
    as the causal one, whatever the run's luck); and so an upper bound of the profile's error (rms
    std over rms error 31-46 exact, 56-82 air spring; 2-sigma coverage 1.000)."""
    from suspension_estimation.harness.smoothing import smooth_default

    t, meas, zr, params, v, z0 = _drive(nonlinear, 3, 40 / 3.6, 30.0, seed=2)
    out = smooth_default(meas[:, 0], meas[:, 1], meas[:, 2], v, params, 1e-3)
    assert out["anchor"][0] == (0.0 if nonlinear else 1.0)  # the air spring drops the anchor, as the causal
    c, s = _scores(t, out, zr, v, z0)
    assert s["err_std_hp_pct"] <= 0.5 * c["err_std_hp_pct"], (s["err_std_hp_pct"], c["err_std_hp_pct"])
    assert s["rmse_raw_mm"] <= (1.15 if nonlinear else 0.85) * c["rmse_raw_mm"], (s["rmse_raw_mm"], c["rmse_raw_mm"])
    assert 0.6 <= s["std_over_raw_err"] <= (np.inf if nonlinear else 2.5), s["std_over_raw_err"]
    assert s["std_over_err"] >= 1.0 and s["coverage_2sigma"] >= 0.95, s


def test_stop_and_go_with_a_burst_of_nan():
    """Speed 0 -> 15 -> 3 m/s (the model follows it) and 50 ms of NaN on the body accelerometer
    (predict-only steps there): every output finite, the HP error of the profile at most 0.4 of
    the causal one's (0.07-0.21 on seeds 1-6)."""
    from suspension_estimation.harness.smoothing import smooth_default

    n = 16000
    v = np.interp(np.arange(n), [0, 6000, 12000, n - 1], [0.0, 15.0, 15.0, 3.0])
    t, meas, zr, params, v, z0 = _drive(False, 4, v, n * 1e-3, seed=3)
    meas[11000:11050, 0] = np.nan
    out = smooth_default(meas[:, 0], meas[:, 1], meas[:, 2], v, params, 1e-3)
    for k in ("road_height_est", "road_height_std", "z_s_est", "v_u_est"):
        assert np.all(np.isfinite(out[k])), k
    c, s = _scores(t, out, zr, v, z0)
    assert s["err_std_hp_pct"] <= 0.4 * c["err_std_hp_pct"], (s["err_std_hp_pct"], c["err_std_hp_pct"])


def test_the_default_passes_are_the_rts_smoother_of_their_record():
    """``_rts_pass`` over a ``_kalman_pass`` (two speeds, so F and Q change mid-run; a NaN stretch:
    predict-only steps for that channel; chunks of 700 steps) equals ``rts_smooth`` of the record it makes (x_k|k, P_k|k, F_k,
    Q_k), which equals filterpy's (above); and smoothing never raises the road's variance."""
    from suspension_estimation.estimators.model import IZR, DiscreteModel, measurement_covariance
    from suspension_estimation.estimators.model import ModelNoise
    from suspension_estimation.harness.smoothing import _fixed, _kalman_pass, _live, _rts_pass
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    t, meas, zr, params, v, _ = _drive(False, 3, np.r_[np.full(1500, 11.0), np.full(1500, 12.0)], 3.0, seed=4)
    meas[1000:1100, 1] = np.nan
    R = measurement_covariance(0.02, 0.2, 1e-4)
    noise = ModelNoise(q_f=900.0, q_b=1000.0, tau_b=10.0)
    models = [_fixed(DiscreteModel.build(DEFAULT_VEHICLE, s, iso8608.class_psd_n0(6), 1e-3, noise=noise), R)
              for s in (11.0, 12.0)]
    index = (v > 11.5).astype(int)
    xs, xp, Ps = _kalman_pass(models, index, meas, _live(meas, 1e-3, 0.05), 1e4)
    x_mine, var_mine = _rts_pass(models, index, xs, xp, Ps, (IZR,), chunk=700)
    F = np.stack([m.F for m in models])[index]
    Q = np.stack([m.Q for m in models])[index]
    P = np.stack(Ps)
    x_ref, P_ref = rts_smooth(FilterRecord(xs, P, F, Q))
    np.testing.assert_allclose(x_mine, x_ref, rtol=0, atol=1e-9 * np.max(np.abs(x_ref)))
    np.testing.assert_allclose(var_mine[:, 0], P_ref[:, IZR, IZR], rtol=1e-9, atol=0)
    assert np.all(var_mine[:, 0] <= P[:, IZR, IZR] * (1 + 1e-9))
    assert np.max(np.abs(x_mine - xs)) > 1e-3 * np.max(np.abs(xs))  # it smoothed


def test_the_reference_correction_refers_the_model_truth_to_the_road():
    """The model's common-mode reference follows the body, c = LP(z_s): what the filters estimate is
    z_r - LP(z_s). Plus reference_correction(z_s, z_r) it is the road's own high-pass z_r - LP(z_r)
    (``_tracked_road``; true states of the linear plant, ISO C at 40 km/h, 20 s): left over 15 % of
    the gap, and 10 % of it in band (the correction's 0.03 Hz high-pass; 9 % and 5 % measured)."""
    from scipy.signal import lsim

    from suspension_estimation.estimators.model import RoadModel
    from suspension_estimation.harness.metrics import highpass
    from suspension_estimation.harness.smoothing import reference_correction
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    h, n, rm = 1e-3, 20000, RoadModel()
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=6)
    car = QuarterCar(DEFAULT_VEHICLE, SensorNoise())
    z0 = road.height(0.0)
    car.settle(z0)
    zs, zr = np.empty(n), np.empty(n)
    for k in range(n):
        car.step(road.height(40 / 3.6 * (k + 1) * h), h)
        zs[k], zr[k] = car.x[0] - z0, car.road - z0
    t = np.arange(n + 1) * h
    w = 2 * np.pi * rm.f_ref
    _, lp_body, _ = lsim(([2 * rm.zeta_ref * w, w * w], [1.0, 2 * rm.zeta_ref * w, w * w]), np.r_[0.0, zs], t)
    model_truth = zr - lp_body[1:]
    corr = reference_correction(zs, zr, h, rm)
    truth = _tracked_road(t, np.r_[0.0, zr])[1:]
    late = slice(2000, None)
    rms = lambda x: float(np.sqrt(np.mean(x[late] ** 2)))  # noqa: E731
    gap, left = model_truth - truth, model_truth + corr - truth
    assert rms(left) < 0.15 * rms(gap)
    assert rms(highpass(left, h)) < 0.1 * rms(highpass(gap, h))
