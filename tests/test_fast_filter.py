"""The frozen-gain road filter gives the estimates of the full covariance recursion.

The estimator starts (and restarts after every model rebuild) at the stationary covariance of
its model and keeps the gain frozen there; after skipped or partial updates it runs the full
recursion until it is back at the fixed point (estimators/kalman.py). ``fast_gain=False`` runs
the full recursion every step: both must agree to 1e-9 m on every state estimate, through
bursts of bad samples, a frozen sensor, a wrong start mass (mass rebuilds and a re-filter) and
a step-size change."""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.estimators.kalman import LinearKF, error_buildup, stationary_covariance
from suspension_estimation.estimators.model import (IZR, DiscreteModel, RoadModel, iso_road_height_std, measurement_covariance,
                              reference_step_response)
from suspension_estimation.estimators.suspension import SuspensionEstimator
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE
from test_estimators_core import simulate

STATE_OUTPUTS = ("road_height_est", "road_velocity_est", "z_s_est", "v_s_est", "z_u_est", "v_u_est")


@pytest.mark.parametrize("acc_sampling", [0, 1])
def test_stationary_covariance_is_the_fixed_point(acc_sampling):
    m = DiscreteModel.build(DEFAULT_VEHICLE, 11.1, iso8608.class_psd_n0(6), 1e-3,
                            acc_sampling=acc_sampling, road_hold=acc_sampling == 1)
    R = measurement_covariance(0.02, 0.2, 1e-4)
    Pp, P = stationary_covariance(m.Phi, m.Q, m.H, R)
    # one recursion step from the fixed point stays there (prior and posterior)
    kf = LinearKF(len(P), 3)
    kf.F, kf.Q, kf.H, kf.R, kf.P = m.Phi, m.Q, m.H, R, P
    kf.predict()
    np.testing.assert_allclose(kf.P, Pp, rtol=0, atol=1e-12 * np.abs(Pp).max())
    kf.update(np.zeros(3))
    np.testing.assert_allclose(kf.P, P, rtol=0, atol=1e-12 * np.abs(P).max())
    assert np.linalg.eigvalsh(P).min() > 0



def test_error_buildup_is_the_error_covariance_recursion():
    """From no error, the constant-gain filter's error covariance S_k = A S A' + (I-KH) Q (I-KH)'
    + K R K' (A = (I-KH) F), iterated directly, equals P (1 - d) of error_buildup at every table
    point, and the deficit falls monotonically from 1 towards 0."""
    m = DiscreteModel.build(DEFAULT_VEHICLE, 11.1, iso8608.class_psd_n0(3), 1e-3)
    R = measurement_covariance(0.02, 0.2, 1e-4)
    Pp, P = stationary_covariance(m.Phi, m.Q, m.H, R)
    K = Pp @ m.H.T @ np.linalg.inv(m.H @ Pp @ m.H.T + R)
    every = 50
    d = error_buildup(m.Phi, m.H, K, m.Q, R, P, IZR, every, 8000)
    # down to the fixed point's own error (the doubling's P against the recursion's limit, ~3e-6)
    assert d[0] == 1.0 and np.all(np.diff(d) <= 1e-12) and d[-1] < 1e-5
    assert 100 < len(d) * every * 1e-3 < 400  # s: the reference's time scale (0.01 Hz)
    I_KH = np.eye(len(P)) - K @ m.H
    drive = I_KH @ m.Q @ I_KH.T + K @ R @ K.T
    A = I_KH @ m.Phi
    S = np.zeros_like(P)
    for k in range(1, 200 * every + 1):
        S = A @ S @ A.T + drive
        if k % every == 0:
            assert S[IZR, IZR] == pytest.approx(P[IZR, IZR] * (1 - d[k // every]), rel=0, abs=1e-6 * P[IZR, IZR])


def test_road_height_std_builds_up_from_a_start_at_rest():
    """road_height_std^2 = c P_zr (1 - d(t)) + start-height term after the start from rest, and
    exactly c P_zr + start-height term after a re-initialisation (c: the real steady raw-error
    variance over P_zr) (no credit there: the relative states of a moving car are not known).
    The start-height term is g^2 P_bb - 2 g P_db of the z_0 estimate (start_offset.py), which
    shifts the road estimate by g z_0^, and starts at the prior (s0 g)^2 (``start_offset``: the
    absolute level of an ISO road; test_real_roads.py has the default, relative to the start)."""
    # the exact-model KF: with road_estimator 2 the same terms come from its anchor filter
    est = SuspensionEstimator(road_class=3, mass_estimator=0, road_estimator=0, start_offset=True)
    _, meas, _, _ = simulate(road_class=3, T=20.0)
    s0 = iso_road_height_std(iso8608.class_psd_n0(3))
    h = 1e-3
    for z in meas:
        o = est.step(z[0], z[1], z[2], 40 / 3.6, h)
    t = est.time
    dt, d = est._buildup
    frac = np.interp(t / dt, np.arange(len(d)), d)
    start = s0 * reference_step_response(t, RoadModel())
    ratio = est._honest[3]  # real steady raw-error variance / P[z_r, z_r] (test_estimators_core)
    assert 0.3 < frac < 0.99 and 0.5 < ratio < 1.0
    g = reference_step_response(t, RoadModel())
    off = est._offset
    assert 0 < off.start_variance(g) < start ** 2
    assert o["road_height_std"] ** 2 == pytest.approx(ratio * est.kf.P[IZR, IZR] * (1 - frac) + off.start_variance(g),
                                                      rel=1e-9)
    assert o["road_height_est"] == pytest.approx(est.kf.x[IZR] + g * off.b, rel=0, abs=1e-15)
    est.reset_state()
    o = est.step(z[0], z[1], z[2], 40 / 3.6, h)
    assert o["road_height_std"] ** 2 == pytest.approx(
        ratio * est.kf.P[IZR, IZR] + (s0 * reference_step_response(h, RoadModel())) ** 2, rel=1e-6)


def _run_both(meas, steps, **kw):
    outs = []
    for fast in (True, False):
        est = SuspensionEstimator(fast_gain=fast, **kw)
        rows = []
        for z, h in zip(meas, steps):
            o = est.step(z[0], z[1], z[2], 40 / 3.6, h)
            rows.append([o[k] for k in STATE_OUTPUTS] + [o["road_height_std"], o["sprung_mass_est"], o["status"]])
        outs.append((est, np.array(rows)))
    return outs


@pytest.mark.parametrize("kw", [{}, {"road_estimator": 1, "mass_estimator": 0}, {"acc_sampling": 1},
                                {"m_s_nominal": 300.0}])
def test_frozen_gain_equals_full_recursion(kw):
    _, meas, _, _ = simulate(T=12.0, seed=3)
    meas = meas.copy()
    meas[2000:2050, 0] = np.nan  # 50 ms without the body accelerometer
    meas[4000:4050, 1] += 981.0  # 100 g on the wheel accelerometer
    meas[6000:6100, 2] = meas[6000, 2]  # deflection frozen for 100 ms
    steps = np.full(len(meas), 1e-3)
    (fast, a), (full, b) = _run_both(meas, steps, **kw)
    assert fast.kf.fast and not full.kf.fast
    assert fast.kf.frozen  # back at the fixed point (frozen) after the last disturbance
    assert fast.anchor is None or fast.anchor.frozen
    assert np.array_equal(a[:, -1], b[:, -1])  # the same rejection decisions
    # the frozen gain is the fixed point to freeze_tol (1e-8 relative): states agree to about
    # that relative size, and to 10 nm / 10 nm/s where they are small
    np.testing.assert_allclose(a[:, :6], b[:, :6], rtol=1e-8, atol=1e-8)
    # road_height_std: an anchor restart (10-15 after the frozen deflection) copies the force-error
    # filter's covariance into the anchor, the frozen fixed point in one run and the full
    # recursion in the other; measured 0.7-1.2e-6 relative after them
    np.testing.assert_allclose(a[:, 6], b[:, 6], rtol=3e-6)
    np.testing.assert_allclose(a[:, 7], b[:, 7], rtol=1e-9)  # sprung mass
    if kw.get("m_s_nominal"):
        assert fast.refilters >= 1 and fast.refilters == full.refilters
