"""harness.vb_study: paper 004's model is our plant's in relative coordinates; its scenario's
stretches and noise levels; the batched filters against the single-run core."""
from __future__ import annotations

import numpy as np

from estimators.vb_akf import VBAKF
from harness.vb_study import (CLASS_Q, CLASS_R, PAPER_VEHICLE, kalman_runs, paper_model,
                              paper_scenario, simulate, vb_runs)
from plant.quarter_car import discretise, state_matrices


def test_paper_model_is_the_plant_in_relative_coordinates():
    """With s = [z_s, v_s, z_u, v_u, z_r] and the road velocity as the held input, the plant's
    exact ZOH model maps onto the paper's x = [z_s - z_u, z_u - z_r, v_s, v_u] by x = T s."""
    h = 0.01
    A4, B4 = state_matrices(PAPER_VEHICLE)
    A = np.zeros((5, 5))
    A[:4, :4], A[:4, 4] = A4, B4
    Fs, Bs = discretise(A, np.eye(5)[4], h)
    T = np.array([[1, 0, -1, 0, 0], [0, 0, 1, 0, -1], [0, 1, 0, 0, 0], [0, 0, 0, 1, 0.0]])
    F, B, H = paper_model(PAPER_VEHICLE, h)
    np.testing.assert_allclose(F @ T, T @ Fs, rtol=0, atol=1e-12)
    np.testing.assert_allclose(B, T @ Bs, rtol=0, atol=1e-15)
    np.testing.assert_allclose(H[0] @ T, np.r_[A4[1], B4[1]], rtol=1e-14)


def test_scenario_stretches_and_levels():
    scn = paper_scenario()
    assert len(scn.classes) == 1501 and scn.starts == [0, 501, 1001]
    for j, c in enumerate("ECA"):
        s = scn.scored[j]
        assert set(scn.classes[s]) == {c}
        assert np.all(scn.Q_nominal[s] == CLASS_Q[c])
        # the true levels swing around the nominal: 0 .. 2x, mean 1 over the stretch's two periods
        assert 0.97 < scn.Q_true[s].mean() / CLASS_Q[c] < 1.03
        assert np.all(scn.Q_true[s] >= 0) and scn.Q_true[s].max() <= 2 * CLASS_Q[c]
        np.testing.assert_allclose(scn.R_true[s].mean(axis=0) / CLASS_R[c], 1, atol=0.03)


def test_batched_filters_equal_the_single_run_core():
    F, B, H = paper_model()
    scn = paper_scenario()
    X, Y = simulate(scn, F, B, H, 2, np.random.default_rng(7))
    Qn = np.concatenate([[0.0], scn.Q_nominal[:-1]])[:, None, None] * np.outer(B, B)
    xv, Pv = vb_runs(F, Qn, H, scn, Y)
    xk, Pk = kalman_runs(F, Qn, H, scn.R_nominal, Y)
    vb = VBAKF(F, Qn[1], H, np.diag(scn.R_nominal[0]))
    kf = VBAKF(F, Qn[1], H, np.diag(scn.R_nominal[0]), rho=1.0, tau=np.inf, dof=1e15)
    for k in range(1, 501):  # the first stretch (one nominal, no restart)
        vb.step(Y[1, k])
        kf.step(Y[1, k])
        np.testing.assert_allclose(vb.x, xv[1, k], rtol=0, atol=1e-12 * np.max(np.abs(xv[1])))
    np.testing.assert_allclose(vb.P, Pv[1, 500], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(kf.x, xk[1, 500], rtol=0, atol=1e-9 * np.max(np.abs(xk[1])))
    # the VB estimate is not the KF's (it adapts)
    assert np.max(np.abs(xv[1, 1:501] - xk[1, 1:501])) > 1e-3 * np.max(np.abs(xk[1]))
