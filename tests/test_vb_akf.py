"""The VB-AKF core (estimators/vb_akf.py): its update against independent closed forms, its KF
limit against filterpy, and a sensor whose noise grows 4x mid-run on our quarter-car model."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import invwishart

from suspension_estimation.estimators.kalman import LinearKF
from suspension_estimation.estimators.model import DiscreteModel
from suspension_estimation.estimators.vb_akf import VBAKF, vb_update
from suspension_estimation.harness.studies.vb import noise_growth
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE


def _spd(rng, n, scale=1.0):
    a = rng.standard_normal((n, n))
    return scale * (a @ a.T + n * np.eye(n))


def _info_form(x_pred, P_pred, z, H, R):
    """Posterior N(x, P) of x ~ N(x_pred, P_pred), z = H x + v, v ~ N(0, R), information form."""
    Ri = np.linalg.inv(R)
    P = np.linalg.inv(np.linalg.inv(P_pred) + H.T @ Ri @ H)
    return P @ (np.linalg.solve(P_pred, x_pred) + H.T @ Ri @ z), P


def _expect(f, x, P):
    """E f(X), X ~ N(x, P), by the 2n symmetric sigma points x +- sqrt(n) L_i (weights 1/2n),
    exact for a quadratic f (mean and covariance are matched exactly)."""
    n = len(x)
    L = np.linalg.cholesky(P) * math.sqrt(n)
    pts = [x + L[:, i] for i in range(n)] + [x - L[:, i] for i in range(n)]
    return sum(f(p) for p in pts) / (2 * n)


def _assert_iw_posterior(df0, S0, E, df1, S1, rng):
    """IW(df1, S1) is the posterior of IW(df0, S0) times exp(E_q log N(e; 0, X)) when
    E_q[e e'] = E: the log densities differ by a constant over random X (scipy's IW)."""
    m = len(S0)
    diffs = []
    for _ in range(6):
        X = _spd(rng, m, float(np.trace(S0)) / m)
        loglik = -0.5 * np.linalg.slogdet(X)[1] - 0.5 * np.trace(np.linalg.solve(X, E))
        diffs.append(invwishart(df0, S0).logpdf(X) + loglik - invwishart(df1, S1).logpdf(X))
    assert np.ptp(diffs) < 1e-8 * max(1.0, np.max(np.abs(diffs)))


def test_iterations_against_closed_form_posteriors():
    rng = np.random.default_rng(3)
    n, m = 4, 3
    H = rng.standard_normal((m, n))
    x_pred, P_pred = rng.standard_normal(n), _spd(rng, n, 0.1)
    z = H @ x_pred + rng.standard_normal(m)
    u, U = 7.0, _spd(rng, m, 0.5)
    rho, tau = 0.95, 0.8
    u0, U0 = rho * u, rho * U  # the R prior of this step (forgetting)
    R0 = invwishart(u0, U0).mean()

    # one iteration: the KF update with the prior means, and the IW posterior of R given q(x)
    x1, P1, u1, U1 = vb_update(x_pred, P_pred, z, H, u, U, rho, tau, n_iter=1)
    xi, Pi = _info_form(x_pred, P_pred, z, H, R0)
    np.testing.assert_allclose(x1, xi, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(P1, Pi, rtol=1e-9, atol=1e-12)
    E_R = _expect(lambda x: np.outer(z - H @ x, z - H @ x), x1, P1)
    np.testing.assert_allclose(U1, U0 + E_R, rtol=1e-10)
    assert u1 == pytest.approx(u0 + 1)
    _assert_iw_posterior(u0, U0, E_R, u1, U1, rng)

    # the second iteration uses the posterior means of R and of the PECM (prior IW(tau + n + 1,
    # tau P_pred), mean P_pred), both from the q(x) of the first
    E_P = _expect(lambda x: np.outer(x - x_pred, x - x_pred), x1, P1)
    t0, T0 = tau + n + 1, tau * P_pred
    _assert_iw_posterior(t0, T0, E_P, t0 + 1, T0 + E_P, rng)
    Sigma1 = invwishart(t0 + 1, T0 + E_P).mean()
    R1 = invwishart(u0 + 1, U0 + E_R).mean()
    x2, P2, _, U2 = vb_update(x_pred, P_pred, z, H, u, U, rho, tau, n_iter=2)
    xi, Pi = _info_form(x_pred, Sigma1, z, H, R1)
    np.testing.assert_allclose(x2, xi, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(P2, Pi, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(U2, U0 + _expect(lambda x: np.outer(z - H @ x, z - H @ x), x2, P2),
                               rtol=1e-10)


def test_batched_update_equals_single():
    rng = np.random.default_rng(4)
    n, m, b = 4, 3, 5
    H = rng.standard_normal((m, n))
    xs = rng.standard_normal((b, n))
    Ps = np.stack([_spd(rng, n, 0.1) for _ in range(b)])
    zs = rng.standard_normal((b, m))
    Us = np.stack([_spd(rng, m) for _ in range(b)])
    out = vb_update(xs, Ps, zs, H, 6.0, Us)
    for i in range(b):
        one = vb_update(xs[i], Ps[i], zs[i], H, 6.0, Us[i])
        for a, c in zip((out[0][i], out[1][i], out[3][i]), (one[0], one[1], one[3])):
            np.testing.assert_allclose(a, c, rtol=1e-12, atol=1e-15)


def _quarter_car_run(T, h, noise_at, seed, road_class=3, speed=40 / 3.6):
    """Measurements and true [z_s - z_u, z_u - z_r, v_s, v_u] of the plant on an ISO road;
    ``noise_at(t)`` gives the plant's SensorNoise at time t (s)."""
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    car = QuarterCar(DEFAULT_VEHICLE, noise_at(0.0), noise_seed=100 + seed)
    n = int(round(T / h))
    meas, truth = np.empty((n, 3)), np.empty((n, 4))
    for k in range(n):
        car.noise = noise_at(k * h)
        car.step(road.height(speed * k * h), h)
        x = car.x
        meas[k] = car.measured
        truth[k] = x[0] - x[2], x[2] - car.road, x[1], x[3]
    return meas, truth


def _model(h):
    return DiscreteModel.build(DEFAULT_VEHICLE, 40 / 3.6, iso8608.class_psd_n0(3), h, road_hold=True)


@pytest.mark.parametrize("tau", [1e12, math.inf])
def test_known_noise_limit_is_the_kalman_filter(tau):
    from filterpy.kalman import KalmanFilter

    h = 5e-3
    mdl = _model(h)
    noise = SensorNoise()
    R = np.diag([noise.acc_sprung, noise.acc_unsprung, noise.deflection]) ** 2
    meas, _ = _quarter_car_run(3.0, h, lambda t: noise, seed=1)
    P0 = np.eye(6) * 1e-6
    kf = KalmanFilter(6, 3)
    kf.F, kf.Q, kf.H, kf.R, kf.P = mdl.Phi, mdl.Q, mdl.H, R, P0.copy()
    kf.x = np.zeros(6)
    # rho = 1 and a huge prior weight: R and the PECM stay at their nominal values
    limit = VBAKF(mdl.Phi, mdl.Q, mdl.H, R, P0=P0, rho=1.0, tau=tau, dof=1e12)
    loose = VBAKF(mdl.Phi, mdl.Q, mdl.H, R, P0=P0, rho=1.0, tau=min(tau, 1e3), dof=1e3)
    worst = 0.0
    for z in meas:
        kf.predict()
        kf.update(z)
        limit.step(z)
        loose.step(z)
        np.testing.assert_allclose(limit.x, kf.x, rtol=0, atol=1e-9 * np.max(np.abs(kf.x)))
        worst = max(worst, np.max(np.abs(loose.x - kf.x)) / np.max(np.abs(kf.x)))
    np.testing.assert_allclose(limit.P, kf.P, rtol=1e-8, atol=1e-9 * np.max(np.abs(kf.P)))
    assert worst > 1e-6  # a finite prior weight is NOT the KF: the limit is approached, not assumed


@pytest.mark.parametrize("seed", [1, 2])
def test_sensor_noise_growing_4x_is_tracked(seed):
    """The body accelerometer's noise std grows 4x at t = 4 s (a loosening mount); the R-only
    VB-AKF (tau = inf) against the KF with the nominal R, scored 5 .. 12 s."""
    r = noise_growth(seed=seed, sensor=0, factor=4.0, tau=math.inf)
    assert 0.7 < r["before"] / r["true_before"] < 1.5
    assert 0.8 < r["after"] / r["true_after"] < 1.25
    ratio = r["vb"] / r["kf"]  # z_s - z_u, z_u - z_r, v_s, v_u
    assert ratio[0] < 0.8  # the deflection: the filter no longer trusts the noisy a_s
    assert ratio.mean() < 0.95
