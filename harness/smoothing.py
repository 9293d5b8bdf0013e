"""Offline Rauch-Tung-Striebel (RTS) smoothing of a recorded filter run.

A smoother is non-causal: the estimate at step k uses every measurement of the record, up to
its end. Its errors must be compared with other smoothers, never with causal filters; to compare
smoothing on equal terms, every filter is smoothed here by the same backward pass from the same
kind of record and the same model.

What a filter must record, at every step k = 0 .. K-1 (``FilterRecord``):

- ``x``: the posterior mean x_k|k (all n states, not only the published outputs);
- ``P``: the posterior covariance P_k|k (n x n, the full matrix);
- the model it predicted with: ``F`` (F[k] takes step k-1 to step k) and ``Q`` (Q[k] the
  process noise covariance of that transition), one matrix for all steps or one per step; F[0]
  and Q[0] are not used. This is filterpy's convention (``batch_filter``, ``rts_smoother``): the
  model a filter used at step k is recorded at k.

The prior of step k+1 is recomputed from the record, P_k+1|k = F_k+1 P_k|k F_k+1' + Q_k+1, so the
filter's own (adapted, inflated, frozen-gain ...) prior is NOT used: for an adaptive filter such
as ``estimators.vb_akf`` this is the nominal model, which is what paper 004's backward pass does
(its code smooths the VB posteriors with the nominal prediction). Nothing else about the filter
is needed, so a KF, an adaptive KF or any other Gaussian filter is smoothed by the same rule.

The backward pass (Rauch, Tung, Striebel 1965; filterpy.kalman.rts_smoother):

    G_k = P_k|k F_k+1' P_k+1|k^+
    x_k|K = x_k|k + G_k (x_k+1|K - F_k+1 x_k|k)
    P_k|K = P_k|k + G_k (P_k+1|K - P_k+1|k) G_k'

It is written here rather than calling filterpy's ``rts_smoother`` (which it equals, tested to
1e-9) for two reasons: it smooths a stack of Monte-Carlo runs in one pass (leading axes), and it
takes the pseudo-inverse of P_k+1|k, which is singular while a filter started from an exactly
known state (P_0 = 0, as in paper 004) has not yet seen enough process noise; filterpy inverts it
and fails or returns garbage there. Where P_k+1|k is regular, pinv is its inverse.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class FilterRecord:
    """A recorded filter run (module doc): x (..., K, n), P (K, n, n) or (..., K, n, n), and the
    model F, Q, each (n, n) for every step, (K, n, n) per step or (..., K, n, n) per run and step
    (F[k], Q[k] take step k-1 to step k; the first is unused)."""

    x: np.ndarray
    P: np.ndarray
    F: np.ndarray
    Q: np.ndarray

    def __post_init__(self) -> None:
        self.x = np.asarray(self.x, float)
        self.P = np.asarray(self.P, float)
        self.F = np.asarray(self.F, float)
        self.Q = np.asarray(self.Q, float)
        if self.x.ndim < 2:
            raise ValueError(f"x has shape {self.x.shape}: (steps, states) expected")
        K, n = self.x.shape[-2:]
        if self.P.shape[-3:] != (K, n, n):
            raise ValueError(f"P has shape {self.P.shape}: (..., {K}, {n}, {n}) expected")
        for name in ("F", "Q"):
            a = getattr(self, name)
            if a.shape != (n, n) and a.shape[-3:] != (K, n, n):
                raise ValueError(f"{name} has shape {a.shape}: ({n}, {n}) or (..., {K}, {n}, {n}) expected")


def _per_step(a: np.ndarray, K: int) -> np.ndarray:
    return np.broadcast_to(a, (K,) + a.shape[-2:]) if a.ndim == 2 else a


def rts_smooth(record: FilterRecord) -> tuple[np.ndarray, np.ndarray]:
    """(x_k|K, P_k|K) of every step (module doc), shapes those of record.x and record.P."""
    x, P = record.x, record.P
    K = x.shape[-2]
    F, Q = _per_step(record.F, K), _per_step(record.Q, K)
    F, Q = F[..., 1:, :, :], Q[..., 1:, :, :]  # F[k] now takes step k to k+1, k = 0 .. K-2
    FT = np.swapaxes(F, -1, -2)
    P_prior = F @ P[..., :-1, :, :] @ FT + Q  # P_k+1|k
    G = P[..., :-1, :, :] @ FT @ np.linalg.pinv(P_prior, hermitian=True)
    x_pred = (F @ x[..., :-1, :, None])[..., 0]  # F_k+1 x_k|k
    xs = x.copy()
    Ps = np.array(np.broadcast_to(P, P.shape), copy=True)
    for k in range(K - 2, -1, -1):
        Gk = G[..., k, :, :]
        xs[..., k, :] = x[..., k, :] + (Gk @ (xs[..., k + 1, :] - x_pred[..., k, :])[..., None])[..., 0]
        Ps[..., k, :, :] = P[..., k, :, :] + Gk @ (Ps[..., k + 1, :, :] - P_prior[..., k, :, :]) @ np.swapaxes(Gk, -1, -2)
    return xs, Ps


# --------------------------------------------------------------------------------------------------
# a recorded FMU run
# --------------------------------------------------------------------------------------------------
# SuspensionEstimator outputs that are the 6 states of estimators.model, in its order
# the outputs that give the filter's six states (the road: z_u_est - tire_deflection_est, the
# filter's road before the profile's high-pass)
FMU_STATES = ("z_s_est", "v_s_est", "z_u_est", "v_u_est", "tire_deflection_est", "road_velocity_est")


def fmu_model(parameters: dict, speed: float, h: float, road_class: int | None = None,
              road_hold: bool | None = None):
    """(F, Q, P) for smoothing a SuspensionEstimator run: the exact 6-state model of
    ``estimators.model`` built from the FMU's ``parameters`` (its contract names; the rest at
    their defaults) at ``speed`` m/s and step ``h`` s, and P the stationary posterior covariance of
    the KF of that model with the configured sensor noise (``kalman.stationary_covariance``).

    The defaults are the estimator's own model: ``road_class`` (the road intensity) is class
    max(road_class or default_class, q_class_min) for the KF family (road_estimator 0-2; code 2's
    force-error state is left out: its 6 physical states are smoothed on the exact model) and
    road_class or default_class for the VB-AKF (road_estimator 4: pass the class it identified,
    ``road_class_est``); ``road_hold`` (the road held over the step) as each does it: the KF
    family with acc_sampling 1 only, the VB-AKF unless road_hold = 0. acc_sampling 1 is not
    supported (its model has 8 states)."""
    from suspension_estimation.estimators.kalman import stationary_covariance
    from suspension_estimation.estimators.model import DiscreteModel, measurement_covariance
    from suspension_estimation.estimators.suspension import EstimatorConfig
    from suspension_estimation.plant import iso8608

    cfg = EstimatorConfig(**parameters)
    if int(cfg.acc_sampling) != 0:
        raise ValueError("fmu_model: acc_sampling 1 (8 states) is not supported")
    vb = int(cfg.road_estimator) == 4
    if road_class is None:
        road_class = int(cfg.road_class) or int(cfg.tuning.default_class)
        road_class = road_class if vb else max(road_class, int(cfg.tuning.q_class_min))
    if road_hold is None:
        road_hold = cfg.tuning.road_hold != 0 if vb else cfg.tuning.road_hold == 1
    hold = bool(road_hold)
    m = DiscreteModel.build(cfg.vehicle(), max(speed, 0.1), iso8608.class_psd_n0(road_class), h, cfg.tuning.road_model,
                            cfg.tuning.model_noise, True, 0, hold)
    R = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std, cfg.defl_noise_std)
    sol = stationary_covariance(m.Phi, m.Q, m.H, R)
    if sol is None:
        raise ValueError("fmu_model: the model's Kalman filter has no stationary covariance")
    return m.Phi, m.Q, sol[1]


def smooth_fmu_outputs(outputs: dict, parameters: dict, speed: float, h: float,
                       road_class: int | None = None, road_hold: bool | None = None) -> dict:
    """RTS-smooth a recorded SuspensionEstimator run from its outputs: ``outputs`` maps each name of
    ``FMU_STATES`` to its samples (K,), one per step of h s (the rows after each doStep). The
    outputs are taken as x_k|k; every step gets the covariance P and the model F, Q of
    ``fmu_model`` (the filter's own covariance is not published). Whatever the filter (KF, the
    robust default, the VB-AKF ...), its run is smoothed by the same backward pass with the same
    model and covariance: smoothing compared on equal terms. For a filter at its stationary gain on
    that model (the KF, road_estimator 0) this is its exact RTS smoother (tests/test_smoothing.py).
    Returns the smoothed z_s_est, v_s_est, z_u_est, v_u_est, road_velocity_est,
    susp_deflection_est, tire_deflection_est, and road_height_est, the smoothed road made a
    profile as the estimator makes its own (``profile_of``; the KF family's reference taken off)."""
    from suspension_estimation.estimators.suspension import EstimatorConfig

    F, Q, P = fmu_model(parameters, speed, h, road_class, road_hold)
    cols = [np.asarray(outputs[k], float) for k in FMU_STATES]
    cols[4] = cols[2] - cols[4]  # the filter's road
    x = np.stack(cols, axis=-1)
    K = x.shape[-2]
    xs, _ = rts_smooth(FilterRecord(x, np.broadcast_to(P, (K,) + P.shape), F, Q))
    out = {k: xs[..., i] for i, k in enumerate(FMU_STATES) if k != "tire_deflection_est"}
    out["susp_deflection_est"] = out["z_s_est"] - out["z_u_est"]
    out["tire_deflection_est"] = out["z_u_est"] - xs[..., 4]
    cfg = EstimatorConfig(**parameters)
    rm = cfg.tuning.road_model
    ref = (rm.f_ref, rm.zeta_ref) if int(cfg.road_estimator) in (0, 1, 2) else (0.0, 0.0)
    out["road_height_est"] = np.apply_along_axis(
        profile_of, -1, xs[..., 4], np.full(K, float(speed)), h, cfg.profile_cutoff, cfg.tuning.standstill_speed, ref)
    return out


# --------------------------------------------------------------------------------------------------
# the default estimator (road_estimator 2), smoothed from its inputs
# --------------------------------------------------------------------------------------------------
# Smoothing the six published states on the exact model loses accuracy for the default (above),
# and its own run cannot be smoothed as it stands: the velocity pull towards the anchor, the
# anchor's restarts, the hold after a fault and the causal blend are not Gaussian filter steps. So
# the run is filtered again, offline, by linear Kalman filters of the models the default is made
# of, at the mass and damping it identified, each is RTS-smoothed, and the output is made as the
# default makes its own (``smooth_default``; docs/smoothing.md).

@dataclass
class _Fixed:
    """One model of an offline pass (F, Q, H, R) with its Kalman filter's fixed point: prior and
    posterior covariance Pp, P, gain K and stationary innovation variances Sd."""

    F: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    R: np.ndarray
    Pp: np.ndarray
    P: np.ndarray
    K: np.ndarray
    Sd: np.ndarray
    vehicle: object
    speed: float


def _fixed(model, R: np.ndarray) -> _Fixed:
    from suspension_estimation.estimators.kalman import stationary_covariance

    sol = stationary_covariance(model.Phi, model.Q, model.H, R)
    if sol is None:
        raise ValueError("smooth_default: the model's Kalman filter has no stationary covariance")
    Pp, P = sol
    S = model.H @ Pp @ model.H.T + R
    return _Fixed(model.Phi, model.Q, model.H, R, Pp, P, Pp @ model.H.T @ np.linalg.inv(S), np.diag(S).copy(),
                  model.vehicle, model.speed)


def _live(z: np.ndarray, h: float, frozen_time: float) -> np.ndarray:
    """(K, m) bool: the samples the estimator would take, finite and not frozen (the same value,
    bit for bit, for frozen_time s; SuspensionEstimator._live)."""
    same = np.zeros(z.shape, bool)
    same[1:] = z[1:] == z[:-1]
    idx = np.arange(len(z))[:, None]
    run = idx - np.maximum.accumulate(np.where(same, 0, idx), axis=0)  # repeats so far
    return np.isfinite(z) & (run * h < frozen_time - 1e-12)


def _kalman_pass(models: list[_Fixed], index: np.ndarray, z: np.ndarray, live: np.ndarray, gate: float,
                 tol: float = 1e-8):
    """The Kalman filter of models[index[k]] at every step k from a car at rest (x_0 = 0, P_0 = 0:
    its states relative to the common-mode reference are all zero then). A step updates with the
    live channels whose innovation passes the gate y_i^2 <= gate S_ii (none: predict only; Joseph
    form); the full recursion runs until P is within ``tol`` (relative) of the model's fixed point,
    then the gain is frozen there; at a change of model a frozen filter moves to the new fixed
    point, as the estimator does at a rebuild. Returns the posteriors x_k|k (K, n), the priors
    F_k x_k-1|k-1 (K, n) and the posterior covariances P_k|k (a list: the fixed point's own array
    while frozen)."""
    K, n = len(index), models[0].F.shape[0]
    xs, xp = np.empty((K, n)), np.empty((K, n))
    Ps: list = [None] * K
    I = np.eye(n)
    x, P, frozen, cur = np.zeros(n), np.zeros((n, n)), False, -1
    all_live = live.all(axis=1)
    for k in range(K):
        md = models[index[k]]
        if index[k] != cur:
            cur = index[k]
            if frozen:
                P = md.P
        F, H, R = md.F, md.H, md.R
        x = F @ x
        xp[k] = x
        zk = z[k]
        if frozen and all_live[k]:
            y = zk - H @ x
            if np.all(y * y <= gate * md.Sd):
                x = x + md.K @ y
                xs[k], Ps[k] = x, md.P
                continue
        Pp = F @ P @ F.T + md.Q
        frozen = False
        rows = None if all_live[k] else np.flatnonzero(live[k])
        while rows is None or rows.size:  # the gate, then the update with the channels that pass it
            if rows is not None:
                H, R = md.H[rows], md.R[np.ix_(rows, rows)]
            y = (zk if rows is None else zk[rows]) - H @ x
            S = H @ Pp @ H.T + R
            passed = y * y <= gate * S.diagonal()
            if passed.all():
                break
            rows = np.flatnonzero(passed) if rows is None else rows[passed]
        if rows is None or rows.size:
            Kg = Pp @ H.T @ np.linalg.inv(S)
            x = x + Kg @ y
            IKH = I - Kg @ H
            P = IKH @ Pp @ IKH.T + Kg @ R @ Kg.T
            P = 0.5 * (P + P.T)
            if rows is None and k % 16 == 0 and np.max(np.abs(P - md.P)) <= tol * np.max(np.abs(md.P)):
                P, frozen = md.P, True
        else:
            P = Pp
        xs[k], Ps[k] = x, P
    return xs, xp, Ps


def _rts_pass(models: list[_Fixed], index: np.ndarray, xs: np.ndarray, xp: np.ndarray, Ps: list,
              keep: tuple[int, ...], chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """``rts_smooth`` of a ``_kalman_pass`` (the same backward pass, taking P_k|k a chunk of steps
    at a time instead of all of them stacked): x_k|K (K, n) and the diagonal elements ``keep`` of
    P_k|K (K, len(keep))."""
    K = len(index)
    Fs = np.stack([m.F for m in models])
    Qs = np.stack([m.Q for m in models])
    out = xs.copy()
    var = np.empty((K, len(keep)))
    keep = list(keep)
    Psm = Ps[-1]
    var[-1] = Psm.diagonal()[keep]
    for b in range(K - 1, 0, -chunk):  # steps a .. b-1, each smoothed from the next
        a = max(b - chunk, 0)
        P = np.stack(Ps[a:b])
        F, Q = Fs[index[a + 1:b + 1]], Qs[index[a + 1:b + 1]]
        FT = np.swapaxes(F, -1, -2)
        Pp = F @ P @ FT + Q
        G = P @ FT @ np.linalg.pinv(Pp, hermitian=True)
        for j in range(b - a - 1, -1, -1):
            k = a + j
            Gk = G[j]
            out[k] = xs[k] + Gk @ (out[k + 1] - xp[k + 1])
            Psm = P[j] + Gk @ (Psm - Pp[j]) @ Gk.T
            var[k] = Psm.diagonal()[keep]
    return out, var


def _smoother_transfer(md: _Fixed, f: np.ndarray, h: float) -> np.ndarray:
    """(nf, n, m): measurements -> x_k|K of the steady-state RTS smoother of md's Kalman filter at
    frequencies f (Hz). Filter x_k = M x_k-1 + K y_k, M = (I - K H) F; smoother
    x_k|K = (I - G F) x_k + G x_k+1|K, G = P F' Pp^-1; with z = e^(2 pi i f h):
    X_s = (I - z G)^-1 (I - G F) (I - M / z)^-1 K Y."""
    n = md.F.shape[0]
    I = np.eye(n)
    G = md.P @ md.F.T @ np.linalg.pinv(md.Pp, hermitian=True)
    M = (I - md.K @ md.H) @ md.F
    z = np.exp(2j * np.pi * np.asarray(f, float) * h)[:, None, None]
    Xf = np.linalg.solve(I - M / z, np.broadcast_to(md.K, (len(f),) + md.K.shape))
    return np.linalg.solve(I - z * G, (I - G @ md.F) @ Xf)


def _reference_lowpass(f: np.ndarray, f_ref: float, zeta_ref: float) -> np.ndarray:
    """1 - the reference's high-pass: (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2), s = 2 pi i f."""
    from suspension_estimation.estimators.steady_state import reference_highpass

    return 1.0 - reference_highpass(f, f_ref, zeta_ref)


def _blend_gain(f: np.ndarray, hz: float, h: float) -> np.ndarray:
    """|B(f)|^2 of the zero-phase blend (``_blend``: the second-order Butterworth low-pass at hz
    forwards and backwards); 1 for hz = inf (the anchor alone), 0 for hz = 0."""
    from scipy.signal import butter, sosfreqz

    if not np.isfinite(hz) or hz <= 0:
        return np.full(len(f), 1.0 if hz > 0 else 0.0)
    _, b = sosfreqz(butter(2, hz, fs=1.0 / h, output="sos"), worN=np.asarray(f, float), fs=1.0 / h)
    return np.abs(b) ** 2


def _output_row(hi: _Fixed, lo: _Fixed, f: np.ndarray, h: float, blend_hz: float, road_model) -> np.ndarray:
    """(nf, m): measurements -> the smoothed road output before the lag term (``smooth_default``):
    the blend of the two smoothers' states (lo below blend_hz, hi above), then the reference's
    correction of the road."""
    from suspension_estimation.estimators.model import IZR, IZS, N_STATES

    X = _smoother_transfer(lo, f, h)[:, :N_STATES]
    if hi is not lo:
        L = _blend_gain(f, blend_hz, h)[:, None, None]
        X = L * X + (1.0 - L) * _smoother_transfer(hi, f, h)[:, :N_STATES]
    from scipy.signal import sosfreqz

    hp = sosfreqz(_correction_sos(h), worN=np.asarray(f, float), fs=1.0 / h)[1]
    lp = _reference_lowpass(f, road_model.f_ref, road_model.zeta_ref) * hp
    return X[:, IZR] + lp[:, None] * (X[:, IZS] - X[:, IZR])


def _through(hi: _Fixed, lo: _Fixed, f: np.ndarray, h: float, blend_hz: float, road_model,
             acc_sampling: int) -> tuple[np.ndarray, np.ndarray]:
    """(o, T): the measurements -> output row (``_output_row``) and the road -> output transfer
    T = o G through lo's vehicle (``steady_state.plant_transfer``), at frequencies f (Hz)."""
    from suspension_estimation.estimators.steady_state import plant_transfer

    o = _output_row(hi, lo, f, h, blend_hz, road_model)
    G = plant_transfer(lo.vehicle, h, np.exp(-2j * np.pi * f * h), acc_sampling)[:, :lo.H.shape[0]]
    return o, np.einsum("fi,fi->f", o, G)


def _lag(hi: _Fixed, lo: _Fixed, h: float, blend_hz: float, road_model, acc_sampling: int) -> float:
    """q (1/s): the smoothed output's lag behind the reference's high-pass HP below the band, as
    ``steady_state.reference_lag`` (T = HP (1 - q / s) there: q = mean of Re[s (HP / T - 1)] over
    0.2-2 f_ref; the output adds q int x dt); 0 without a reference or when T is not finite."""
    from suspension_estimation.estimators.steady_state import reference_highpass

    rm = road_model
    if not rm.f_ref > 0:
        return 0.0
    f = np.geomspace(0.2 * rm.f_ref, 2.0 * rm.f_ref, 5)
    T = _through(hi, lo, f, h, blend_hz, rm, acc_sampling)[1]
    q = float(np.mean((2j * np.pi * f * (reference_highpass(f, rm.f_ref, rm.zeta_ref) / T - 1)).real))
    return q if np.isfinite(q) else 0.0


def _steady(hi: _Fixed, lo: _Fixed, h: float, blend_hz: float, road_model, gd_n0: float, acc_sampling: int,
            q: float) -> tuple[float, float]:
    """(raw error variance m^2, P_k|K[z_r, z_r] m^2) of the steady-state smoothed road output with
    the lag term q int x dt (q 1/s), on an ISO road of intensity gd_n0 (m^3) at lo's speed, the
    vehicle lo's. Variance: the road through the plant and the smoother, |T (1 + q / s) - HP|^2 S_r
    over the ISO band, plus the white sensor noise (R, one-sided PSD 2 h R_ii) through it,
    |o_i|^2 over 1e-6 Hz .. Nyquist (without the lag term, as ``steady_state.raw_error_variance``).
    P_k|K: lo's (the std is taken from it), the fixed point of P_k|K = P + G (P_k|K - Pp) G'
    (summed by doubling)."""
    from suspension_estimation.estimators.model import IZR
    from suspension_estimation.estimators.steady_state import iso_psd_time, reference_highpass
    from suspension_estimation.plant import iso8608

    rm, md = road_model, lo
    v = max(abs(md.speed), 0.1)
    var = 0.0
    f_lo, f_hi = iso8608.N_MIN * v, min(iso8608.N_MAX * v, 0.999 / (2 * h))
    if f_hi > f_lo:
        f = np.geomspace(f_lo, f_hi, 1500)
        T = _through(hi, lo, f, h, blend_hz, rm, acc_sampling)[1]
        err = T * (1 + q / (2j * np.pi * f)) - reference_highpass(f, rm.f_ref, rm.zeta_ref)
        var += float(np.trapezoid(np.abs(err) ** 2 * iso_psd_time(f, gd_n0, v), f))
    f = np.geomspace(1e-6, 0.999 / (2 * h), 6000)
    o = _through(hi, lo, f, h, blend_hz, rm, acc_sampling)[0]
    var += float(np.trapezoid((np.abs(o) ** 2 * (2 * h * np.diag(md.R))).sum(axis=1), f))
    # the smoothed covariance's fixed point: D = P_k|K - P = G D G' + G (P - Pp) G'
    G = md.P @ md.F.T @ np.linalg.pinv(md.Pp, hermitian=True)
    D = G @ (md.P - md.Pp) @ G.T
    for _ in range(64):
        add = G @ D @ G.T
        D = D + add
        if abs(add[IZR, IZR]) <= 1e-13 * abs(D[IZR, IZR]):
            break
        G = G @ G
    return var, float(md.P[IZR, IZR] + D[IZR, IZR])


CORRECTION_HZ = 0.03  # Hz, the high-pass of z_s - z_r in ``reference_correction``


def _correction_sos(h: float) -> np.ndarray:
    from scipy.signal import butter

    return butter(2, CORRECTION_HZ, btype="highpass", fs=1.0 / h, output="sos")


def reference_correction(z_s: np.ndarray, z_r: np.ndarray, h: float, road_model=None) -> np.ndarray:
    """What to add (m) to body, wheel and road heights estimated relative to the estimators'
    common-mode reference to make them relative to the road's own, the road's high-pass
    z_r - LP(z_r), which ``profile_of`` then takes off exactly; z_s, z_r (m): the body and road
    estimates, one sample per step of h s from a car at rest at t = 0. Causal.

    The model's reference follows the BODY: c'' = 2 zeta w (z_s' - c') + w^2 (z_s - c), so the
    estimates are z - LP(z_s), LP = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2) = 1 - HP
    (``estimators.model``, w = 2 pi f_ref), while the road's own is z_r - LP(z_r). The difference
    is LP(z_s - z_r): in band LP ~ 2 zeta w / s, 1.3 % at the body resonance (1.1 Hz), where
    z_s - z_r is as large as the road: 0.5-0.9 points off the causal default's HP error %
    (docs/smoothing.md). z_s - z_r passes a second-order Butterworth high-pass at CORRECTION_HZ
    first: that of a linear car is ~(f / 1 Hz)^2 of the road below it, but a suspension that
    jacks (an asymmetric damper) holds a mean offset of mm there, which the force-error filter's
    slow bias takes up instead (air-spring plant, ISO C at 40 km/h, seed 2, 30 s: smoothed raw
    error 44 mm without the high-pass, 33 mm with it, as the causal estimate's).
    Exact for a linear car's true states but for that high-pass: left over ~5 % of the
    correction in band. Both filters run from rest (scipy.signal.lsim: input linear between
    samples)."""
    from scipy.signal import lsim, sosfilt

    from suspension_estimation.estimators.model import RoadModel

    rm = RoadModel() if road_model is None else road_model
    u = np.asarray(z_s, float) - np.asarray(z_r, float)
    if not rm.f_ref > 0:
        return np.zeros_like(u)
    w = 2 * np.pi * rm.f_ref
    _, y, _ = lsim(([2 * rm.zeta_ref * w, w * w], [1.0, 2 * rm.zeta_ref * w, w * w]),
                   np.r_[0.0, sosfilt(_correction_sos(h), u)], np.arange(len(u) + 1) * h)
    return np.asarray(y, float)[1:]


def _blend(hi: np.ndarray, lo: np.ndarray, hz: float, h: float) -> np.ndarray:
    """hi + B (lo - hi), B the second-order Butterworth low-pass at hz (Hz) run forwards and
    backwards (zero phase, gain |B|^2): lo's states below hz, hi's above, exactly complementary.
    hz = inf: lo alone; 0: hi alone."""
    from scipy.signal import butter, sosfiltfilt

    if not np.isfinite(hz) or hz <= 0:
        return lo.copy() if hz > 0 else hi.copy()
    pad = min(len(hi) - 1, int(round(3.0 / (hz * h))))  # three periods of the corner at each end
    return hi + sosfiltfilt(butter(2, hz, fs=1.0 / h, output="sos"), lo - hi, axis=0, padlen=pad)


def profile_of(road: np.ndarray, speed: np.ndarray, h: float, cutoff: float, standstill: float,
               reference: tuple[float, float]) -> np.ndarray:
    """The road profile (m) of a road estimate ``road`` (m, relative to the common-mode reference
    ``reference`` = (f_ref, zeta_ref)) as the estimator makes road_height_est
    (estimators.road_profile.Profiler; the car moves while |speed| >= ``standstill`` m/s)."""
    from suspension_estimation.estimators.road_profile import Profiler

    p = Profiler(cutoff, reference)
    sp = np.abs(np.asarray(speed, float))
    ds = np.where(sp >= standstill, sp * h, 0.0).tolist()
    return np.array([p.step(r, h, d) for r, d in zip(np.asarray(road, float).tolist(), ds)])


def smooth_default(acc_sprung: np.ndarray, acc_unsprung: np.ndarray, susp_deflection: np.ndarray,
                   vehicle_speed: np.ndarray | float, parameters: dict | None = None, h: float = 1e-3,
                   blend_hz: float | None = None) -> dict[str, np.ndarray]:
    """Offline fixed-interval (RTS) smoothing of the default estimator (``road_estimator`` 2) over a
    recorded run (docs/smoothing.md). Sample k of each input is what the estimator was given at its
    k-th step of h s: acc_sprung, acc_unsprung (m/s^2), susp_deflection (m), vehicle_speed (m/s, an
    array or one value); ``parameters``: the estimator's, by the FMU's parameter names (the rest at
    their defaults). Returns arrays (K,) aligned with the inputs.

    1. The causal default runs over the inputs (``SuspensionEstimator``, the FMU's core). Per
       stretch between the payload changes it detected, the passes below use the model mass and
       identified damping it ended the stretch with; whether it kept the anchor (a suspension
       linear at low frequency) decides their models; the road class is the one it found (from
       the start: the first one it found).
    2. Two passes, each the Kalman filter of a model followed by its RTS smoother (``_kalman_pass``,
       ``_rts_pass``: ``rts_smooth`` of the filter's record x_k|k, P_k|k, F_k, Q_k), from the car at
       rest at t = 0 (x = 0, P = 0):
       - lo, the output below ``blend_hz`` (default the estimator's, anchored_road.blend_corner at
         h): the estimator's own model,
         the anchor's (exact, at the identified damping), or the force-error filter's
         (``model.force_error_matrices``, nominal mass and c_s) without the anchor; Q from the class
         max(class, q_class_min), the road held as the estimator has it;
       - hi, the output above it: the force-error filter's model with the road held over the step,
         as the plant has it, and the road intensity of the class found. Measured against the
         estimator's model in this band: HP error 2.00 -> 1.71 % (held road) and 2.06 -> 1.80 % (ISO
         B, class B's Q) in steady state (ISO C at 40 km/h unless said). Below the band the held
         road couples the common mode (the reference moves over the step, the held road does not)
         and the estimator's model stays.
       The models follow the speed (a new one when it has moved by ``speed_rebuild_tol``, at least
       0.1 m/s). A sample that is not finite, frozen for ``frozen_time`` or fails the gate
       y_i^2 <= outlier_nis S_ii is left out of the update (none left: a predict-only step).
    3. Output: x = x_hi + B (x_lo - x_hi), B the second-order Butterworth at blend_hz forwards and
       backwards (zero phase: exactly complementary); the heights plus ``reference_correction``
       (the model's reference follows the body, the road's own the road) and then q int z_r dt,
       q the smoothed output's lag below the band (``_lag``) as the estimator adds its own; without
       the anchor the exact model's q, as the estimator keeps the anchor's.
    4. road_height_std = sqrt(P_k|K[z_r, z_r] r): P_k|K lo's smoothed covariance, r the ratio of
       the steady-state output's real raw error on an ISO road of the class found (sensor noise
       and road through plant, smoothers and output; ``_steady``) to lo's fixed point of P_k|K.
       Without the anchor: ``Tuning.nonlinear_std_factor`` sqrt(max(P_k|K, its fixed point)). The
       error before the profile's high-pass: an upper bound of the profile's.
    5. road_height_est: the road of 3., as the estimator makes its output (``profile_of``).

    Returned keys: road_height_est, road_velocity_est, road_height_std, z_s_est, v_s_est, z_u_est,
    v_u_est, susp_deflection_est, tire_deflection_est (smoothed, the contract's units);
    causal_road_height_est, causal_road_height_std, causal_z_s_est (the causal run's); mass_model
    (kg), damping_model (N.s/m) per step, anchor (1 kept, 0 dropped) as the passes used them."""
    from suspension_estimation.estimators.model import (IVR, IVS, IVU, IZR, IZS, IZU, DiscreteModel,
                                                        measurement_covariance)
    from suspension_estimation.estimators.anchored_road import blend_corner
    from suspension_estimation.estimators.suspension import SuspensionEstimator
    from suspension_estimation.plant import iso8608

    a_s, a_u, d = (np.asarray(x, float).ravel() for x in (acc_sprung, acc_unsprung, susp_deflection))
    K = len(a_s)
    if len(a_u) != K or len(d) != K or K < 2:
        raise ValueError(f"smooth_default: inputs of {K}, {len(a_u)}, {len(d)} samples (at least 2, the same)")
    v = np.array(np.broadcast_to(np.asarray(vehicle_speed, float), (K,)))
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"smooth_default: step h = {h!r} must be finite and > 0")
    est = SuspensionEstimator(**(parameters or {}))
    cfg = est.cfg
    tun = cfg.tuning
    if int(cfg.road_estimator) != 2:
        raise ValueError(f"smooth_default smooths road_estimator 2, not {cfg.road_estimator}")
    blend_hz = float(blend_corner(tun.blend_hz, h, tun.blend_coarse_step, tun.blend_coarse_hz)
                     if blend_hz is None else blend_hz)

    # 1. the causal run
    causal, causal_std, causal_zs = np.empty(K), np.empty(K), np.empty(K)
    seg, cls = np.zeros(K, int), np.empty(K, int)
    mass, damp = np.empty(K), np.empty(K)
    me = est.mass_est
    for k in range(K):
        o = est.step(a_s[k], a_u[k], d[k], v[k], h)
        causal[k], causal_std[k], causal_zs[k] = o["road_height_est"], o["road_height_std"], o["z_s_est"]
        cls[k] = cfg.road_class or est.classifier.road_class  # 0 until the first one is identified
        mass[k] = est.m_model
        damp[k] = me.damping if me is not None and me.damping_identified else est.c_model
        if me is not None:
            seg[k] = me.resets
    anchor = est.anchor_trusted
    found = np.flatnonzero(cls)
    cls[cls == 0] = cls[found[0]] if found.size else int(tun.default_class)  # the first class found, from the start
    # per stretch between payload changes, the values it ended with (nonlinear: the nominal mass)
    last = np.r_[np.flatnonzero(np.diff(seg)), K - 1]
    first = np.r_[0, last[:-1] + 1]
    for i, j in zip(first, last):
        mass[i:j + 1] = mass[j] if anchor else cfg.m_s_nominal
        damp[i:j + 1] = damp[j] if anchor else cfg.c_s

    # 2. the two passes
    ok = np.isfinite(v)  # a non-finite speed: the last finite one, as the estimator keeps its model's
    speed = np.where(ok, v, 0.0)[np.maximum.accumulate(np.where(ok, np.arange(K), 0))]
    speed = np.maximum(np.abs(speed), 0.1)
    R = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std,
                               cfg.defl_noise_std if tun.use_deflection else None)
    z = np.column_stack([a_s, a_u, d] if tun.use_deflection else [a_s, a_u])
    live = _live(z, h, tun.frozen_time)
    build: dict = {}

    def model(key, force: bool, hold: bool, class_min: int) -> _Fixed:
        md = build.get((key, force, hold, class_min))
        if md is None:
            vm, m, c, cl = key
            veh = cfg.vehicle(m) if force else cfg.vehicle(m).with_(c_s=c)
            md = build[(key, force, hold, class_min)] = _fixed(DiscreteModel.build(
                veh, vm, iso8608.class_psd_n0(max(cl, class_min)), h, tun.road_model,
                est.road.noise if force else tun.model_noise, tun.use_deflection, int(cfg.acc_sampling), hold), R)
        return md

    keys, key_index, index = [], {}, np.empty(K, int)
    vm = None
    for k in range(K):
        if vm is None or abs(speed[k] - vm) > tun.speed_rebuild_tol * vm:
            vm = float(speed[k])
        key = (vm, float(mass[k]), float(damp[k]), int(cls[k]))
        i = key_index.get(key)
        if i is None:
            i = key_index[key] = len(keys)
            keys.append(key)
        index[k] = i
    # above blend_hz the force-error filter with the road held over the step, as the plant has it,
    # and the road intensity of the class found; below it the estimator's own model
    hi_models = [model(key, True, True, 1) for key in keys]
    lo_models = [model(key, not anchor, est.road.road_hold, int(tun.q_class_min)) for key in keys]
    passes = {}
    for name, models in (("hi", hi_models), ("lo", lo_models)):
        if name == "lo" and models[0] is hi_models[0]:
            passes["lo"] = passes["hi"]
            break
        xs, xp, Ps = _kalman_pass(models, index, z, live, tun.outlier_nis)
        passes[name] = _rts_pass(models, index, xs, xp, Ps, (IZR,))
        del xs, xp, Ps
    x = _blend(passes["hi"][0][:, :6], passes["lo"][0][:, :6], blend_hz, h)
    var = passes["lo"][1][:, 0]

    # 3. the output transform, 4. the std
    rm = tun.road_model
    heights = [IZS, IZU, IZR]
    x[:, heights] += reference_correction(x[:, IZS], x[:, IZR], h, rm)[:, None]
    steady: dict = {}
    per_model = np.empty((len(keys), 3))
    for i, key in enumerate(keys):
        vm_, m_, c_, cl = key
        skey = (round(np.log(vm_) / np.log(1.05)), m_, c_, cl)  # speed within 5 %, as the estimator
        if skey not in steady:
            hi, lo = hi_models[i], lo_models[i]
            # without the anchor the estimator keeps the anchor's q (its _honest_ratio is cached
            # per class and speed); the force-error filter's own, ~1.2e-2 1/s, is not a lag
            # (docs/real-roads.md)
            ex = lo if anchor else model(key, False, est.road.road_hold, int(tun.q_class_min))
            qk = _lag(hi if anchor else ex, ex, h, blend_hz, rm, int(cfg.acc_sampling))
            real, p = _steady(hi, lo, h, blend_hz, rm, iso8608.class_psd_n0(cl), int(cfg.acc_sampling), qk)
            r = real / p if p > 0 else np.nan
            steady[skey] = (qk, r if 0.0 < r <= 1e3 else 1.0, p)  # garbage from an ill-conditioned vehicle: 1
        per_model[i] = steady[skey]
    q, ratio, p_fixed = per_model[index, 0], per_model[index, 1], per_model[index, 2]
    x[:, heights] += (np.cumsum(q * x[:, IZR]) * h)[:, None]
    # without the anchor the force-error filter's error is not one built up from rest (the
    # estimator's _distrust_anchor): at least its fixed point's
    std = np.sqrt(var * ratio) if anchor else np.sqrt(np.maximum(var, p_fixed)) * tun.nonlinear_std_factor
    # 5. the profile, as the estimator reports it: the smoothed road freed of the reference and
    # high-passed in distance while the car moves
    road = profile_of(x[:, IZR], v, h, cfg.profile_cutoff, tun.standstill_speed, (rm.f_ref, rm.zeta_ref))
    return {"road_height_est": road, "road_velocity_est": x[:, IVR], "road_height_std": std,
            "z_s_est": x[:, IZS], "v_s_est": x[:, IVS], "z_u_est": x[:, IZU], "v_u_est": x[:, IVU],
            "susp_deflection_est": x[:, IZS] - x[:, IZU], "tire_deflection_est": x[:, IZU] - x[:, IZR],
            "causal_road_height_est": causal, "causal_road_height_std": causal_std, "causal_z_s_est": causal_zs,
            "mass_model": mass, "damping_model": damp, "anchor": np.full(K, 1.0 if anchor else 0.0)}
