"""The frozen-gain road filter gives the estimates of the full covariance recursion.

The estimator starts (and restarts after every model rebuild) at the stationary covariance of
its model and keeps the gain frozen there; after skipped or partial updates it runs the full
recursion until it is back at the fixed point (estimators/kalman.py). ``fast_gain=False`` runs
the full recursion every step: both must agree to 1e-9 m on every state estimate, through
bursts of bad samples, a frozen sensor, a wrong start mass (mass rebuilds and a re-filter) and
a step-size change."""
from __future__ import annotations

import math

import numpy as np
import pytest

from suspension_estimation.estimators.kalman import LinearKF, stationary_covariance
from suspension_estimation.estimators.model import IZR, DiscreteModel, RoadModel, measurement_covariance
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



def test_road_height_std_is_the_band_error_at_the_filters_covariance():
    """road_height_std^2 = c P[z_r, z_r] at every step, c fixed per model: at the fixed point of
    the covariance recursion (here solved independently from the estimator's model) it is the
    steady-state error variance of the profile (steady_state.band_error_variance: the ISO road of
    the assumed class and the sensor noise, through the reference taken off), plus with the
    default calibration allowance the variance of 3 % gain errors on both accelerometers and 2 ms
    delays on every channel (band_error_budget's V_g, V_tau). The estimator starts at that fixed
    point, so the std holds from the first step and again right after a re-initialisation (no
    start term: the profile has no start level); without the body accelerometer the filter
    predicts, P[z_r, z_r] grows and the std with it, and both come back."""
    from suspension_estimation.estimators.steady_state import band_error_budget

    _, meas, _, _ = simulate(road_class=3, T=6.0)
    meas = meas.copy()
    meas[3000:3050, 0] = np.nan  # 50 ms without the body accelerometer
    h, speed = 1e-3, 40 / 3.6
    std = {}
    for allowance in (False, True):
        cal = {} if allowance else {"calibration_gain_std": 0.0, "calibration_delay_std": 0.0}
        est = SuspensionEstimator(road_class=3, mass_estimator=0, road_estimator=0, **cal)
        rows = []
        for z in meas:
            o = est.step(z[0], z[1], z[2], speed, h)
            rows.append((o["road_height_std"], est.kf.P[IZR, IZR], o["status"]))
        std[allowance], p_zr, status = map(np.array, zip(*rows))
        assert np.all(status[3000:3050] == 1) and np.all(np.delete(status, range(3000, 3050)) == 0)
        ratio = std[allowance] ** 2 / p_zr
        np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
        m, R = est.model, est.R
        Pp, P = stationary_covariance(m.Phi, m.Q, m.H, R)
        K = Pp @ m.H.T @ np.linalg.inv(m.H @ Pp @ m.H.T + R)
        args = (m.Phi, m.H, K)
        rest = (h, iso8608.class_psd_n0(3), speed, est.cfg.profile_cutoff, m.vehicle, 0, IZR)
        ref = (RoadModel.f_ref, RoadModel.zeta_ref)
        var, v_g, v_tau = band_error_budget(*args, R, *rest, reference=ref)
        if allowance:
            var += 0.03 ** 2 * (v_g[0] + v_g[1]) + 0.002 ** 2 * v_tau.sum()
        assert std[allowance][0] == pytest.approx(math.sqrt(var), rel=1e-6)
        assert std[allowance][2999] == pytest.approx(math.sqrt(var), rel=1e-6)
        assert np.all(np.diff(std[allowance][3000:3050]) > 0)  # predicting: P grows
        assert std[allowance][-1] == pytest.approx(math.sqrt(var), rel=1e-6)  # back at the fixed point
        est.reset_state()
        assert est.step(*meas[-1], speed, h)["road_height_std"] == pytest.approx(math.sqrt(var), rel=1e-6)
    assert np.all(std[True] > std[False])


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
