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
    """A KF run (road_estimator 0, stationary gain, no start-height correction) smoothed from its
    outputs alone equals filterpy's rts_smoother fed the filter's own states, covariances and model."""
    from filterpy.kalman import rts_smoother

    from suspension_estimation.estimators.suspension import SuspensionEstimator
    from suspension_estimation.harness.smoothing import FMU_STATES, smooth_fmu_outputs
    from suspension_estimation.harness.studies.vb import loosening_measurements

    params = {"road_estimator": 0, "mass_estimator": 0, "road_class": 3, "k_s": 22000.0}
    meas, _ = loosening_measurements(4, T=1.5, factor=1.0)
    est = SuspensionEstimator(**params, start_offset=False)
    outs, xs, Ps = [], [], []
    heights = [i for i, k in enumerate(FMU_STATES) if k in ("z_s_est", "z_u_est", "road_height_est")]
    for a, u, d in meas:
        o = est.step(a, u, d, 40 / 3.6, 1e-3)
        # the heights carry the correction of the filter's lag behind its reference (a common
        # shift, steady_state.reference_lag): taken off, the outputs are the filter's own states
        row = [o[k] for k in FMU_STATES]
        for i in heights:
            row[i] -= est._x_int
        outs.append(row)
        xs.append(est.kf.x.copy())
        Ps.append(est.kf.P.copy())
    outs = np.array(outs)
    np.testing.assert_allclose(outs, np.array(xs), rtol=0, atol=1e-15)
    mine = smooth_fmu_outputs({k: outs[:, i] for i, k in enumerate(FMU_STATES)}, params, 40 / 3.6, 1e-3)
    K = len(xs)
    ref, *_ = rts_smoother(np.array(xs), np.array(Ps), [est.model.Phi] * K, [est.model.Q] * K)
    # the prior P_k+1|k of this model has a condition number ~1e10 (the 0.01 Hz common mode): its
    # pseudo-inverse (here) and inverse (filterpy) agree to ~1e-7, the smoothed states to ~1e-5
    for i, k in enumerate(FMU_STATES):
        tol = 1e-4 * np.max(np.abs(ref[:, i]))
        np.testing.assert_allclose(mine[k], ref[:, i], rtol=0, atol=tol)
        if k in ("z_u_est", "road_height_est"):
            assert np.max(np.abs(mine[k] - outs[:, i])) > 30 * tol  # the smoother did move them
