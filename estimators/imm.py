"""Interacting multiple model (IMM) estimator over a bank of linear Kalman filters.

Paper 002 (the IMMAKF paper), eqs. 18-32: r Kalman filters, one per sub-model (here one per
sprung mass), mixed at every step by their model probabilities mu (dimensionless, summing to 1)
under a Markov chain of model switches with transition probabilities p_ji (from model j to i):

    mixing (eqs. 18-20)    cbar_i = sum_j p_ji mu_j,   mu_ji = p_ji mu_j / cbar_i,
                           x0_i = sum_j mu_ji x_j,   P0_i = sum_j mu_ji [P_j + (x_j - x0_i)(x_j - x0_i)']
    filters (eqs. 21-25)   x_i = Phi_i x0_i,  P_i = Phi_i P0_i Phi_i' + Q_i,  S_i = H_i P_i H_i' + R,
                           K_i = P_i H_i' S_i^-1,  x_i += K_i d_i,  d_i = z - H_i x_i (innovation)
    probabilities (26-30)  Lambda_i = N(d_i; 0, S_i),  mu_i = Lambda_i cbar_i / c,  c = sum_i Lambda_i cbar_i
    combination (31-32)    x = sum_i mu_i x_i,   P = sum_i mu_i [P_i + (x_i - x)(x_i - x)']

Printed slips, fixed here:
- eq. 30 prints c = Lambda_i / (sum Lambda_i) * sum_j p_ji mu_j, which depends on i and does not
  make the mu_i sum to one; the normaliser of eq. 29 is c = sum_i Lambda_i cbar_i (Bar-Shalom,
  Li, Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 11.6.6).
- eq. 26 prints 1 / sqrt(2 pi^N det|S|); the Gaussian density has 1 / sqrt((2 pi)^N det S).
- eqs. 27 and 28 print the innovation twice and S_i nowhere: S_i = H_i P_i H_i' + R (above).
- eq. 23 writes the gain as a fraction; with several measurements it is P H' S^-1.
- eq. 25 gives P = (I - K H) P; the Joseph form (I - K H) P (I - K H)' + K R K' is used, equal
  in exact arithmetic and kept symmetric and positive in rounding (also filterpy's form).

The probabilities are updated with LOG-likelihoods, log mu_i = log Lambda_i + log cbar_i - log c:
at 1 kHz with three sensors a model that is wrong by tens of kilograms has innovations of many
standard deviations, and Lambda_i = exp(-0.5 d' S^-1 d) / ... underflows to 0 in double
precision for every model at once (filterpy's KalmanFilter then reports the smallest float, and
the probabilities become meaningless). Written by hand, not filterpy's ``IMMEstimator``, for
that and for speed: the r filters are advanced together as stacked numpy arrays instead of r
``KalmanFilter`` objects with Python loops (tests/test_imm.py checks equality with filterpy on
data where filterpy does not underflow).

The sprung mass is the probability-weighted mass of the bank, m = sum_i mu_i m_i (kg).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from plant.vehicle import Vehicle

from .model import DiscreteModel, ModelNoise, RoadModel

LOG_2PI = float(np.log(2.0 * np.pi))


def transition_matrix(r: int, stay: float) -> np.ndarray:
    """(r, r) matrix p[j, i] of switching from model j to model i (rows sum to 1): ``stay`` on the
    diagonal and the rest shared equally among the other models."""
    if r < 2:
        raise ValueError(f"an IMM needs at least 2 models, got {r}")
    if not 0.0 < stay < 1.0:
        raise ValueError(f"stay = {stay!r} must be in (0, 1)")
    p = np.full((r, r), (1.0 - stay) / (r - 1))
    np.fill_diagonal(p, stay)
    return p


class IMM:
    """IMM over r linear Kalman filters x_k = Phi_i x_{k-1} + w (cov Q_i), z_k = H_i x_k + v (cov R).

    ``Phi``, ``Q``: (r, n, n) or sequences of r (n, n) arrays; ``H``: (r, m, n) or one (m, n) for
    all; ``R`` (m, m); ``transition`` (r, r) with transition[j, i] the probability of switching
    from model j to model i per step (rows sum to 1); ``mu`` the initial model probabilities
    (default equal); ``x``, ``P`` the initial state and covariance of every filter.

    After ``step(z)``: ``x``, ``P`` (eqs. 31-32), ``mu``, ``xs``, ``Ps`` (each filter's posterior),
    ``log_likelihood`` (each filter's log N(d_i; 0, S_i)), ``cbar``.
    """

    def __init__(self, Phi, Q, H, R: np.ndarray, transition: np.ndarray, mu: np.ndarray | None = None,
                 x: np.ndarray | None = None, P: np.ndarray | None = None):
        self.Phi = np.array(Phi, float)
        self.Q = np.array(Q, float)
        r, n = self.Phi.shape[0], self.Phi.shape[1]
        H = np.array(H, float)
        self.H = np.broadcast_to(H, (r,) + H.shape[-2:]).copy() if H.ndim == 2 else H
        self.R = np.array(R, float)
        self.M = np.array(transition, float)
        if self.Phi.shape != (r, n, n) or self.Q.shape != (r, n, n) or self.H.shape[::2] != (r, n):
            raise ValueError(f"Phi, Q must be (r, n, n) and H (r, m, n): got {self.Phi.shape}, {self.Q.shape}, "
                             f"{self.H.shape}")
        if r < 2:
            raise ValueError(f"an IMM needs at least 2 models, got {r}")
        if self.M.shape != (r, r) or np.any(self.M < 0) or not np.allclose(self.M.sum(axis=1), 1.0, atol=1e-12):
            raise ValueError(f"transition must be ({r}, {r}), non-negative, with rows summing to 1")
        m = self.H.shape[1]
        if self.R.shape != (m, m):
            raise ValueError(f"R must be ({m}, {m}), got {self.R.shape}")
        mu = np.full(r, 1.0 / r) if mu is None else np.array(mu, float)
        if mu.shape != (r,) or np.any(mu < 0) or not mu.sum() > 0:
            raise ValueError(f"mu must be {r} non-negative probabilities")
        self.mu = mu / mu.sum()
        x0 = np.zeros(n) if x is None else np.array(x, float)
        P0 = np.eye(n) if P is None else np.array(P, float)
        self.xs = np.repeat(x0[None, :], r, axis=0)
        self.Ps = np.repeat(P0[None, :, :], r, axis=0)
        self.x, self.P = x0.copy(), P0.copy()
        self.log_likelihood = np.zeros(r)
        self.cbar = self.mu @ self.M
        self._I = np.eye(n)

    @property
    def r(self) -> int:
        return self.Phi.shape[0]

    def mix(self) -> None:
        """Eqs. 18-20: every filter starts the step from the mixture of all filters' posteriors."""
        self.cbar = self.mu @ self.M
        w = self.M * self.mu[:, None] / self.cbar[None, :]  # w[j, i] = mu_ji
        x0 = w.T @ self.xs
        d = self.xs[None, :, :] - x0[:, None, :]  # d[i, j] = x_j - x0_i
        self.Ps = np.einsum("ji,jab->iab", w, self.Ps) + np.einsum("ji,ija,ijb->iab", w, d, d)
        self.xs = x0

    def predict(self) -> None:
        """Mixing, then eqs. 21-22 for every filter."""
        self.mix()
        self.xs = np.einsum("iab,ib->ia", self.Phi, self.xs)
        self.Ps = self.Phi @ self.Ps @ self.Phi.transpose(0, 2, 1) + self.Q

    def update(self, z: np.ndarray) -> None:
        """Eqs. 23-32 with the measurement ``z`` (m,)."""
        H, P = self.H, self.Ps
        Ht = H.transpose(0, 2, 1)
        PHt = P @ Ht
        S = H @ PHt + self.R
        # S scaled to a unit diagonal before inverting: its sensors differ by 1e6 in variance
        # (cond(S) ~ 4e7), and the log-likelihood of the unscaled inverse was off by up to 1e-6
        s = 1.0 / np.sqrt(np.einsum("iaa->ia", S))
        ss = s[:, :, None] * s[:, None, :]
        SIn = np.linalg.inv(S * ss)
        K = PHt @ (SIn * ss)
        d = z[None, :] - np.einsum("iab,ib->ia", H, self.xs)
        self.xs = self.xs + np.einsum("iab,ib->ia", K, d)
        IKH = self._I - K @ H
        P = IKH @ P @ IKH.transpose(0, 2, 1) + K @ self.R @ K.transpose(0, 2, 1)
        self.Ps = 0.5 * (P + P.transpose(0, 2, 1))
        ds = d * s
        logdet = -np.linalg.slogdet(SIn)[1] - 2.0 * np.log(s).sum(axis=1)
        self.log_likelihood = -0.5 * (np.einsum("ia,iab,ib->i", ds, SIn, ds) + logdet + z.shape[0] * LOG_2PI)
        # eqs. 29-30 in logs: mu_i proportional to Lambda_i cbar_i, normalised to sum to 1
        with np.errstate(divide="ignore"):
            a = self.log_likelihood + np.log(self.cbar)
        a -= a.max()
        mu = np.exp(a)
        self.mu = mu / mu.sum()
        self.x = self.mu @ self.xs
        e = self.xs - self.x
        self.P = np.einsum("i,iab->ab", self.mu, self.Ps) + np.einsum("i,ia,ib->ab", self.mu, e, e)

    def step(self, z: np.ndarray) -> None:
        """One sample: ``predict()`` then ``update(z)``."""
        self.predict()
        self.update(z)


class MassIMM(IMM):
    """The IMM of paper 002 over sprung-mass sub-models: one ``DiscreteModel`` per mass of
    ``masses`` (kg), the rest of the vehicle, the road and the sensors shared; the sprung mass
    is sum_i mu_i m_i (kg).

    ``stay``: probability of keeping the model per step (``transition_matrix``), unless
    ``transition`` gives the whole (r, r) matrix. ``sensor_std``: (body acceleration m/s^2,
    wheel acceleration m/s^2, deflection m) of the R of every filter."""

    def __init__(self, masses: Sequence[float], vehicle: Vehicle, speed: float, gd_n0: float, h: float,
                 sensor_std: tuple[float, float, float], stay: float = 0.999,
                 transition: np.ndarray | None = None, road: RoadModel = RoadModel(),
                 noise: ModelNoise = ModelNoise(), mu: np.ndarray | None = None, P0: np.ndarray | None = None):
        self.masses = np.array(masses, float)
        if self.masses.ndim != 1 or np.any(~(self.masses > 0)):
            raise ValueError(f"masses = {masses!r} must be positive sprung masses in kg")
        self.models = [DiscreteModel.build(vehicle.with_(m_s=float(m)), speed, gd_n0, h, road, noise)
                       for m in self.masses]
        R = np.diag(np.square(np.array(sensor_std, float)))
        M = transition_matrix(len(self.masses), stay) if transition is None else transition
        super().__init__([d.Phi for d in self.models], [d.Q for d in self.models], [d.H for d in self.models],
                         R, M, mu=mu, P=P0)

    @property
    def mass(self) -> float:
        """Probability-weighted sprung mass, kg."""
        return float(self.mu @ self.masses)
