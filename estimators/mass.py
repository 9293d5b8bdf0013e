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
terms, m_s F[a_s] + c F[d'] = -k_s F[d] holds exactly for the filtered signals. The samples
are taken to move linearly from one to the next (a first-order hold: ``StateVariableFilter``),
as the continuous signals they sample do: held over the step instead, as a zero-order hold
takes them, F[d'] is the filtered rate of a staircase, whose jumps fall half a step after the
rate they stand for, and the damping term's lag read as mass (point samples at 10 ms of a car
simulated at 0.5 ms, ISO C, 40 km/h: since-change mass +0.94 %, damping +4.5 %; with the linear
hold -0.07 %, -0.05 %). The high-pass
(w_h) removes sensor offsets and drift, the low-pass (w_c) the white sensor noise (which
would otherwise bias least squares through errors in the regressor).

Damping. By default c is the known parameter c_s and only m_s is estimated (one-parameter RLS,
phi = F[a_s], y = -k_s F[d] - c_s F[d']). ``estimate_damping=True`` estimates the paper's
theta = [m_s, c], as a cascade: the since-change least squares (below) is solved for [m_s, c]
(the body resonance excites a_s and d' nearly in quadrature, so it is well posed) and its c
replaces c_s in the fast one-parameter RLS and its change detection. A fast two-parameter RLS
(the paper's form) was tried first: after a covariance reset on weakly exciting data its 2 x 2
problem is ill-conditioned, and on ISO C with a 590 kg body it jumped to its 4100 kg bound.

A suspension that is not linear (our addition). A real damper is stiffer in rebound than in
compression and digressive at speed, an air spring stiffens as it is compressed. Written as
c d' + c_a |d'| + c_q d'|d'| for the damper (c_a = (c_r - c_c)/2 for slopes c_r, c_c) and
k_s d + k_2 d^2 for the spring, the terms the linear balance leaves out are correlated with the
body acceleration they cause, and bias the mass: on the air-spring plant with its 3:1 digressive
damper (plant/suspension_forces.py), told the static-point linearisation, the [m_s, c] estimate
was 16.5 % low on ISO C at 40 km/h (13.5 % with the linear spring). With ``estimate_damping`` the
regression is therefore theta = [m_s, c, c_a, c_q, k_2] over phi = [F[a_s], F[d'], F[|d'|],
F[d'|d'|], F[d^2]] (TERMS): d' comes from a second state-variable filter on d (low-pass RATE_LP,
high-pass f_hp), and each term passes through the same F, so the balance still holds exactly for
the filtered signals. k_s stays the given static-point stiffness: it sets the scale. On a linear
suspension the extra coefficients come out ~0 and their regressors, even in the motion where a_s
is odd, are nearly uncorrelated with the others: the mass changed by < 0.01 % there.

Two estimates from the same regression. ``mass`` is the paper's forgetting-factor RLS (memory
h / (1 - lambda), 0.2 s at 1 ms and lambda = 0.995) with covariance resetting on a detected
change (below): it tracks a payload step within ~0.05-0.2 s, but its noise is ~0.3-1 % (more on
a smooth road, where the regressor is small). ``mass_slow`` is the least-squares estimate over ALL data
since the last detected change (a long forgetting time ``slow_tau`` only bounds its memory), with
its standard error ``mass_slow_std``. It is what the road filter should be built at: on ISO B a
model mass 0.6 % off costs about 2 % of the road in band (as much as the whole noise floor),
because the body-acceleration mismatch integrates into the unobservable common velocity. The
standard error counts the colour of the residual (low-passed at f_lp: one independent sample per
1 / (2 B) s, B = 1.11 f_lp the noise bandwidth), so a significance test on it is meaningful.

Payload changes (our addition; the paper's RLS only forgets). Two parts:

* Detection: a windowed least-squares estimate of the mass change from the a-priori innovations
  e = y - F[a_s] m, dm = <F[a_s] e> / <F[a_s]^2> (kg; <.> a low-pass of time constant
  ``reset_tau``), the generalised likelihood-ratio statistic of a step in m. A change is declared
  when it is relevant, |dm| > ``reset_ratio`` m, AND significant, dm^2 <F[a_s]^2> > z^2 s_e^2
  (z = ``reset_z``, s_e^2 the innovation noise variance, a low-pass of e^2 clipped at 9 s_e^2 so
  a change does not inflate it). Because dm correlates e with the regressor, sensor noise does
  not bias it, and with little excitation (small <F[a_s]^2>) it is not significant. The former
  test (low-passed e^2 > reset_ratio^2 times low-passed y^2) fired whenever the body acceleration
  dipped: y^2 falls, the noise in e does not. On ISO B at a constant mass it reset up to 5 times
  in 30 s, and each reset let the large reset covariance fit a few noisy, weakly excited samples
  exactly (excursions of the fast estimate to +180 %).
* Restart of the regression: after a change at t_c the filtered balance m F[a_s] = y is wrong
  for as long as the filters remember data from before t_c: F[m a] = m_2 F[a] - (m_2 - m_1)
  F[a 1(t < t_c)], 100 N rms in the first 0.1 s after a 190 kg step (the low-pass) and still
  ~7 N (against 1.2 N of noise) 1 s later (the 0.2 Hz high-pass, time constant 0.8 s). A reset
  covariance gives those contaminated samples full weight, and the forgetting factor removes
  them only slowly (estimates stuck 4 % off for 0.3 s, or a second reset). At a detection the
  state-variable filters therefore restart from zero at the current sample, which by linearity
  removes their free response, i.e. every sample before the restart, exactly. The filtered
  deflection rate s F[d] of the restarted filter then also holds the response to the jump of its
  input from 0 to d(t_r), d(t_r) times the step response's rate state S_2 (computed alongside),
  which is subtracted; nothing else changes. The RLS covariance is reset to its initial value
  and the since-change least squares restarts with it.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from ..plant.quarter_car import discretise_linear_input

# The product F[a_s] e of regressor and residual decorrelates faster than the residual alone
# (n_corr): the regressor is narrow-band at the body resonance. The factor is measured, not
# derived: with n_corr / h alone the standard error was 1.7-1.9 times the rms error of the fast
# estimate (seeds 11 and 12, ISO A and C, 40 km/h, 5-30 s; rms error 0.58 / 0.14 %); the checks
# reported in docs/real-roads.md use other seeds, classes and speeds.
MASS_STD_COLOUR = 1.0 / 3.0
DAMPING_MIN_DATA = 3.0  # s of data after a detected change before its damping estimate is used
# s of data before the first damping estimate is used: after 0.3 s it scattered by ~5 %, and each
# later update of more than the road filter's tolerance rebuilds (and kicks) its anchor
DAMPING_FIRST_DATA = 1.0
# Hz, low-pass of the deflection-rate signal whose magnitude |d'| is a regressor (module doc): its
# lag biases the fitted asymmetry and the mass (8 degrees at the ~11 Hz wheel hop here), its noise
# biases |d'| upwards (~22 mm/s rms from the default 1e-4 m deflection noise at 1 kHz). On a 3:1
# damper, 20 s of ISO C at 40 km/h, 4 seeds: mass -2.0..-0.8 % at 90 Hz, -1.8..-0.6 % at 120 Hz,
# -2.6..+0.8 % at 200 Hz, -5.0..-1.5 % at 30 Hz
RATE_LP = 120.0
# ... at most this fraction of the sampling rate: a corner at or beyond Nyquist leaves d' the
# noisy difference of the samples (logged at 200 / 100 Hz, an air-spring car's mass came out
# 9 / 49 % low with 120 Hz; 0.3 / h gives 60 / 30 Hz there)
RATE_LP_PER_RATE = 0.3
# the suspension's departures from k_s d + c d' that the [m_s, c] regression also fits (module
# doc): the damper's asymmetry |d'| and its progression d'|d'|, the spring's curvature d^2
TERMS = ("|d'|", "d'|d'|", "d^2")
# The regression needs the body to move: where the filtered body acceleration F[a_s] is little more
# than filtered sensor noise (a smooth road, standstill) least squares fits noise to noise and the
# mass falls towards zero (a flat road at 72 km/h: 41 kg, the 0.1 x nominal bound, in 15 s, and the
# road filter rebuilt ~20 times a second at it). Below this ratio of the mean square of F[a_s] to
# its noise-only value (``MassEstimator.excitation``) the estimates hold their value.
EXCITATION_MIN = 4.0
EXCITATION_TAU = 1.0  # s, low-pass of F[a_s]^2 that the fast RLS's excitation test uses
# s between two solutions of the since-change least squares with the damping (5 x 5, ~15 us, a
# third of the default estimator's step when solved every sample); its data change little in a
# few ms, and the road filter's mass feedback acts at most every 20 ms (mass_rebuild_interval)
SLOW_SOLVE_INTERVAL = 0.005


def _terms(v: float, d: float) -> tuple[float, float, float]:
    """The TERMS at deflection rate v (m/s) and deflection d (m)."""
    return abs(v), v * abs(v), d * d


HELD_INPUT = (0.0, 0.0, 0.0)  # B0 of an input held over the step (B1 = Bd)


def _svf_step(r0, r1, r2, b0, b1, x, u0, u):
    """x <- Ad x + B0 u0 + B1 u for the 3-state filter whose input moves linearly from u0 to u
    over the step (``StateVariableFilter.discretise_linear``; held: B0 = HELD_INPUT, B1 = Bd),
    Ad given by its rows (plain floats)."""
    x0, x1, x2 = x
    return (r0[0] * x0 + r0[1] * x1 + r0[2] * x2 + b0[0] * u0 + b1[0] * u,
            r1[0] * x0 + r1[1] * x1 + r1[2] * x2 + b0[1] * u0 + b1[1] * u,
            r2[0] * x0 + r2[1] * x1 + r2[2] * x2 + b0[2] * u0 + b1[2] * u)


class StateVariableFilter:
    """Discrete exact realisation of F(s) above for one scalar signal: ``discretise`` with the
    input held over the step (ZOH), ``discretise_linear`` with the input moving linearly from
    one sample to the next (first-order hold).

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
        self.Ad = self.Bd = None  # the discretisation at step _h

    def discretise(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        if self._h != h:
            M = np.zeros((4, 4))
            M[:3, :3] = self.A
            M[:3, 3] = self.B
            E = expm(M * h)
            self.Ad, self.Bd, self._h = np.ascontiguousarray(E[:3, :3]), np.ascontiguousarray(E[:3, 3]), h
        return self.Ad, self.Bd

    def discretise_linear(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Ad, B0, B1): x[k] = Ad x[k-1] + B0 u[k-1] + B1 u[k] for an input moving linearly from
        u[k-1] to u[k] over the step (B0 + B1 = Bd of ``discretise``)."""
        Ad, Bd = self.discretise(h)
        B1 = discretise_linear_input(self.A, self.B, h)
        return Ad, np.ascontiguousarray(Bd - B1), B1


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

    def update_scalar(self, phi: float, y: float) -> None:
        """``update`` for one parameter, in scalar arithmetic (identical results, ~5x cheaper)."""
        F = float(self.F[0, 0])
        Fphi = F * phi
        L = Fphi / (self.lam + phi * Fphi)
        self.theta[0] += L * (y - phi * float(self.theta[0]))
        F = (F - L * Fphi) / self.lam
        if self.trace_max is not None and F > self.trace_max:
            F = self.trace_max
        self.F[0, 0] = F


class MassEstimator:
    """Sprung mass (kg) from measured a_s (m/s^2) and deflection d (m): state-variable filter
    + forgetting-factor RLS on m_s F[a_s] + c F[d'] = -k_s F[d] (paper 001 eq. 15).

    ``lam`` is per sample (the contract's forgetting_factor): memory ~ h / (1 - lam) seconds.
    Change detection (module doc): ``reset_ratio`` relative mass change that is relevant,
    ``reset_tau`` s window of the change estimate, ``reset_z`` its significance in standard
    deviations, ``noise_tau`` s time constant of the innovation noise variance (no significance
    test before that much data), ``reset_hold`` s without a new detection after one;
    ``reset_ratio`` = 0 disables it.
    """

    def __init__(self, m_nominal: float, k_s: float, c_s: float, lam: float = 0.995,
                 estimate_damping: bool = False, f_hp: float = 0.2, f_lp: float = 8.0,
                 m_bounds: tuple[float, float] | None = None, reset_ratio: float = 0.1,
                 reset_tau: float = 0.03, reset_hold: float = 0.3, slow_tau: float = 30.0,
                 reset_z: float = 5.0, noise_tau: float = 1.0, acc_noise_std: float = 0.0,
                 defl_noise_std: float = 0.0):
        self.k_s, self.c_s = float(k_s), float(c_s)
        self.acc_noise_std, self.defl_noise_std = float(acc_noise_std), float(defl_noise_std)
        self._noise_fa = self._noise_fdd = 0.0  # noise-only variance of F[a_s], F[d'] (set per h)
        self._faa = 0.0  # F[a_s]^2 low-passed over EXCITATION_TAU
        self._solve_every = 1  # samples between least-squares solutions (SLOW_SOLVE_INTERVAL)
        self.estimate_damping = bool(estimate_damping)
        self.m_nominal = float(m_nominal)
        self.svf = StateVariableFilter(f_hp, f_lp)
        self.xa = (0.0, 0.0, 0.0)  # filter states on a_s
        self.xd = (0.0, 0.0, 0.0)  # filter states on d
        self.svf_rate = StateVariableFilter(f_hp, RATE_LP)
        self.xr = (0.0, 0.0, 0.0)  # states of the rate filter on d: x2 = d' (m/s), band-limited
        self.xe = [(0.0, 0.0, 0.0)] * len(TERMS)  # F states on each extra term (estimate_damping)
        self._svf_h = None
        self._svf_ad = self._svf_bd = self._rate_ad = None  # at step _svf_h
        self._svf_b = self._rate_b = None  # (B0, B1) of the linear input, at step _svf_h
        self._u_last: tuple | None = None  # the last sample's a_s (m/s^2) and d (m)
        # Initial covariance: a +-100 % prior on m (and c) at unit regressor scale; the
        # regressor's own size (F[a_s]^2 ~ 0.1..10) makes this prior weak within ~0.1 s.
        theta0, F0 = [m_nominal], np.diag([m_nominal ** 2])
        self.c_hat = self.c_s  # N.s/m, the damping the fast RLS uses (estimated: see the module doc)
        self.extra_hat = [0.0] * len(TERMS)  # coefficients of TERMS (estimated with the damping)
        self.damping_identified = False  # c_hat has been estimated once
        self.rls = ForgettingRLS(np.array(theta0), F0, lam, trace_max=100.0 * float(np.trace(F0)))
        self.m_bounds = m_bounds or (0.1 * m_nominal, 10.0 * m_nominal)
        self.samples = 0
        # Change detection and restart (module doc): on a detected payload change the filters
        # restart and F is reset to its initial value, so the RLS re-converges in tens of ms
        # instead of waiting ~3 memory lengths h/(1-lambda).
        self.F0 = F0.copy()
        self.reset_ratio, self.reset_tau, self.reset_hold = reset_ratio, reset_tau, reset_hold
        self.reset_z, self.noise_tau = float(reset_z), float(noise_tau)
        self._spe = self._sff = 0.0  # low-passed F[a_s] e (N m/s^2) and F[a_s]^2 ((m/s^2)^2)
        self._s2 = 0.0  # innovation noise variance (N^2)
        self._hold = 0.0
        self.resets = 0
        # step response of the filter since the last restart (None when decayed), and the
        # deflection (m) at the restart: s F[d] of the restarted filter holds d0 * S[2] extra
        self._S: tuple[float, float, float] | None = None
        self._S_left = 0.0  # s until S is negligible (8 high-pass time constants)
        self._d0 = 0.0
        # since-last-change least squares (weighted sums), see the module doc
        self.slow_tau = float(slow_tau)
        self._restart_slow()
        self.n_corr = 1.0 / (2 * 1.11 * f_lp)  # s per independent residual sample
        self.guard = 5.0 / (2 * np.pi * f_lp)  # s without regression after a substituted sample
        self._guard = 0.0
        self._g = self._g_h = 0.0

    def _restart_slow(self) -> None:
        self._slow_key = self._slow_val = None  # the sample of the cached solution, and it
        self._s1 = self._spp = self._spy = self._syy = 0.0
        self._faa = 0.0
        n = 2 + len(TERMS)  # the same sums for theta = [m_s, c, *TERMS] (estimate_damping)
        self._S2pp = np.zeros((n, n))
        self._S2py = np.zeros(n)

    def _slow_solution(self) -> tuple[float, float, float] | None:
        """(mass kg, 1 / information of the mass (1/(m/s^2)^2 per sample), residual sum of
        squares N^2) of the since-change least squares, or None while it is singular."""
        if not self.estimate_damping:
            if not self.excited_slow:
                return None
            spp = self._spp - self._s1 * self._noise_fa  # errors in the regressor removed
            if spp <= 0.0:
                return None
            m = self._spy / spp  # residual sum of squares of m (not of the ordinary LS)
            return m, 1.0 / spp, max(self._syy - 2.0 * m * self._spy + m * m * self._spp, 0.0)
        sol = self._slow_theta_info()
        if sol is None:
            return None
        theta, inv_info, sse = sol
        return float(theta[0]), inv_info, sse

    def _slow_theta(self) -> np.ndarray | None:
        """[m_s kg, c N.s/m, *TERMS] of the since-change least squares, None while singular."""
        sol = self._slow_theta_info()
        return None if sol is None else sol[0]

    def _slow_theta_info(self) -> tuple[np.ndarray, float, float] | None:
        """(theta, 1 / information of the mass, residual sum of squares N^2) of the
        since-change least squares with the damping, None while singular; solved again once
        SLOW_SOLVE_INTERVAL s of samples have come in (the mass feedback asks every step)."""
        if self._slow_key is None or self.samples - self._slow_key >= self._solve_every:
            self._slow_key, self._slow_val = self.samples, self._solve_slow()
        return self._slow_val

    def _solve_slow(self) -> tuple[np.ndarray, float, float] | None:
        # the noise in F[a_s] and F[d'] (independent sensors, known std) adds s1 times its
        # variance to their diagonal of the normal matrix and biases theta towards zero
        # (errors in variables); it is taken out
        if not self.excited_slow:
            return None
        A = self._S2pp.copy()
        A[0, 0] -= self._s1 * self._noise_fa
        A[1, 1] -= self._s1 * self._noise_fdd
        diag = np.diag(A)
        if not np.all(diag > 0.0):
            return None
        # conditioning of the scaled normal matrix (unit diagonal)
        Ad = A / np.sqrt(np.outer(diag, diag))
        if not np.linalg.det(Ad) > 1e-9:
            return None
        rhs = np.zeros((len(diag), 2))
        rhs[:, 0], rhs[0, 1] = self._S2py, 1.0
        sol = np.linalg.solve(A, rhs)  # theta, and the first column of A^-1
        theta = sol[:, 0]
        # residual of this theta (not of the ordinary least squares): with the uncorrected sums
        sse = self._syy - 2.0 * float(theta @ self._S2py) + float(theta @ self._S2pp @ theta)
        return theta, float(sol[0, 1]), max(sse, 0.0)

    @property
    def excited_slow(self) -> bool:
        """The since-change data excite the body: their mean square of F[a_s] is at least
        EXCITATION_MIN times the noise-only value (always True without a noise std)."""
        if self._noise_fa <= 0.0:
            return True
        spp = self._S2pp[0, 0] if self.estimate_damping else self._spp
        return spp > EXCITATION_MIN * self._s1 * self._noise_fa

    @property
    def excitation(self) -> float:
        """Mean square of F[a_s] over the last EXCITATION_TAU s over its noise-only value
        (dimensionless; inf without a noise std). Below EXCITATION_MIN the fast RLS holds."""
        return self._faa / self._noise_fa if self._noise_fa > 0.0 else math.inf

    @property
    def mass_slow(self) -> float:
        """Least-squares mass (kg) over the data since the last detected change (the fast
        estimate until there is enough excitation); with ``estimate_damping`` the mass of the
        least-squares [m_s, c]."""
        sol = self._slow_solution()
        if sol is None:
            return self.mass
        lo, hi = self.m_bounds
        return min(max(sol[0], lo), hi)

    def mass_slow_std(self, h: float) -> float:
        """Standard error (kg) of ``mass_slow``; inf until 5 independent samples are in."""
        sol = self._slow_solution()
        if sol is None or self._s1 * h < 5 * self.n_corr:
            return float("inf")
        _, inv_info, sse = sol
        var_e = sse / self._s1  # residual variance per sample
        return math.sqrt(var_e * inv_info * max(self.n_corr / h, 1.0))

    def agrees_with(self, m_model: float, tol: float, sigma: float, h: float) -> tuple[float, float, bool]:
        """(``mass_slow`` kg, its standard error kg, whether it agrees with the model mass
        ``m_model`` kg: within max(``tol`` m_model, ``sigma`` standard errors))."""
        m, sd = self.mass_slow, self.mass_slow_std(h)
        return m, sd, abs(m - m_model) <= max(tol * m_model, sigma * sd)

    def mass_std(self, h: float) -> float:
        """Standard error (kg) of ``mass``, the forgetting-factor RLS: its covariance F times the
        innovation noise variance s_e^2 (N^2), over 1 + lambda (exponentially weighted least
        squares with white residuals: var = s_e^2 (1 - lambda) / ((1 + lambda) <F[a_s]^2>),
        F = (1 - lambda) / <F[a_s]^2>), times the colour of the product regressor x residual:
        MASS_STD_COLOUR n_corr / h samples per independent one (n_corr as ``mass_slow_std``).
        It measures how well the road excites the body:
        F[a_s] is small on a smooth road, F and the error large (410 kg at 40 km/h, rms over
        5-20 s through the FMUs: ISO A 0.57 %, ISO C 0.14 %). Until the noise variance has ``noise_tau`` s of data, and
        without the change detector (which estimates s_e^2): m_nominal, the RLS's +-100 % prior."""
        if self.reset_ratio <= 0 or self.samples * h < self.noise_tau or self._s2 <= 0.0:
            return self.m_nominal
        lam = self.rls.lam
        return math.sqrt(self._s2 * float(self.rls.F[0, 0]) / (1.0 + lam) * max(MASS_STD_COLOUR * self.n_corr / h, 1.0))

    @property
    def mass(self) -> float:
        lo, hi = self.m_bounds
        return min(max(float(self.rls.theta[0]), lo), hi)

    @property
    def damping_asymmetry(self) -> float:
        """c_a = (c_rebound - c_compression)/2 (N.s/m): 0, or with ``estimate_damping`` identified."""
        return self.extra_hat[0]

    @property
    def damping(self) -> float:
        """Damping (N.s/m): c_s, or with ``estimate_damping`` the since-change least squares'."""
        return self.c_hat

    def update(self, acc_sprung: float, deflection: float, h: float, use: bool = True) -> float:
        """Filter one sample, update the RLS and return the sprung-mass estimate in kg.

        ``use=False`` marks a substituted sample (the caller passes the road filter's prediction
        for a rejected or missing measurement): the state-variable filters run on, but the
        regression is not updated for it nor for ``guard`` s after it (the filters' memory of
        the substitution, a few low-pass time constants)."""
        self._filter(acc_sprung, deflection, h)
        self.samples += 1
        if not use:
            self._guard = self.guard
        if self._guard > 0.0:
            self._guard = max(self._guard - h, 0.0)
            return self.mass
        fa, phi, y = self._regression()
        self._faa += min(h / EXCITATION_TAU, 1.0) * (fa * fa - self._faa)
        y1 = y if phi is None else self._target(y, phi)  # N, the one-parameter target
        if self.reset_ratio > 0 and self._change_detected(fa, y1, h):
            self._restart(acc_sprung, deflection, self._svf_bd)
            fa, phi, y = self._regression()
            y1 = y if phi is None else self._target(y, phi)
        if h != self._g_h:
            self._g, self._g_h = math.exp(-h / self.slow_tau), h
        g = self._g
        self._s1 = g * self._s1 + 1.0
        self._syy = g * self._syy + y * y
        if self._faa > EXCITATION_MIN * self._noise_fa:
            self.rls.update_scalar(fa, y1)
        if self.estimate_damping:
            self._S2pp = g * self._S2pp + np.outer(phi, phi)
            self._S2py = g * self._S2py + phi * y
            # c does not change with the payload: once estimated, after a detected change it is
            # updated again only from DAMPING_MIN_DATA s of new data on (a deflection stuck for 0.1 s, then a
            # spurious "change", had left 0.3 s of data and c 34 % low)
            need = DAMPING_MIN_DATA if self.damping_identified else max(5 * self.n_corr, DAMPING_FIRST_DATA)
            if self.samples % 16 == 0 and self._s1 * h >= need:
                sol = self._slow_theta()
                if sol is not None:
                    self.c_hat = min(max(float(sol[1]), 0.0), 10.0 * self.c_s + 1e3)
                    # both slopes c +- c_a stay >= 0
                    self.extra_hat = [float(v) for v in sol[2:]]
                    self.damping_identified = True
        else:
            self._spp = g * self._spp + fa * fa
            self._spy = g * self._spy + fa * y
        return self.mass

    def _filter(self, acc_sprung: float, deflection: float, h: float) -> None:
        """One sample through the state-variable filters (module doc), rebuilt when h changes."""
        if h != self._svf_h:  # the filter matrices as plain floats (3 x 3 in scalar arithmetic)
            Ad, B0, B1 = self.svf.discretise_linear(h)
            self._svf_ad, self._svf_bd, self._svf_h = tuple(Ad.tolist()), tuple((B0 + B1).tolist()), h
            self._svf_b = (tuple(B0.tolist()), tuple(B1.tolist()))
            corner = min(RATE_LP, RATE_LP_PER_RATE / h)
            if abs(self.svf_rate.wc - 2 * math.pi * corner) > 1e-9 * self.svf_rate.wc:
                self.svf_rate = StateVariableFilter(self.svf.wh / (2 * math.pi), corner)
            Ad, B0, B1 = self.svf_rate.discretise_linear(h)
            self._rate_ad = tuple(Ad.tolist())
            self._rate_b = (tuple(B0.tolist()), tuple(B1.tolist()))
            self._noise_fa, self._noise_fdd = self._noise_variances(h)
            self._solve_every = max(1, int(round(SLOW_SOLVE_INTERVAL / h)))
        (r0, r1, r2), (b0, b1) = self._svf_ad, self._svf_b
        last = self._u_last or (acc_sprung, deflection)  # the first sample: held
        self.xa = _svf_step(r0, r1, r2, b0, b1, self.xa, last[0], acc_sprung)
        self.xd = _svf_step(r0, r1, r2, b0, b1, self.xd, last[1], deflection)
        if self.estimate_damping:
            self.xr = _svf_step(*self._rate_ad, *self._rate_b, self.xr, last[1], deflection)
            # the TERMS held over the step, as RATE_LP was chosen with: fed linearly the air-spring
            # car's mass came out 2.6-4.8 % lower at 10 ms (road seeds 1-3, ISO C, 40 km/h)
            u = _terms(self.xr[2], deflection)
            self.xe = [_svf_step(r0, r1, r2, HELD_INPUT, self._svf_bd, x, 0.0, ui) for x, ui in zip(self.xe, u)]
        self._u_last = (acc_sprung, deflection)
        if self._S is not None:
            self._S_left -= h
            self._S = _svf_step(r0, r1, r2, HELD_INPUT, self._svf_bd, self._S, 0.0, 1.0) if self._S_left > 0.0 else None

    def _change_detected(self, fa: float, y1: float, h: float) -> bool:
        """A payload change (module doc): the windowed estimate of the mass change from the
        a-priori innovation (N) of eq. 22 is relevant and significant."""
        e = y1 - fa * float(self.rls.theta[0])
        a = min(h / self.reset_tau, 1.0)
        self._spe += a * (fa * e - self._spe)
        self._sff += a * (fa * fa - self._sff)
        warm = self.samples * h >= self.noise_tau
        e2 = min(e * e, 9.0 * self._s2) if warm else e * e
        self._s2 += max(h / self.noise_tau, 1.0 / self.samples) * (e2 - self._s2)
        self._hold = max(self._hold - h, 0.0)
        if self._hold == 0.0 and self.samples * h > 3 * self.reset_tau and self._sff > 0.0:
            dm = self._spe / self._sff  # kg
            return bool(abs(dm) > self.reset_ratio * self.mass
                        and (not warm or dm * dm * self._sff > self.reset_z ** 2 * self._s2))
        return False

    def _noise_variances(self, h: float) -> tuple[float, float]:
        """Stationary variance of F[a_s] ((m/s^2)^2) and of F[d'] ((m/s)^2) when the sensors
        give nothing but their white noise (std per sample ``acc_noise_std``, ``defl_noise_std``,
        moving linearly between the samples as the filters take them)."""
        from scipy.linalg import solve_discrete_lyapunov

        # x[k] = Ad x[k-1] + B0 e[k-1] + B1 e[k], e white: w = x - B1 e follows
        # w[k] = Ad w[k-1] + (Ad B1 + B0) e[k-1], and P = P_w + B1 B1'
        Ad, B0, B1 = self.svf.discretise_linear(h)
        g = Ad @ B1 + B0
        P = solve_discrete_lyapunov(Ad, np.outer(g, g)) + np.outer(B1, B1)
        return self.acc_noise_std ** 2 * float(P[1, 1]), self.defl_noise_std ** 2 * float(P[2, 2])

    def _regression(self) -> tuple[float, np.ndarray | None, float]:
        """F[a_s] (m/s^2), phi (3-parameter case, else None) and y (N) of eq. 15 from the
        filter states, the restart's step term removed from s F[d]."""
        fa, fd, fdd = self.xa[1], self.xd[1], self.xd[2]
        if self._S is not None:
            fdd -= self._d0 * self._S[2]
        if self.estimate_damping:
            return fa, np.array([fa, fdd] + [x[1] for x in self.xe]), -self.k_s * fd
        return fa, None, -self.k_s * fd - self.c_s * fdd

    def _target(self, y: float, phi: np.ndarray) -> float:
        """y less the damping and extra terms at their current estimates (N)."""
        t = y - self.c_hat * float(phi[1])
        for c, p in zip(self.extra_hat, phi[2:]):
            t -= c * float(p)
        return t

    def _restart(self, acc_sprung: float, deflection: float, Bd: tuple[float, float, float]) -> None:
        """A detected payload change: filters restarted at this sample (zero state, then this
        sample's input), covariance reset, since-change least squares and detector restarted."""
        self.xa = tuple(b * acc_sprung for b in Bd)
        self.xd = tuple(b * deflection for b in Bd)
        self.xe = [tuple(b * ui for b in Bd) for ui in _terms(self.xr[2], deflection)]
        self._S = tuple(Bd)
        self._S_left = 8.0 / self.svf.wh
        self._d0 = float(deflection)
        self.rls.F = self.F0.copy()
        self._hold = self.reset_hold
        self.resets += 1
        self._restart_slow()
        self._spe = self._sff = 0.0
