"""harness.studies.vb: paper 004's model is our plant's in relative coordinates; its scenario's
stretches and noise levels; the batched filters against the single-run core."""
from __future__ import annotations

import numpy as np

from suspension_estimation.estimators.vb_akf import VBAKF
from suspension_estimation.harness.studies.vb import (CLASS_Q, CLASS_R, PAPER_VEHICLE, kalman_runs, paper_model,
                              paper_scenario, simulate, vb_runs)
from suspension_estimation.plant.quarter_car import discretise, state_matrices


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
    xv, Pv = vb_runs(F, Qn, H, scn.R_nominal, Y)
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


def test_rsakf_against_filterpy_with_a_residual_window():
    """rsakf_runs against filterpy's KalmanFilter whose R is set before every update from a
    window of post-fit residuals (Mohamed and Schwarz), one run; window 0 is the nominal KF."""
    from collections import deque

    from filterpy.kalman import KalmanFilter

    from suspension_estimation.harness.studies.vb import rsakf_runs

    F, B, H = paper_model()
    scn = paper_scenario()
    X, Y = simulate(scn, F, B, H, 2, np.random.default_rng(3))
    Qn = np.concatenate([[0.0], scn.Q_nominal[:-1]])[:, None, None] * np.outer(B, B)
    L = 20
    xr, Pr = rsakf_runs(F, Qn, H, scn.R_nominal, Y, window=L)
    kf = KalmanFilter(4, 3)
    kf.F, kf.H, kf.x, kf.P = F, H, np.zeros(4), np.zeros((4, 4))
    res = deque(maxlen=L)
    for k in range(1, 700):
        kf.Q = Qn[k]
        R = (sum(np.outer(e, e) for e in res) / L + H @ kf.P @ H.T) if len(res) == L else np.diag(scn.R_nominal[k])
        kf.predict()
        kf.update(Y[1, k], R=R)
        res.append(Y[1, k] - H @ kf.x)
        np.testing.assert_allclose(kf.x, xr[1, k], rtol=0, atol=1e-9 * np.max(np.abs(xr[1])))
    x0 = rsakf_runs(F, Qn, H, scn.R_nominal, Y, window=0)[0]
    np.testing.assert_allclose(x0, kalman_runs(F, Qn, H, scn.R_nominal, Y)[0], rtol=0, atol=1e-12)
    assert np.max(np.abs(xr[1, 100:] - x0[1, 100:])) > 1e-3 * np.max(np.abs(x0[1]))


def test_per_run_schedule_equals_the_core_with_restarts():
    """vb_runs with a nominal per run and step: the single-run VBAKF with set_model and
    reset_noise where the run's class changes."""
    from suspension_estimation.harness.studies.vb import _nominal_q_into_step, nominal_of

    F, B, H = paper_model()
    scn = paper_scenario()
    _, Y = simulate(scn, F, B, H, 2, np.random.default_rng(4))
    cls = np.array([list("E" * 300 + "D" * 200 + "C" * 1001), list("E" * 600 + "A" * 901)])
    q, R = nominal_of(cls)
    Qd = _nominal_q_into_step(q, B)
    xv, Pv = vb_runs(F, Qd, H, R, Y)
    for i in range(2):
        vb = VBAKF(F, Qd[i, 1], H, np.diag(R[i, 0]))
        for k in range(1, 900):
            vb.set_model(Q=Qd[i, k])
            vb.step(Y[i, k])
            if cls[i, k + 1] != cls[i, k]:
                vb.reset_noise(np.diag(R[i, k + 1]))
        np.testing.assert_allclose(vb.x, xv[i, 899], rtol=0, atol=1e-9 * np.max(np.abs(xv[i])))
        np.testing.assert_allclose(vb.P, Pv[i, 899], rtol=1e-7, atol=1e-15)


def test_in_loop_classifier_on_held_out_runs():
    """The in-loop schedule equals the streaming classifier; off the first block after a switch
    it is right on most blocks of held-out runs (benchmarks/road_class_accuracy.py: 99 %)."""
    from suspension_estimation.estimators.response_class import ResponseClassifier
    from suspension_estimation.harness.studies.vb import CLASS_BLOCK, TS, classified_schedule, paper_classifier
    from suspension_estimation.plant import iso8608

    model = paper_classifier(runs=20)
    F, B, H = paper_model()
    scn = paper_scenario()
    _, Y = simulate(scn, F, B, H, 20, np.random.default_rng(77))
    cls = classified_schedule(model, Y, "E")
    clf = ResponseClassifier(model, initial=5)
    for k in range(1, 1501):
        assert cls[3, k] == iso8608.class_name(clf.road_class)  # in force at step k
        clf.update(Y[3, k], 1.0, TS)
    truth = np.array(scn.classes)
    settled = np.ones(1501, bool)
    for s in scn.starts:
        settled[s:s + 2 * CLASS_BLOCK + 1] = False  # latency: the block straddling and the next
    assert np.mean(cls[:, settled] == truth[settled]) > 0.9
