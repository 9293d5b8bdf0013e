"""Paper 004's Monte-Carlo scenario and its ARMSE table, with the smoother's share made explicit.

The scenario is the one of the authors' published scripts (the paper's text states it only in
part): their 2-DOF quarter car (m_s 250 kg, m_u 30 kg, k_s 10 kN/m, k_t 100 kN/m, c_s 1000 N.s/m),
state x = [z_s - z_u, z_u - z_r, v_s, v_u] (m, m, m/s, m/s), input the road velocity w = z_r'
(m/s) held over the step (ZOH, T_s = 0.01 s), measurements y = [a_s, z_s - z_u, z_u - z_r]
(m/s^2, m, m). 15 s = 1501 samples in three stretches of 5 s: ISO E, C, A. On each stretch the
nominal ("constant") Q and R are the class values of the paper's Table 1, and the true ones vary
around them: Q_true = (1 - sin(4 pi k / 501)) Q, R_true = (1 + sin) R for a_s and z_u - z_r and
(1 - sin) R for z_s - z_u, k = 1 .. 501 within the stretch. w_k ~ N(0, Q_true,k),
v_k ~ N(0, R_true,k), x_0 = 0 known (P_0 = 0).

The nominal values switch at the true stretch boundaries: this is the paper's "with road
classification" experiment, in which the authors' script uses the true class (an oracle, no
classifier runs). The VB filter restarts its R prior at the new nominal there, as their code does.

Rows (ARMSE per stretch, paper 004 eq. 42: sqrt of the mean over the stretch's steps of the
Monte-Carlo mean of the squared error summed over the two positions, resp. the two velocities):

- KFTCM: KF with the true Q_k, R_k (causal);
- KFNCM: KF with the nominal Q, R (causal);
- VB forward: ``estimators.vb_akf`` with the nominal prior, rho = 1 - e^-4, tau = 0.8, N = 6,
  dof 5 (causal);
- VB + RTS: the VB posteriors smoothed by ``harness.smoothing.rts_smooth`` with the nominal model
  (the paper's "proposed" filter, non-causal over the whole 15 s record);
- KFNCM + RTS, KFTCM + RTS: the same smoother on those filters' records (each with its own Q).

The KF covariances do not depend on the data, so one covariance recursion serves all runs; the
VB filter and the smoother run on stacks of runs (``vb_update`` and ``rts_smooth`` broadcast).

``noise_growth``: the case the VB-AKF is for, on OUR model (estimators.model, plant.quarter_car):
one sensor's noise std grows by a factor (a loosening mount) at some instant; the VB-AKF (nominal
R = the initial noise) against the KF that keeps the nominal R.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from estimators.kalman import LinearKF
from estimators.model import DiscreteModel
from estimators.vb_akf import DOF, N_ITER, RHO, TAU, VBAKF, vb_update
from harness.smoothing import FilterRecord, rts_smooth
from plant import iso8608
from plant.quarter_car import QuarterCar, SensorNoise, discretise
from plant.road import SyntheticRoad
from plant.vehicle import DEFAULT_VEHICLE, Vehicle

PAPER_VEHICLE = Vehicle(m_s=250.0, m_u=30.0, k_s=1.0e4, k_t=1.0e5, c_s=1000.0)
TS = 0.01  # s
DURATION = 15.0  # s
# Paper 004 Table 1 (as in the authors' code): nominal road-velocity variance per step (m^2/s^2)
# and measurement noise variances (a_s in (m/s^2)^2, deflections in m^2), classes A .. E
CLASS_Q = {"A": 0.0022, "B": 0.0088, "C": 0.0351, "D": 0.1406, "E": 0.5624}
CLASS_R = {"A": (0.0001, 0.0001, 0.0015), "B": (0.0004, 0.0004, 0.006),
           "C": (0.0016, 0.0016, 0.024), "D": (0.0064, 0.0064, 0.096),
           "E": (0.0256, 0.0256, 0.384)}
STRETCHES = ("E", "C", "A")
ROWS = ("KFTCM", "KFNCM", "VB forward", "VB + RTS", "KFNCM + RTS", "KFTCM + RTS")


def paper_model(v: Vehicle = PAPER_VEHICLE, h: float = TS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F 4x4, B (4,), H 3x4) of the authors' model, ZOH over h (s); module doc for the states."""
    ms, mu, ks, kt, c = v.m_s, v.m_u, v.k_s, v.k_t, v.c_s
    A = np.array([[0.0, 0.0, 1.0, -1.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [-ks / ms, 0.0, -c / ms, c / ms],
                  [ks / mu, -kt / mu, c / mu, -c / mu]])
    B = np.array([0.0, -1.0, 0.0, 0.0])
    H = np.vstack([A[2], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    F, Bd = discretise(A, B, h)
    return F, Bd, H


@dataclass
class Scenario:
    """Per-step noise levels of the scenario (K = 1501 steps): nominal and true Q (K,), R (K, 3),
    the class of each step and the slices of the three stretches the ARMSE is taken over."""

    Q_nominal: np.ndarray
    Q_true: np.ndarray
    R_nominal: np.ndarray
    R_true: np.ndarray
    classes: list[str]
    starts: list[int]  # first step of each stretch (0, 501, 1001)
    scored: list[slice]  # steps scored per stretch (1:501, 501:1001, 1001:1501)


def paper_scenario(stretches: tuple[str, ...] = STRETCHES, h: float = TS,
                   duration: float = DURATION) -> Scenario:
    """The authors' time-varying noise scenario (module doc)."""
    L = int(round(duration / len(stretches) / h)) + 1  # samples per stretch incl. its first
    k = np.arange(1, L + 1)
    wave = np.sin(4 * math.pi * k / L)
    Qn, Qt, Rn, Rt, cls, starts = [], [], [], [], [], []
    for j, c in enumerate(stretches):
        first = 0 if j == 0 else 1  # later stretches drop the sample shared with the previous
        q, r = CLASS_Q[c], np.array(CLASS_R[c])
        scale = np.stack([1 + wave, 1 - wave, 1 + wave], axis=1)
        starts.append(sum(len(a) for a in Qn))
        Qn.append(np.full(L, q)[first:])
        Qt.append(((1 - wave) * q)[first:])
        Rn.append(np.tile(r, (L, 1))[first:])
        Rt.append((scale * r)[first:])
        cls += [c] * (L - first)
    K = len(cls)
    ends = starts[1:] + [K]
    scored = [slice(max(s, 1), e) for s, e in zip(starts, ends)]
    return Scenario(np.concatenate(Qn), np.concatenate(Qt), np.concatenate(Rn),
                    np.concatenate(Rt), cls, starts, scored)


def simulate(scn: Scenario, F: np.ndarray, B: np.ndarray, H: np.ndarray, runs: int,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """True states X (runs, K, 4) and measurements Y (runs, K, 3): x_0 = 0,
    x_k = F x_k-1 + B w_k-1, y_k = H x_k + v_k."""
    K = len(scn.classes)
    w = rng.standard_normal((runs, K)) * np.sqrt(scn.Q_true)
    v = rng.standard_normal((runs, K, 3)) * np.sqrt(scn.R_true)
    X = np.zeros((runs, K, 4))
    for k in range(1, K):
        X[:, k] = X[:, k - 1] @ F.T + w[:, k - 1, None] * B
    return X, X @ H.T + v


def kalman_runs(F: np.ndarray, Qd: np.ndarray, H: np.ndarray, R: np.ndarray,
                Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """KF from x_0 = 0, P_0 = 0 on every run of Y (runs, K, m): predict into step k with Qd[k]
    (K, n, n), update with R[k] (K, m) diagonal. The covariance does not depend on the data, so it is
    computed once. Returns x (runs, K, n), P (K, n, n)."""
    runs, K, _ = Y.shape
    n = F.shape[0]
    x = np.zeros((runs, K, n))
    P = np.zeros((K, n, n))
    for k in range(1, K):
        Pp = F @ P[k - 1] @ F.T + Qd[k]
        S = H @ Pp @ H.T + np.diag(R[k])
        G = np.linalg.solve(S, H @ Pp).T
        xp = x[:, k - 1] @ F.T
        x[:, k] = xp + (Y[:, k] - xp @ H.T) @ G.T
        P[k] = Pp - G @ H @ Pp
    return x, P


def vb_runs(F: np.ndarray, Qd: np.ndarray, H: np.ndarray, scn: Scenario, Y: np.ndarray,
            n_iter: int = N_ITER, rho: float = RHO, tau: float = TAU,
            dof: float = DOF) -> tuple[np.ndarray, np.ndarray]:
    """VB-AKF on every run of Y (runs, K, m) with the nominal model; the R prior restarts at the
    nominal of the next stretch after each stretch's last step (as the authors' code does).
    Returns x (runs, K, n), P (runs, K, n, n)."""
    runs, K, m = Y.shape
    n = F.shape[0]
    x = np.zeros((runs, K, n))
    P = np.zeros((runs, K, n, n))
    restart = {s - 1 for s in scn.starts[1:]}  # after the last step of a stretch
    u, U = dof, np.broadcast_to((dof - m - 1) * np.diag(scn.R_nominal[0]), (runs, m, m))
    for k in range(1, K):
        xp = x[:, k - 1] @ F.T
        Pp = F @ P[:, k - 1] @ F.T + Qd[k]
        x[:, k], P[:, k], u, U = vb_update(xp, Pp, Y[:, k], H, u, U, rho, tau, n_iter)
        if k in restart:
            u = dof
            U = np.broadcast_to((dof - m - 1) * np.diag(scn.R_nominal[k + 1]), (runs, m, m))
    return x, P


def squared_errors(x: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sum over runs of the squared error of the positions and of the velocities, per step (K,)."""
    e2 = (x - X) ** 2
    return e2[..., :2].sum(axis=(0, 2)), e2[..., 2:].sum(axis=(0, 2))


def armse_table(runs: int, seed: int = 1, chunk: int = 250, n_iter: int = N_ITER,
                progress=None) -> dict:
    """ARMSE (position m, velocity m/s) of every row on every stretch over ``runs`` Monte-Carlo
    runs (module doc), simulated ``chunk`` at a time. Returns {"rows": {row: {"pos": [..],
    "vel": [..]}}, "se_change_pct": the standard error of each row's change against KFNCM in %
    from batch means over the chunks (None with fewer than 4 chunks), "runs", "seconds", ...}."""
    F, B, H = paper_model()
    scn = paper_scenario()
    # the process noise INTO step k is B w_k-1: Q[k] = B B' Q_k-1 (Q[0] unused)
    BB = np.outer(B, B)
    Q_nom = np.concatenate([[0.0], scn.Q_nominal[:-1]])[:, None, None] * BB
    Q_true = np.concatenate([[0.0], scn.Q_true[:-1]])[:, None, None] * BB
    chunks = []  # per chunk: {row: (sum of squared position errors (K,), velocity (K,))}, runs
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    done = 0
    while done < runs:
        b = min(chunk, runs - done)
        X, Y = simulate(scn, F, B, H, b, rng)
        xt, Pt = kalman_runs(F, Q_true, H, scn.R_true, Y)
        xn, Pn = kalman_runs(F, Q_nom, H, scn.R_nominal, Y)
        xv, Pv = vb_runs(F, Q_nom, H, scn, Y, n_iter=n_iter)
        est = {
            "KFTCM": xt, "KFNCM": xn, "VB forward": xv,
            "VB + RTS": rts_smooth(FilterRecord(xv, Pv, F, Q_nom))[0],
            "KFNCM + RTS": rts_smooth(FilterRecord(xn, Pn, F, Q_nom))[0],
            "KFTCM + RTS": rts_smooth(FilterRecord(xt, Pt, F, Q_true))[0],
        }
        chunks.append(({r: squared_errors(x, X) for r, x in est.items()}, b))
        done += b
        if progress:
            progress(done, runs)

    def armse(parts):
        n = sum(b for _, b in parts)
        out = {}
        for r in ROWS:
            pos = sum(c[r][0] for c, _ in parts) / n
            vel = sum(c[r][1] for c, _ in parts) / n
            out[r] = {"pos": [float(np.sqrt(pos[s].mean())) for s in scn.scored],
                      "vel": [float(np.sqrt(vel[s].mean())) for s in scn.scored]}
        return out

    table = armse(chunks)
    # Monte-Carlo standard error of each change against KFNCM (%), by batch means over the chunks
    se = None
    if len(chunks) >= 4:
        per = [armse([c]) for c in chunks]
        se = {r: {key: [float(np.std([100 * (p[r][key][j] / p["KFNCM"][key][j] - 1) for p in per],
                                     ddof=1) / math.sqrt(len(per))) for j in range(len(scn.scored))]
                  for key in ("pos", "vel")} for r in ROWS}
    return {"rows": table, "se_change_pct": se, "runs": runs, "seed": seed, "n_iter": n_iter,
            "chunk": chunk, "stretches": list(STRETCHES), "seconds": time.perf_counter() - t0}


GROWTH_STATES = ("z_s - z_u", "z_u - z_r", "v_s", "v_u")


def noise_growth(seed: int = 1, sensor: int = 0, factor: float = 4.0, tau: float = math.inf,
                 n_iter: int = N_ITER, T: float = 12.0, h: float = 5e-3, t_change: float = 4.0,
                 road_class: int = 3, speed: float = 40 / 3.6) -> dict:
    """Sensor ``sensor`` (0 a_s, 1 a_u, 2 deflection) of the plant (default vehicle and
    SensorNoise, ISO ``road_class`` road ``seed``, ``speed`` m/s, step h s) gets ``factor`` times
    its noise std from ``t_change`` s on. The KF (LinearKF) and the VB-AKF (``tau``, ``n_iter``,
    the default rho and dof) run on the 6-state model with the road held over the step, both
    assuming the initial R, from P_0 = 1e-6 I. Scored from 1 s after the change (R memory
    55 steps = 0.28 s) to T: RMSE of GROWTH_STATES for both filters ("kf", "vb"), and the VB's
    estimated std of the sensor (mean of sqrt(R_hat)) over [t_change / 2, t_change) ("before")
    and over the scored time ("after"), with the true stds ("true_before", "true_after"); the
    estimated stds of all three sensors over the scored time ("after_all") and the true ones
    ("true_all")."""
    nominal = SensorNoise()
    stds = [nominal.acc_sprung, nominal.acc_unsprung, nominal.deflection]
    grown = list(stds)
    grown[sensor] *= factor
    grown_noise = SensorNoise(*grown)
    model = DiscreteModel.build(DEFAULT_VEHICLE, speed, iso8608.class_psd_n0(road_class), h,
                                road_hold=True)
    R = np.diag(stds) ** 2
    P0 = np.eye(6) * 1e-6
    kf = LinearKF(6, 3)
    kf.F, kf.Q, kf.H, kf.R, kf.P = model.Phi, model.Q, model.H, R, P0.copy()
    vb = VBAKF(model.Phi, model.Q, model.H, R, P0=P0, tau=tau, n_iter=n_iter)
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    car = QuarterCar(DEFAULT_VEHICLE, nominal, noise_seed=100 + seed)
    D = np.array([[1, 0, -1, 0, 0, 0], [0, 0, 1, 0, -1, 0], [0, 1, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0.0]])
    n = int(round(T / h))
    err = np.empty((2, n, 4))
    r_std = np.empty((n, 3))
    for k in range(n):
        if k * h >= t_change:
            car.noise = grown_noise
        car.step(road.height(speed * k * h), h)
        x = car.x
        truth = np.array([x[0] - x[2], x[2] - car.road, x[1], x[3]])
        z = np.array(car.measured)
        kf.predict()
        kf.update(z)
        vb.step(z)
        err[0, k] = D @ kf.x - truth
        err[1, k] = D @ vb.x - truth
        r_std[k] = np.sqrt(np.diag(vb.R_estimate))
    k0, k1 = int(round(t_change / h)), int(round((t_change + 1.0) / h))
    rmse = np.sqrt(np.mean(err[:, k1:] ** 2, axis=1))
    return {"kf": rmse[0], "vb": rmse[1], "before": float(r_std[k0 // 2:k0, sensor].mean()),
            "after": float(r_std[k1:, sensor].mean()), "true_before": stds[sensor],
            "true_after": grown[sensor], "after_all": r_std[k1:].mean(axis=0),
            "true_all": np.array(grown)}
