"""Sprung-mass estimation: forgetting-factor RLS on the filtered body force balance.

Li, Wang, Zhang, Yang, *Kalman Filter Method Based Vehicle Mass Estimation for Automobile
Suspension System*, eqs. 15-24: m_b x_b'' + c (x_b' - x_w') = -k_s (x_b - x_w), theta = [m_b, c],
phi = [x_b'', x_b' - x_w'], y = -k_s (x_b - x_w), solved by RLS with forgetting factor lambda.

Regressor (independent of the assumed mass). The paper takes the suspension velocity from a
Kalman filter built at the nominal mass; that velocity is biased towards the nominal model and
pulls the estimate back to it. Here every regressor entry comes from the sensors only: the
measured body acceleration a_s and the measured deflection d = z_s - z_u. The velocity d' is
never formed by differencing: a and d both pass through the SAME linear "state-variable"
filter F(s) = s/(s + w_h) * w_c^2/(s^2 + 2 zeta w_c s + w_c^2), whose second-order part yields
F[d] and F[d'] = s F[d] exactly as two of its states. Because F is linear and common to all
terms, m_s F[a_s] + c F[d'] = -k_s F[d] holds exactly for the filtered signals. The high-pass
(w_h) removes sensor offsets and drift, the low-pass (w_c) the white sensor noise (which
would otherwise bias least squares through errors in the regressor).

Damping. By default c is the known parameter c_s and only m_s is estimated (one-parameter RLS,
phi = F[a_s], y = -k_s F[d] - c_s F[d']): the body resonance excites a_s and d' nearly in
quadrature, the 2-parameter problem is well posed, but its variance is about twice as large and
it converges more slowly; ``estimate_damping=True`` gives the paper's theta = [m_s, c].
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import expm


class StateVariableFilter:
    """Discrete exact (ZOH) realisation of F(s) above for one scalar signal.

    States [hp_state, x1, x2]: output F[u] = x1 and s F[u] = x2 (units of u and u/s).
    """

    def __init__(self, f_hp: float = 0.2, f_lp: float = 8.0, zeta: float = 0.7071):
        self.wh, self.wc, self.zeta = 2 * np.pi * f_hp, 2 * np.pi * f_lp, zeta
        # u_hp = u - z,  z' = wh (u - z);  x1' = x2,  x2' = -wc^2 x1 - 2 zeta wc x2 + wc^2 u_hp
        wh, wc = self.wh, self.wc
        self.A = np.array([[-wh, 0.0, 0.0],
                           [0.0, 0.0, 1.0],
                           [-wc ** 2, -wc ** 2, -2 * zeta * wc]])
        self.B = np.array([wh, 0.0, wc ** 2])
        self._h = None

    def discretise(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        if self._h != h:
            M = np.zeros((4, 4))
            M[:3, :3] = self.A
            M[:3, 3] = self.B
            E = expm(M * h)
            self.Ad, self.Bd, self._h = E[:3, :3], E[:3, 3], h
        return self.Ad, self.Bd


class ForgettingRLS:
    """Recursive least squares with forgetting factor (paper 001 eqs. 20-24).

    theta_k = theta_{k-1} + L_k (y_k - phi_k' theta_{k-1})              (eq. 22)
    L_k = F_{k-1} phi_k / (lambda + phi_k' F_{k-1} phi_k)                (eq. 23, F_{k-1}: the
                                                                          printed F(t) is a slip)
    F_k = (I - L_k phi_k') F_{k-1} / lambda                              (eq. 24)

    ``trace_max`` bounds trace(F) so that long stretches without excitation (smooth road,
    standstill) cannot wind the covariance up.
    """

    def __init__(self, theta0: np.ndarray, F0: np.ndarray, lam: float = 0.995,
                 trace_max: float | None = None):
        self.theta = np.array(theta0, dtype=float)
        self.F = np.array(F0, dtype=float)
        self.lam = float(lam)
        self.trace_max = trace_max

    def update(self, phi: np.ndarray, y: float) -> np.ndarray:
        Fphi = self.F @ phi
        denom = self.lam + phi @ Fphi
        L = Fphi / denom
        self.theta = self.theta + L * (y - phi @ self.theta)
        self.F = (self.F - np.outer(L, Fphi)) / self.lam
        if self.trace_max is not None:
            tr = np.trace(self.F)
            if tr > self.trace_max:
                self.F *= self.trace_max / tr
        return self.theta


class MassEstimator:
    """Sprung mass (kg) from measured a_s (m/s^2) and deflection d (m): state-variable filter
    + forgetting-factor RLS on m_s F[a_s] + c F[d'] = -k_s F[d] (paper 001 eq. 15).

    ``lam`` is per sample (the contract's forgetting_factor): memory ~ h / (1 - lam) seconds.
    """

    def __init__(self, m_nominal: float, k_s: float, c_s: float, lam: float = 0.995,
                 estimate_damping: bool = False, f_hp: float = 0.2, f_lp: float = 8.0,
                 m_bounds: tuple[float, float] | None = None, reset_ratio: float = 0.1,
                 reset_tau: float = 0.03, reset_hold: float = 0.3):
        self.k_s, self.c_s = float(k_s), float(c_s)
        self.estimate_damping = bool(estimate_damping)
        self.m_nominal = float(m_nominal)
        self.svf = StateVariableFilter(f_hp, f_lp)
        self.xa = np.zeros(3)  # filter states on a_s
        self.xd = np.zeros(3)  # filter states on d
        # Initial covariance: a +-100 % prior on m (and c) at unit regressor scale; the
        # regressor's own size (F[a_s]^2 ~ 0.1..10) makes this prior weak within ~0.1 s.
        if self.estimate_damping:
            theta0 = [m_nominal, c_s]
            F0 = np.diag([m_nominal ** 2, (c_s + 100.0) ** 2])
        else:
            theta0, F0 = [m_nominal], np.diag([m_nominal ** 2])
        self.rls = ForgettingRLS(np.array(theta0), F0, lam, trace_max=100.0 * float(np.trace(F0)))
        self.m_bounds = m_bounds or (0.1 * m_nominal, 10.0 * m_nominal)
        self.samples = 0
        # Change detection (covariance resetting): when the low-passed a-priori residual power
        # exceeds reset_ratio^2 of the low-passed output power, the payload has changed; F is
        # reset to its initial value so the RLS re-converges in tens of ms instead of waiting
        # ~3 memory lengths h/(1-lambda). 0 disables it.
        self.F0 = F0.copy()
        self.reset_ratio, self.reset_tau, self.reset_hold = reset_ratio, reset_tau, reset_hold
        self._e2 = self._y2 = 0.0
        self._hold = 0.0
        self.resets = 0

    @property
    def mass(self) -> float:
        return float(np.clip(self.rls.theta[0], *self.m_bounds))

    @property
    def damping(self) -> float:
        return float(self.rls.theta[1]) if self.estimate_damping else self.c_s

    def update(self, acc_sprung: float, deflection: float, h: float) -> float:
        """Filter one sample, update the RLS and return the sprung-mass estimate in kg."""
        Ad, Bd = self.svf.discretise(h)
        self.xa = Ad @ self.xa + Bd * acc_sprung
        self.xd = Ad @ self.xd + Bd * deflection
        fa, fd, fdd = self.xa[1], self.xd[1], self.xd[2]
        self.samples += 1
        if self.estimate_damping:
            phi, y = np.array([fa, fdd]), -self.k_s * fd
        else:
            phi, y = np.array([fa]), -self.k_s * fd - self.c_s * fdd
        if self.reset_ratio > 0:
            a = min(h / self.reset_tau, 1.0)
            e = y - phi @ self.rls.theta
            self._e2 += a * (e * e - self._e2)
            self._y2 += a * (y * y - self._y2)
            self._hold = max(self._hold - h, 0.0)
            if (self._hold == 0.0 and self.samples * h > 3 * self.reset_tau
                    and self._e2 > self.reset_ratio ** 2 * self._y2):
                self.rls.F = self.F0.copy()
                self._hold = self.reset_hold
                self.resets += 1
        self.rls.update(phi, y)
        return self.mass
