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

from estimators.kalman import LinearKF, stationary_covariance
from estimators.model import DiscreteModel, measurement_covariance
from estimators.suspension import SuspensionEstimator
from plant import iso8608
from plant.vehicle import DEFAULT_VEHICLE
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
    assert np.array_equal(a[:, -1], b[:, -1])  # the same rejection decisions
    np.testing.assert_allclose(a[:, :6], b[:, :6], rtol=0, atol=1e-9)
    np.testing.assert_allclose(a[:, 6], b[:, 6], rtol=1e-6)  # road_height_std
    np.testing.assert_allclose(a[:, 7], b[:, 7], rtol=1e-9)  # sprung mass
    if kw.get("m_s_nominal"):
        assert fast.refilters >= 1 and fast.refilters == full.refilters
