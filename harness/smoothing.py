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
FMU_STATES = ("z_s_est", "v_s_est", "z_u_est", "v_u_est", "road_height_est", "road_velocity_est")


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
    Returns the smoothed samples under the same names, plus ``susp_deflection_est`` and
    ``tire_deflection_est``."""
    F, Q, P = fmu_model(parameters, speed, h, road_class, road_hold)
    x = np.stack([np.asarray(outputs[k], float) for k in FMU_STATES], axis=-1)
    K = x.shape[-2]
    xs, _ = rts_smooth(FilterRecord(x, np.broadcast_to(P, (K,) + P.shape), F, Q))
    out = {k: xs[..., i] for i, k in enumerate(FMU_STATES)}
    out["susp_deflection_est"] = out["z_s_est"] - out["z_u_est"]
    out["tire_deflection_est"] = out["z_u_est"] - out["road_height_est"]
    return out
