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
