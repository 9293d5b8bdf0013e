"""Variational-Bayes adaptive Kalman filter (VB-AKF) of paper 004, causal forward pass only.

Paper 004: a state estimator for a quarter-car suspension with time-varying, unknown noise
covariances, built on the VB-AKF of Huang, Zhang, Wu, Chambers (IEEE TAC 2018, the paper's
ref. [29]): the predicted error covariance P_k|k-1 ("PECM") and the measurement noise
covariance R_k ("MNCM") get inverse-Wishart (IW) priors and are inferred jointly with the state
by N fixed-point iterations per step (paper 004 eqs. 21-32, Algorithm 1). The paper's copy we
have lost its equations, so every formula below is the one of the authors' published code
(its function ``My_filter``), which Algorithm 1 describes; the smoother the paper appends
(its "Backward Process") is not part of this causal filter: see ``harness.smoothing``.

IW(X; u, U) is the density prop. to |X|^-(u+m+1)/2 exp(-tr(U X^-1)/2) of an m x m matrix,
mean U / (u - m - 1) (scipy.stats.invwishart(df=u, scale=U)). One step k:

    x^- = F x,  P^- = F P F' + Q                               (nominal prediction, eq. 8)
    u^- = rho u,   U^- = rho U                                 (R forgetting, eq. 28)
    t^- = tau + n + 1,  T^- = tau P^-                          (PECM prior, eq. 28; mean P^-)
    R_0 = U^- / (u^- - m - 1),  Sigma_0 = P^-
    for i = 0 .. N-1:                                          (fixed point, eqs. 29-32)
        K = Sigma_i H' (H Sigma_i H' + R_i)^-1
        x_i = x^- + K (z - H x^-),  P_i = Sigma_i - K H Sigma_i
        T = T^- + P_i + (x_i - x^-)(x_i - x^-)',  t = t^- + 1
        U = U^- + H P_i H' + (z - H x_i)(z - H x_i)',  u = u^- + 1
        Sigma_{i+1} = T / (t - n - 1),  R_{i+1} = U / (u - m - 1)
    x, P = x_N-1, P_N-1;  (u, U) carried to the next step

The IW update of R is the exact conjugate posterior of R given the Gaussian q(x) = N(x_i, P_i)
(tested against scipy.stats.invwishart in tests/test_vb_akf.py); likewise for P^- given q(x).

Choices where the paper is silent or differs from its code (the code is followed):
- Only R is carried between steps (through u, U with the forgetting factor rho). The PECM prior
  is rebuilt every step from the NOMINAL prediction, t^- = tau + n + 1, T^- = tau P^-, so its
  prior mean is P^- and tau (dimensionless) is its weight against the data of this step; the
  nominal Q itself is never adapted (the paper's "Q" adaptation is this PECM adaptation).
- The iterate uses the IW MEAN U / (u - m - 1) (paper: "the expected value of the IW
  distribution"), not E[R^-1]^-1 = U / u of the strict VB fixed point; likewise for Sigma.
- The estimate is the LAST iterate (x_N-1, P_N-1): the paper's eqs. 36-38 describe an average
  over the N iterates, the authors' code does not do it.
- The prior of R: u_0 = ``dof`` (5 in the paper and code, which needs m <= 3: u_0 > m + 1),
  U_0 = (dof - m - 1) R_nominal, so the prior mean is R_nominal (the code's U_0 = R_nominal with
  dof 5 and m = 3 is the same). The code restarts (u, U) at the nominal of each road class when
  the class changes; ``reset_noise`` does that.
- rho = 1 - e^-4 gives an R memory of 1 / (1 - rho) = 55 steps; tau = 0.8; N = 6.
- tau = inf switches the PECM adaptation off (Sigma = P^- in every iteration): the R-only
  VB-AKF of Sarkka and Nummenmaa (IEEE TAC 2009), the paper's "VBAKF-R" comparison filter up to
  its choice of the R forgetting. On our 6-state model (docs/vb-akf.md) tau = 0.8 pulls the
  PECM towards the posterior (Sigma = (0.8 P^- + P + d d') / 1.8), its R estimate does not
  follow a 4x noise growth and it loses to the fixed-R KF; tau = inf tracks the changed R.
- The covariance update is the simple form Sigma - K H Sigma (the code's), symmetrised.

``vb_update`` works on a single filter or on a stack of independent filters (leading axes:
Monte-Carlo runs); u is one number for all of them, or one per filter (filters whose R prior was
restarted at different steps, e.g. by a road classifier in the loop).
"""
from __future__ import annotations

import math

import numpy as np

RHO = 1.0 - math.exp(-4.0)  # forgetting factor of the R posterior (dimensionless)
TAU = 0.8  # weight of the nominal prediction in the PECM prior (dimensionless)
N_ITER = 6  # fixed-point iterations per step
DOF = 5.0  # initial IW degrees of freedom of R


def _t(a: np.ndarray) -> np.ndarray:
    return np.swapaxes(a, -1, -2)


def _sym(a: np.ndarray) -> np.ndarray:
    return 0.5 * (a + _t(a))


def vb_update(x_pred: np.ndarray, P_pred: np.ndarray, z: np.ndarray, H: np.ndarray,
              u: float | np.ndarray, U: np.ndarray, rho: float = RHO, tau: float = TAU,
              n_iter: int = N_ITER) -> tuple[np.ndarray, np.ndarray, float | np.ndarray, np.ndarray]:
    """One VB measurement update (module doc; paper 004 eqs. 28-32, Algorithm 1).

    x_pred (..., n), P_pred (..., n, n): the nominal prediction; z (..., m) the measurement;
    H (m, n); u (dimensionless, a number or one per filter: shape ...) and U (..., m, m) the IW
    parameters of R after the previous step; tau = inf: no PECM adaptation (R only).
    Returns (x, P, u, U) after this step. Units: those of the state and of z."""
    m = H.shape[0]
    if n_iter < 1:
        raise ValueError(f"n_iter = {n_iter!r} must be at least 1")
    u_pre = rho * (u if np.isscalar(u) else np.asarray(u, float))
    U_pre = rho * U
    if np.any(u_pre <= m + 1):
        raise ValueError(f"rho * u = {np.min(u_pre)!r} must exceed m + 1 = {m + 1} (IW mean undefined)")
    uw = u_pre if np.isscalar(u_pre) else u_pre[..., None, None]  # broadcast over (m, m)
    adapt_P = math.isfinite(tau)
    T_pre = tau * P_pred if adapt_P else None
    Sigma, R = P_pred, U_pre / (uw - m - 1)
    HT = H.T
    z_pred = x_pred @ HT
    r = z - z_pred
    SHT = Sigma @ HT
    HSHT = H @ SHT
    for i in range(n_iter):
        if i and adapt_P:
            SHT = Sigma @ HT
            HSHT = H @ SHT
        K = SHT @ np.linalg.inv(HSHT + R)  # Sigma H' S^-1 (inv: faster than solve for m = 3)
        x = x_pred + (K @ r[..., None])[..., 0]
        P = Sigma - K @ _t(SHT)
        e = z - x @ HT
        U_post = U_pre + H @ P @ HT + e[..., :, None] * e[..., None, :]
        if i == n_iter - 1:
            break  # (u, U) of the last iterate are what the code carries to the next step
        R = U_post / (uw - m)  # U / (u - m - 1) with u = u_pre + 1
        if adapt_P:
            d = x - x_pred
            Sigma = (T_pre + P + d[..., :, None] * d[..., None, :]) / (tau + 1.0)  # T / (t - n - 1)
    return x, _sym(P), u_pre + 1.0, _sym(U_post)


class VBAKF:
    """Causal VB-AKF on a linear model x_k = F x_k-1 + w (cov Q), z_k = H x_k + v (cov R_k).

    ``R_nominal`` is the prior mean of R; F, Q, H may be replaced between steps (``set_model``)
    and the R prior restarted (``reset_noise``). Attributes after a step: x, P (posterior),
    x_prior, P_prior (the nominal prediction), u, U (IW of R) and ``R_estimate`` (its mean)."""

    def __init__(self, F: np.ndarray, Q: np.ndarray, H: np.ndarray, R_nominal: np.ndarray,
                 x0: np.ndarray | None = None, P0: np.ndarray | None = None,
                 rho: float = RHO, tau: float = TAU, n_iter: int = N_ITER, dof: float = DOF):
        self.F, self.Q, self.H = np.asarray(F, float), np.asarray(Q, float), np.asarray(H, float)
        n = self.F.shape[0]
        self.x = np.zeros(n) if x0 is None else np.array(x0, float)
        self.P = np.zeros((n, n)) if P0 is None else np.array(P0, float)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        if not 0.0 < rho <= 1.0:
            raise ValueError(f"rho = {rho!r} must be in (0, 1]")
        if tau <= 0.0:
            raise ValueError(f"tau = {tau!r} must be positive")
        if int(n_iter) < 1:
            raise ValueError(f"n_iter = {n_iter!r} must be at least 1")
        self.rho, self.tau, self.n_iter = float(rho), float(tau), int(n_iter)
        if self.H.shape[1] != n:
            raise ValueError(f"H has {self.H.shape[1]} columns, the state {n} entries")
        self.reset_noise(R_nominal, dof)

    def reset_noise(self, R_nominal: np.ndarray, dof: float = DOF) -> None:
        """Restart the IW prior of R at mean ``R_nominal`` with ``dof`` degrees of freedom."""
        m = self.H.shape[0]
        if self.rho * dof <= m + 1:
            raise ValueError(f"rho * dof = {self.rho * dof!r} must exceed m + 1 = {m + 1}")
        self.u = float(dof)
        self.U = (dof - m - 1) * np.array(R_nominal, float)

    def set_model(self, F: np.ndarray | None = None, Q: np.ndarray | None = None,
                  H: np.ndarray | None = None) -> None:
        if F is not None:
            self.F = np.asarray(F, float)
        if Q is not None:
            self.Q = np.asarray(Q, float)
        if H is not None:
            self.H = np.asarray(H, float)

    @property
    def R_estimate(self) -> np.ndarray:
        """Mean of the R posterior, U / (u - m - 1) (units of z squared)."""
        return self.U / (self.u - self.H.shape[0] - 1)

    def step(self, z: np.ndarray) -> None:
        """Nominal prediction, then ``vb_update`` with the measurement z."""
        F = self.F
        self.x_prior = F @ self.x
        self.P_prior = F @ self.P @ F.T + self.Q
        self.x, self.P, self.u, self.U = vb_update(
            self.x_prior, self.P_prior, np.asarray(z, float), self.H, self.u, self.U,
            self.rho, self.tau, self.n_iter)
