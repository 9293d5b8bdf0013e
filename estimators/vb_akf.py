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
  its choice of the R forgetting. On our 6-state model at 5 ms with the paper's prior weight 5
  (``harness.studies.vb.noise_growth``, docs/vb-akf.md) tau = 0.8 pulls the PECM towards the
  posterior (Sigma = (0.8 P^- + P + d d') / 1.8), its R estimate does not follow a 4x noise
  growth and it loses to the fixed-R KF; tau = inf tracks the changed R. ``VBRoadFilter`` (the
  FMU's road_estimator 4) restarts R with a larger weight and there both follow it.
- The covariance update is the simple form Sigma - K H Sigma (the code's), symmetrised.

``vb_update`` works on a single filter or on a stack of independent filters (leading axes:
Monte-Carlo runs); u is one number for all of them, or one per filter (filters whose R prior was
restarted at different steps, e.g. by a road classifier in the loop).
"""
from __future__ import annotations

import math

import numpy as np

from ..plant import iso8608
from .interface import RoadFilter
from .kalman import stationary_covariance
from .model import DiscreteModel, measurement_covariance
from .response_class import ResponseClassifier, load_model

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


def vb_update_r_only(x_pred: np.ndarray, P_pred: np.ndarray, z: np.ndarray, H: np.ndarray, u: float,
                     U: np.ndarray, rho: float = RHO, n_iter: int = N_ITER
                     ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """``vb_update`` with tau = inf (R only) for one filter, iterated in measurement space.

    With Sigma = P^- fixed, every quantity the iterations need is an m x m one: with
    A = H P^- H', r = z - H x^-, S_i = A + R_i and G_i = A S_i^-1,
        H P_i H' = A - G_i A,   z - H x_i = r - G_i r,
    so only the last iterate forms the n-dimensional K, x and P. For m = 3 the iterations run on
    plain floats (a 3 x 3 symmetric inverse by cofactors), cheaper than numpy's per-call cost on
    such small matrices. Same result as ``vb_update`` (tests/test_vb_akf.py)."""
    return _r_only(x_pred, P_pred, z, H, u, U, rho, n_iter)[:4]


def _r_only(x_pred, P_pred, z, H, u, U, rho, n_iter):
    """``vb_update_r_only`` and the NIS r' S_0^-1 r of the prior (S_0 = A + the prior mean of R)."""
    m = H.shape[0]
    u_pre = rho * u
    if u_pre <= m + 1:
        raise ValueError(f"rho * u = {u_pre!r} must exceed m + 1 = {m + 1} (IW mean undefined)")
    PHT = P_pred @ H.T
    A = H @ PHT
    r = z - H @ x_pred
    if m == 3:
        Si, U_post, nis = _iterate3(A.tolist(), r.tolist(), (rho * U).tolist(), u_pre, n_iter)
    else:
        U_pre = rho * U
        R = U_pre / (u_pre - m - 1)
        for i in range(n_iter):
            Si = np.linalg.inv(A + R)
            if i == 0:
                nis = float(r @ Si @ r)
            G = A @ Si
            e = r - G @ r
            U_post = U_pre + (A - G @ A) + np.outer(e, e)
            R = U_post / (u_pre - m)
    K = PHT @ Si
    x = x_pred + K @ r
    P = P_pred - K @ PHT.T
    return x, _sym(P), u_pre + 1.0, _sym(U_post), nis


def _iterate3(A: list, r: list, Up: list, u_pre: float, n_iter: int) -> tuple[np.ndarray, np.ndarray, float]:
    """The R-only fixed point of ``vb_update_r_only`` for m = 3 on floats: (S^-1 and U of the last
    iterate as arrays, the NIS of the first). A, Up symmetric 3 x 3 (lists), r 3 floats."""
    a00, a01, a02 = A[0]
    a11, a12, a22 = A[1][1], A[1][2], A[2][2]
    p00, p01, p02 = Up[0]
    p11, p12, p22 = Up[1][1], Up[1][2], Up[2][2]
    r0, r1, r2 = r
    c = 1.0 / (u_pre - 3.0)  # R = U / (u - m - 1) with u = u_pre + 1 after the update
    c0 = 1.0 / (u_pre - 4.0)  # the prior mean U_pre / (u_pre - m - 1)
    R00, R01, R02, R11, R12, R22 = p00 * c0, p01 * c0, p02 * c0, p11 * c0, p12 * c0, p22 * c0
    nis = None
    for _ in range(n_iter):
        s00, s01, s02, s11, s12, s22 = a00 + R00, a01 + R01, a02 + R02, a11 + R11, a12 + R12, a22 + R22
        k00 = s11 * s22 - s12 * s12
        k01 = s02 * s12 - s01 * s22
        k02 = s01 * s12 - s02 * s11
        d = 1.0 / (s00 * k00 + s01 * k01 + s02 * k02)
        i00, i01, i02 = k00 * d, k01 * d, k02 * d
        i11 = (s00 * s22 - s02 * s02) * d
        i12 = (s01 * s02 - s00 * s12) * d
        i22 = (s00 * s11 - s01 * s01) * d
        # G = A S^-1
        g00 = a00 * i00 + a01 * i01 + a02 * i02
        g01 = a00 * i01 + a01 * i11 + a02 * i12
        g02 = a00 * i02 + a01 * i12 + a02 * i22
        g10 = a01 * i00 + a11 * i01 + a12 * i02
        g11 = a01 * i01 + a11 * i11 + a12 * i12
        g12 = a01 * i02 + a11 * i12 + a12 * i22
        g20 = a02 * i00 + a12 * i01 + a22 * i02
        g21 = a02 * i01 + a12 * i11 + a22 * i12
        g22 = a02 * i02 + a12 * i12 + a22 * i22
        e0 = r0 - (g00 * r0 + g01 * r1 + g02 * r2)
        e1 = r1 - (g10 * r0 + g11 * r1 + g12 * r2)
        e2 = r2 - (g20 * r0 + g21 * r1 + g22 * r2)
        if nis is None:
            nis = (r0 * (i00 * r0 + i01 * r1 + i02 * r2) + r1 * (i01 * r0 + i11 * r1 + i12 * r2)
                   + r2 * (i02 * r0 + i12 * r1 + i22 * r2))
        # U = U_pre + (A - G A) + e e'
        u00 = p00 + a00 - (g00 * a00 + g01 * a01 + g02 * a02) + e0 * e0
        u01 = p01 + a01 - (g00 * a01 + g01 * a11 + g02 * a12) + e0 * e1
        u02 = p02 + a02 - (g00 * a02 + g01 * a12 + g02 * a22) + e0 * e2
        u11 = p11 + a11 - (g10 * a01 + g11 * a11 + g12 * a12) + e1 * e1
        u12 = p12 + a12 - (g10 * a02 + g11 * a12 + g12 * a22) + e1 * e2
        u22 = p22 + a22 - (g20 * a02 + g21 * a12 + g22 * a22) + e2 * e2
        R00, R01, R02, R11, R12, R22 = u00 * c, u01 * c, u02 * c, u11 * c, u12 * c, u22 * c
    Si = np.array([[i00, i01, i02], [i01, i11, i12], [i02, i12, i22]])
    U_post = np.array([[u00, u01, u02], [u01, u11, u12], [u02, u12, u22]])
    return Si, U_post, nis


# --------------------------------------------------------------------------------------------------
# road_estimator 4: the VB-AKF on our vehicle model, its nominal Q scheduled by the response class
# --------------------------------------------------------------------------------------------------
# Ranges of the contract's VB parameters (mirrored in EstimatorConfig, checked by ``vb_problems``)
VB_ITERATIONS_RANGE = (1, 50)
VB_FORGETTING_RANGE = (0.9, 1.0)  # (low exclusive, high inclusive]
VB_TAU_RANGE = (0.0, 1e6)  # 0 = no PECM adaptation (R only)
# the shipped response-classifier model (package data), read once at import: a host may delete the
# folder an FMU was extracted to while the process still runs other instances of the same build
RESPONSE_MODEL = load_model()


def vb_problems(cfg) -> list[str]:
    """Messages naming each invalid VB parameter of an ``EstimatorConfig`` and its allowed range."""
    msgs = []
    n = cfg.vb_iterations
    lo, hi = VB_ITERATIONS_RANGE
    if isinstance(n, bool) or not float(n).is_integer() or not lo <= n <= hi:
        msgs.append(f"vb_iterations = {n!r} must be an integer in [{lo}, {hi}]")
    rho = float(cfg.vb_forgetting)
    if not VB_FORGETTING_RANGE[0] < rho <= VB_FORGETTING_RANGE[1]:
        msgs.append(f"vb_forgetting = {cfg.vb_forgetting!r} is outside the allowed range "
                    f"({VB_FORGETTING_RANGE[0]:g}, {VB_FORGETTING_RANGE[1]:g}]")
    tau = float(cfg.vb_tau)
    if not VB_TAU_RANGE[0] <= tau <= VB_TAU_RANGE[1]:
        msgs.append(f"vb_tau = {cfg.vb_tau!r} is outside the allowed range "
                    f"[{VB_TAU_RANGE[0]:g}, {VB_TAU_RANGE[1]:g}]")
    return msgs


class VBRoadFilter(RoadFilter):
    """``road_estimator`` 4 (a ``RoadFilter``, estimators/interface.py): the causal VB-AKF
    (``vb_update``) on OUR discrete quarter-car + road model (``estimators.model``, built from the
    ``EstimatorConfig``: 6 states, or 8 with ``acc_sampling`` 1), its nominal Q scheduled by the
    road class that ``response_class.ResponseClassifier`` finds from the three measurements.

    - Class: ``road_class`` 0 = the response classifier (2 s blocks of a_s, a_u, deflection and
      the speed; ``default_class`` until its first block), 1..8 = that class fixed. The nominal Q
      is the model's at Gd(n0) of the class (paper 004: the class sets the nominal noise).
    - R: the prior mean is the configured sensor noise (``measurement_covariance``). On our car
      the sensor noise does not depend on the road, so the class does not change the nominal R;
      as in the authors' code the R prior restarts at the nominal when the class changes.
    - ``vb_iterations`` = N, ``vb_forgetting`` = rho, ``vb_tau`` = tau (0: no PECM adaptation,
      tau = inf of ``vb_update``, run by ``vb_update_r_only``: the FMU default. Through the FMU
      both follow a body accelerometer whose noise grows 4x and beat the KF; R only is better on
      the deflections (0.44-0.47x the KF's against 0.56-0.63x with tau = 0.8) and cheaper;
      docs/vb-akf.md).
    - The road is held over the step in the model (``road_hold`` -1 or 1; 0 = not), the
      co-simulation convention of our plant FMU. The KF family holds it only with
      ``acc_sampling`` 1 and lives with the mismatch at 1 ms; the VB takes the innovations that
      mismatch leaves for sensor noise (without the hold, ISO C at 40 km/h and 1 ms: a
      deflection noise estimated up to 17x its true std and a deflection error 5-15x the KF's).
    - The R prior restarts with the weight u = 1 / (1 - rho) (the stationary weight of the
      forgetting, u = rho u + 1), not the paper's 5: with 5 the first samples alone set R.
    - The model is rebuilt (x and P kept) when the step, the class, the mass fed back
      (``set_mass``) or the speed (by ``speed_rebuild_tol``) changes.
    - A step with a channel missing (``rows``): the nominal prediction, then a plain KF update of
      the valid rows with the current R estimate; the R posterior is left as it was (no
      forgetting, no data). No channel: prediction only.
    - Start and ``reset``: x = 0, P the stationary posterior covariance of the KF of the nominal
      model (``kalman.stationary_covariance``), the R prior at the nominal.
    Attributes beyond ``RoadFilter``'s: ``road_class`` (the class in force, for ``road_class_est``),
    ``R_estimate`` (the IW mean of R), ``class_changes``."""

    def __init__(self, cfg):
        msgs = vb_problems(cfg)
        if msgs:
            raise ValueError("; ".join(msgs))
        self.cfg = cfg
        self.n_iter = int(cfg.vb_iterations)
        self.rho = float(cfg.vb_forgetting)
        self.tau = math.inf if float(cfg.vb_tau) == 0.0 else float(cfg.vb_tau)
        # weight of the R prior at a (re)start: the stationary weight of the forgetting,
        # u = rho u + 1 -> 1 / (1 - rho) (the paper's 5 lets the first samples decide R alone)
        m = 3 if cfg.tuning.use_deflection else 2
        self.u0 = max(DOF, min(1.0 / (1.0 - self.rho), 1e6)) if self.rho < 1.0 else 1e6
        if self.rho * self.u0 <= m + 1:
            raise ValueError(f"vb_forgetting = {self.rho!r}: rho * {self.u0:g} must exceed {m + 1}")
        self.R_nominal = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std,
                                                cfg.defl_noise_std if cfg.tuning.use_deflection else None)
        self.fixed_class = int(cfg.road_class)
        self.classifier = (ResponseClassifier(RESPONSE_MODEL, initial=int(cfg.tuning.default_class))
                           if self.fixed_class == 0 else None)
        self.road_class = self.fixed_class or int(cfg.tuning.default_class)
        self.m_s = float(cfg.m_s_nominal)
        self.h: float | None = None
        self.model = None
        self._key: tuple | None = None
        self.model_builds = 0
        self.class_changes = 0
        self.mass: float | None = None
        self.nis = 0.0
        self.road_variance = 0.0
        self._x = None
        self.P = None
        self._P0 = None  # the stationary covariance the filter restarts from
        self.x = [0.0] * 6
        self._restart_noise()

    # -- model ------------------------------------------------------------------------------
    def _restart_noise(self) -> None:
        m = self.R_nominal.shape[0]
        u = self.u0
        self.u, self.U = u, (u - m - 1) * self.R_nominal.copy()

    @property
    def R_estimate(self) -> np.ndarray:
        """Mean of the R posterior U / (u - m - 1) (units of z squared)."""
        return self.U / (self.u - self.U.shape[0] - 1)

    def _build(self, speed: float, h: float) -> None:
        cfg = self.cfg
        hold = cfg.tuning.road_hold != 0  # -1 (automatic) holds the road here: see the class doc
        self.model = DiscreteModel.build(cfg.vehicle(self.m_s), max(speed, 0.1),
                                         iso8608.class_psd_n0(self.road_class), h, cfg.tuning.road_model,
                                         cfg.tuning.model_noise, cfg.tuning.use_deflection, int(cfg.acc_sampling), hold)
        self.h, self._key = h, (h, self.road_class, self.m_s, speed)
        self.model_builds += 1
        if self._x is None:
            n = self.model.Phi.shape[0]
            self._x = np.zeros(n)
            sol = stationary_covariance(self.model.Phi, self.model.Q, self.model.H, self.R_nominal)
            self.P = sol[1] if sol is not None else np.eye(n) * 1e-6
            self._P0 = self.P.copy()

    def _due(self, speed: float, h: float) -> bool:
        if self._key is None:
            return True
        h0, c0, m0, v0 = self._key
        return (h != h0 or c0 != self.road_class or m0 != self.m_s
                or abs(speed - v0) > self.cfg.tuning.speed_rebuild_tol * max(v0, 0.1))

    # -- RoadFilter -------------------------------------------------------------------------
    def step(self, z: np.ndarray, rows: np.ndarray | None, speed: float, h: float) -> None:
        """One sample (interface.RoadFilter.step): the class, the model, then the VB step."""
        if self.classifier is not None and rows is None:
            c = int(self.classifier.update(z, speed, h))
            if c != self.road_class:
                self.road_class = c
                self.class_changes += 1
                self._restart_noise()
        if self._due(speed, h):
            self._build(speed, h)
        M = self.model
        xp = M.Phi @ self._x
        Pp = M.Phi @ self.P @ M.Phi.T + M.Q
        H = M.H
        if rows is None:
            if math.isinf(self.tau):
                self._x, self.P, self.u, self.U, self.nis = _r_only(xp, Pp, z, H, self.u, self.U, self.rho,
                                                                    self.n_iter)
            else:
                S = H @ Pp @ H.T + self.R_estimate
                r = z - H @ xp
                self.nis = float(r @ np.linalg.solve(S, r))
                self._x, self.P, self.u, self.U = vb_update(xp, Pp, z, H, self.u, self.U, self.rho, self.tau,
                                                            self.n_iter)
        elif len(rows):
            Hr = H[rows]
            S = Hr @ Pp @ Hr.T + self.R_estimate[np.ix_(rows, rows)]
            K = np.linalg.solve(S, Hr @ Pp).T
            r = z[rows] - Hr @ xp
            self.nis = float(r @ np.linalg.solve(S, r))
            self._x = xp + K @ r
            self.P = _sym(Pp - K @ Hr @ Pp)
        else:
            self._x, self.P, self.nis = xp, Pp, 0.0
        self.x = self._x[:6].tolist()
        self.road_variance = float(self.P[4, 4])

    def set_mass(self, m_s: float) -> None:
        """The sprung mass (kg) fed back by the composer's RLS: the model is rebuilt at it."""
        self.m_s = float(m_s)

    def reset(self) -> None:
        """Zero state at the start covariance, R prior at the nominal."""
        if self._x is not None:
            self._x = np.zeros_like(self._x)
            self.P = self._P0.copy()
        self.x = [0.0] * 6
        self._restart_noise()
