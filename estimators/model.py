"""The 6-state augmented quarter-car model of the road-profile estimators, discretised exactly.

Wang, Dong, Qin, Gu, *Road profile estimation for suspension system based on the minimum model
error criterion combined with a Kalman filter* (J. Vibroengineering 2017), eqs. 1-7: state

    x = [z_s, v_s, z_u, v_u, z_r, v_r]   (m, m/s, m, m/s, m, m/s)

and the accelerations as outputs. The matrices are DERIVED here from the equations of motion
(displacements upwards from static equilibrium, the same as ``plant.quarter_car``):

    m_s a_s = -k_s (z_s - z_u) - c_s (v_s - v_u)
    m_u a_u =  k_s (z_s - z_u) + c_s (v_s - v_u) - k_t (z_u - z_r)

The printed A of the paper (eq. 4) has sign slips in its second row (+k_s/m_b on z_s and on z_u);
eq. 7 prints the correct row. Here row 2 is [-k_s/m_s, -c_s/m_s, k_s/m_s, c_s/m_s, 0, 0].

Road model (the paper's eq. 3 with the ISO 8608 intensity of the IMMAKF paper, eqs. 5-7):

    z_r' = v_r,   v_r' = -a_1 z_r - a_2 v_r + w_r,   E[w_r(t) w_r(t')] = q_r delta(t - t')

A waviness-2 ISO road has a white road velocity: its one-sided PSD in time is
4 pi^2 n0^2 Gd(n0) V (m^2/s^2/Hz) at speed V. The shaping filter reproduces that level between
two corners that are fixed in SPATIAL frequency, so one choice serves every speed and class:
a_2 = 2 pi n_hi V (the road-velocity corner, rad/s) and a_1 = a_2 * 2 pi n_lo V (the
displacement corner a_1/a_2 = 2 pi n_lo V). The low-frequency level of v_r is 2 q_r / a_2^2,
hence q_r = 2 pi^2 n0^2 Gd(n0) V a_2^2 (m^2/s^3). A first-order model (IMMAKF eq. 5) would
leave no road-velocity state; the second-order one keeps v_r (an output of the contract) and
rolls the road off above n_hi, where the generated ISO profiles end (n_max = 2.83 1/m).

Common-mode reference (the steady-state fix). The accelerations and the deflection observe only
RELATIVE motion: a common offset or velocity of z_s, z_u, z_r leaves every output unchanged.
Without an anchor this common mode is pinned only by the road prior (a_1, a_2), and the
steady-state filter then SHRINKS the road by a factor that is flat in frequency (0.05-20 Hz):
on ISO C at 40 km/h the DARE gain gives |estimate/truth| = 0.88 at n_lo = 0.011 and 0.65 at
n_lo = 0.001 (the old n_lo = 1e-4 design was good only while its covariance was small: 1 % HP
at 60 s, 16 % and gain 0.84 by 400 s). The shrink factor does not depend on the road-model
shape (n_hi 0.3-30, first- or second-order road), on q_s/q_u or on h; it scales as
(R / q_r)^(1/4) and grows with the common-mode prior variance, i.e. it is the weakly observable
common mode, not the band, that the filter trades against. The sensors themselves resolve the
absolute road far below the band (body-acceleration SNR = 1 at ~0.004 Hz on ISO C at 11 m/s).
So the model gets an explicit reference: a weak critically damped "virtual spring" (corner
``f_ref`` = 0.01 Hz, damping 0.707) acting on the body's absolute position and velocity, with
the SAME acceleration added to body, wheel and road. Relative motion, and hence every output,
is unchanged (H is built from the physical equations); the common mode becomes stable and
observable, the Riccati recursion converges (DARE exists; the gain freezes), and the estimates
are relative to a reference that follows the absolute motion above ~0.01 Hz. Steady state
(research/steady_state.py sweep, ISO A-E, 10-30 m/s, one configuration): HP error 2.3-3.7 %,
in-band gain 0.995-1.008, sqrt(P[z_r, z_r]) / true raw error 0.95-1.29. The raw error is the
reference drift (double-integrated sensor noise below ~0.01 Hz, ~5.5 mm) plus the ISO road
content below f_ref, and P[z_r, z_r] accounts for it. n_lo (1e-4) no longer matters.

Vehicle states get a small white acceleration noise (q_s, q_u in m^2/s^3) for model error;
larger values decouple the measured body acceleration from the body motion and shrink the
estimated road (1e-4 gave an in-band gain of 0.4).

Discretisation is exact: Phi = expm(A h) and Q_d by Van Loan's method,
expm([[-A, G Qc G^T], [0, A^T]] h) = [[., Phi^-1 Q_d], [0, Phi^T]]. For a mode much faster
than the step (a very stiff damper on a light wheel) Phi @ (Phi^-1 Q_d) cancels catastrophically
and Q_d is built by squaring from a short sub-step instead (``discretise``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..plant.iso8608 import N0, N_MAX, N_MIN
from ..plant.vehicle import Vehicle

N_STATES = 6
IZS, IVS, IZU, IVU, IZR, IVR = range(6)
# acc_sampling = 1 (accelerations averaged over the step) appends the previous step's v_s, v_u
# plus the common-mode reference's velocity increment over the step (discretise_averaged)
IVS_PREV, IVU_PREV = 6, 7
N_STATES_AVG = 8


@dataclass(frozen=True)
class RoadModel:
    """Spatial corners (cycle/m) and intensity scale of the second-order road shaping filter.

    ``n_lo`` is the displacement corner (ISO band starts at 0.011 1/m), ``n_hi`` the road-velocity
    corner, ``q_scale`` multiplies the ISO intensity q_r. Tuned once for all classes and speeds.
    """

    n_lo: float = 1e-4
    n_hi: float = 3.0
    q_scale: float = 1.0
    # Common-mode reference (see the module doc): a weak critically-damped "virtual spring"
    # (corner f_ref Hz, damping zeta_ref) on the body's absolute position/velocity, applied
    # equally to body, wheel and road, so relative motion and every output are unchanged.
    # 0 disables it (the previous, transient-only design).
    f_ref: float = 0.01
    zeta_ref: float = 0.7071


@dataclass(frozen=True)
class ModelNoise:
    """White acceleration noise intensities on the body and wheel velocity states, m^2/s^3,
    and the suspension-force error states (``force_error_matrices``): the fast error e with
    intensity ``q_f`` per unit speed (N^2/m: the state is driven by q_f * speed N^2/s; 0 = no
    such state) and correlation time ``tau_f`` (s), and the slow bias b with ``q_b`` (N^2/m; 0 =
    none, only with q_f > 0) and ``tau_b`` (s)."""

    q_s: float = 1e-8
    q_u: float = 1e-8
    q_f: float = 0.0
    tau_f: float = 0.1
    q_b: float = 0.0
    tau_b: float = 10.0

    @property
    def force_states(self) -> int:
        """Number of force-error states appended to the model (0, 1 or 2)."""
        return 0 if self.q_f <= 0 else (2 if self.q_b > 0 else 1)


def road_coefficients(speed: float, road: RoadModel = RoadModel()) -> tuple[float, float]:
    """(a_1 in 1/s^2, a_2 in 1/s) of the road model at ``speed`` (m/s), from spatial corners."""
    v = max(abs(float(speed)), 0.1)  # a standing car still needs a stable road model
    a2 = 2 * np.pi * road.n_hi * v
    a1 = a2 * 2 * np.pi * road.n_lo * v
    return float(a1), float(a2)


def road_intensity(gd_n0: float, speed: float, road: RoadModel = RoadModel()) -> float:
    """q_r (m^2/s^3): white-noise intensity driving v_r so that the road PSD is Gd(n0)(n/n0)^-2.

    q_r = 2 pi^2 n0^2 Gd(n0) V a_2^2 (IMMAKF paper eq. 5 level, carried to the 2nd-order model).
    """
    v = max(abs(float(speed)), 0.1)
    _, a2 = road_coefficients(v, road)
    return float(road.q_scale * 2 * np.pi ** 2 * N0 ** 2 * gd_n0 * v * a2 ** 2)


def state_matrix(v: Vehicle, speed: float, road: RoadModel = RoadModel()) -> np.ndarray:
    """Continuous A (6x6) of x' = A x + w (paper 000 eq. 4 with the sign slips corrected)."""
    a1, a2 = road_coefficients(speed, road)
    A = physical_state_matrix(v, a1, a2)
    if road.f_ref > 0:
        wr = 2 * np.pi * road.f_ref
        for r in (IVS, IVU, IVR):  # the same acceleration on all three: relative motion unchanged
            A[r, IZS] -= wr * wr
            A[r, IVS] -= 2 * road.zeta_ref * wr
    return A


def physical_state_matrix(v: Vehicle, a1: float, a2: float) -> np.ndarray:
    """A without the common-mode reference: the equations of motion plus the road filter."""
    ms, mu, ks, kt, c = v.m_s, v.m_u, v.k_s, v.k_t, v.c_s
    return np.array([
        [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [-ks / ms, -c / ms, ks / ms, c / ms, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [ks / mu, c / mu, -(ks + kt) / mu, -c / mu, kt / mu, 0.0],
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [0.0, 0.0, 0.0, 0.0, -a1, -a2],
    ])


def output_matrix(v: Vehicle, deflection: bool = True) -> np.ndarray:
    """H of y = H x: rows a_s, a_u (the 2nd and 4th rows of A, paper 000 eq. 4 'C') and,
    if ``deflection``, z_s - z_u. Shape (3, 6) or (2, 6)."""
    A = physical_state_matrix(v, 0.0, 0.0)  # the sensors measure the physical accelerations
    rows = [A[IVS], A[IVU]]
    if deflection:
        rows.append(np.array([1.0, 0.0, -1.0, 0.0, 0.0, 0.0]))
    return np.array(rows)


def noise_intensity(gd_n0: float, speed: float, road: RoadModel = RoadModel(),
                    noise: ModelNoise = ModelNoise()) -> np.ndarray:
    """Continuous process-noise intensity Qc (6x6, diagonal on v_s, v_u, v_r), m^2/s^3."""
    Qc = np.zeros((N_STATES, N_STATES))
    Qc[IVS, IVS] = noise.q_s
    Qc[IVU, IVU] = noise.q_u
    Qc[IVR, IVR] = road_intensity(gd_n0, speed, road)
    return Qc


# Van Loan's Q_d = Phi @ (Phi^-1 Q_d) cancels: the upper-right block carries expm(-A h), whose
# entries grow like e^(|Re lambda| h) for a fast stable mode (the wheel of a stiff damper,
# c_s/m_u = 2.5e5 1/s at h = 2 ms: e^512 ~ 1e222), and the product returns rounding of that size
# (|Q_d| ~ 1e194 instead of 0.4). VAN_LOAN_MAX_GAIN bounds the growth max|Phi| max|E12| / max|Q_d|
# (6 for the default vehicle at 1 ms) up to which that rounding, ~2e-16 times it relative to
# max|Q_d|, is accepted; above it Q_d is built by squaring (``_squared_noise``).
VAN_LOAN_MAX_GAIN = 1e4
# ||A t||_1 (dimensionless) of the sub-step the squaring starts from: expm(-A t) grows at most
# e^0.5 there, so its Van Loan block loses no digits
SUBSTEP_NORM = 0.5


def _van_loan(A: np.ndarray, Qc: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(Phi, Q_d unsymmetrised, gain) by Van Loan's method over h (s); gain = max|Phi| max|E12|
    / max|Q_d| (dimensionless) is the factor by which the product Phi @ E12 amplifies rounding."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = Qc
    M[n:, n:] = A.T
    with np.errstate(all="ignore"):  # a stiff A overflows expm(-A h): reported as gain = inf
        E = expm(M * h)
        # contiguous: strided views round differently after a state copy
        Phi = np.ascontiguousarray(E[n:, n:].T)
        Qd = Phi @ E[:n, n:]
        scale = np.max(np.abs(Qd))
        gain = float(np.max(np.abs(Phi)) * np.max(np.abs(E[:n, n:])) / scale) if scale > 0 else 1.0
    return Phi, Qd, gain if np.isfinite(gain) and np.isfinite(scale) else math.inf


def _squared_noise(A: np.ndarray, Qc: np.ndarray, h: float) -> np.ndarray:
    """Q_d (symmetric PSD) over h (s) for a stiff A, without the cancellation of Van Loan's
    method: Van Loan over the sub-step t = h / 2^s with ||A t||_1 <= SUBSTEP_NORM, then s
    doublings Q(2t) = Q(t) + Phi(t) Q(t) Phi(t)', Phi(2t) = Phi(t)^2 (exact: the noise of the
    second half plus the first half's carried through). Every term is PSD, so nothing cancels;
    the eigenvalues of the result below rounding (|lambda| < n eps max|Q_d|, which Van Loan's
    method does not resolve either) are clipped to zero."""
    norm = float(np.linalg.norm(A, 1)) * h
    s = max(0, int(math.ceil(math.log2(norm / SUBSTEP_NORM)))) if norm > SUBSTEP_NORM else 0
    Phi, Q, _ = _van_loan(A, Qc, h / 2.0 ** s)
    Q = 0.5 * (Q + Q.T)
    for _ in range(s):
        Q = Q + Phi @ Q @ Phi.T
        Q = 0.5 * (Q + Q.T)
        Phi = Phi @ Phi
    w, V = np.linalg.eigh(Q)
    w = np.where(w > 0.0, w, 0.0)
    Q = (V * w) @ V.T
    return 0.5 * (Q + Q.T)


def discretise(A: np.ndarray, Qc: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact (Phi, Q_d) over a step h (s): Phi = expm(A h), Q_d by Van Loan's method, or, when
    its rounding would be amplified by more than VAN_LOAN_MAX_GAIN (a mode much faster than
    the step, e.g. the wheel of a very stiff damper), by squaring from a short sub-step
    (``_squared_noise``). Q_d is symmetric; in the squared case also PSD. Units: A in 1/s,
    Qc in (state unit)^2/s, Q_d in (state unit)^2."""
    Phi, Qd, gain = _van_loan(A, Qc, h)
    if gain <= VAN_LOAN_MAX_GAIN:
        return Phi, 0.5 * (Qd + Qd.T)
    # Van Loan's Phi block is exact but NaN once expm(-A h) overflows: expm(A h) directly
    return np.ascontiguousarray(expm(A * h)), _squared_noise(A, Qc, h)


def discretise_held_road(A: np.ndarray, Qc: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact (Phi, Q_d) when the vehicle sees the road HELD over the step at its end-of-step
    value z_r,k, as in a co-simulation where the road is a communicated input (plant.QuarterCar,
    the contract's road_height "held over the step"). The road states still evolve continuously.

    With A0 = A without the road's action on the vehicle rows, b that action (column IZR of the
    vehicle rows), Phi0, Q0 = Van Loan of (A0, Qc) and Gamma0 = int_0^h expm(A0 s) ds b:
    x_k = Phi0 x_{k-1} + Gamma0 z_r,k + w_k with z_r,k = e_r' x_k, hence
    x_k = M (Phi0 x_{k-1} + w_k), M = (I - Gamma0 e_r')^-1."""
    n = A.shape[0]
    A0 = A.copy()
    b = np.zeros((n, 1))
    for r in (IVS, IVU):
        b[r, 0] = A[r, IZR]
        A0[r, IZR] = 0.0
    Phi0, Q0 = discretise(A0, Qc, h)
    G0 = held_input_matrix(A0, b, h)
    E = np.eye(n)
    E[:, IZR] -= G0[:, 0]
    M = np.linalg.inv(E)
    Q = M @ Q0 @ M.T
    return np.ascontiguousarray(M @ Phi0), 0.5 * (Q + Q.T)


def measurement_covariance(acc_sprung_std: float, acc_unsprung_std: float,
                           defl_std: float | None) -> np.ndarray:
    """R = diag of the assumed sensor noise variances ((m/s^2)^2, (m/s^2)^2, m^2)."""
    d = [acc_sprung_std ** 2, acc_unsprung_std ** 2]
    if defl_std is not None:
        d.append(defl_std ** 2)
    return np.diag(d)


def averaged_output_matrix(h: float, deflection: bool = True) -> np.ndarray:
    """H (3 or 2, 8) of the averaged-acceleration model (acc_sampling = 1): an accelerometer
    behind an anti-alias filter integrating over the sample reports the step average of the
    PHYSICAL acceleration, a_avg,k = (1/h) int a dt (m/s^2). With states 6, 7 as built by
    ``discretise_averaged`` (v_{k-1} plus the common-mode reference's velocity increment over
    the step), a_avg,k = (v_k - x_6,k) / h EXACTLY, so the rows are (v_s - x_6) / h and
    (v_u - x_7) / h; the deflection stays a point sample at the end of the step."""
    rows = [np.zeros(N_STATES_AVG), np.zeros(N_STATES_AVG)]
    rows[0][IVS], rows[0][IVS_PREV] = 1.0 / h, -1.0 / h
    rows[1][IVU], rows[1][IVU_PREV] = 1.0 / h, -1.0 / h
    if deflection:
        d = np.zeros(N_STATES_AVG)
        d[IZS], d[IZU] = 1.0, -1.0
        rows.append(d)
    return np.array(rows)


def reference_acceleration_row(road: RoadModel = RoadModel()) -> np.ndarray:
    """(6,) row r of the common-mode reference's acceleration a_ref = r x (m/s^2), which
    ``state_matrix`` adds to the body, wheel and road accelerations alike:
    a_ref = -w_ref^2 z_s - 2 zeta_ref w_ref v_s, w_ref = 2 pi f_ref (zero when f_ref = 0)."""
    r = np.zeros(N_STATES)
    if road.f_ref > 0:
        wr = 2 * np.pi * road.f_ref
        r[IZS] = -wr * wr
        r[IVS] = -2 * road.zeta_ref * wr
    return r


def discretise_averaged(A: np.ndarray, Qc: np.ndarray, h: float, ref_row: np.ndarray,
                        road_hold: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Exact (Phi, Q_d), 8 x 8, of the averaged-acceleration model (acc_sampling = 1).

    The model's velocities are ABSOLUTE and include the common-mode reference: over a step,
    v_k - v_{k-1} = int (a_phys + a_ref + w) dt, while the sensor reports only the physical
    acceleration a_phys + w (the reference is a prior of the model, no force on the car). A
    model that took (v_k - v_{k-1}) / h as the measured average (the previous design) made the
    sensor see the reference: with the 0.01 Hz reference, 2 zeta w_ref v_s alone is a few
    mm/s^2 of spurious acceleration, and the steady-state HP road error on ISO B at 40 km/h was
    8.2 % at 10 ms and 6.9 % at 1 ms instead of 3.2 % and 2.7 % (estimators.steady_state).

    States 6, 7 are therefore x_6,k = v_s,k-1 + rho_k and x_7,k = v_u,k-1 + rho_k with
    rho_k = int_{t_k-1}^{t_k} a_ref dt (the reference acts equally on body and wheel), so that
    v_k - x_6,k = int (a_phys + w) dt is exactly the physical velocity increment and
    ``averaged_output_matrix`` holds. rho is an extra state of the continuous system,
    rho' = ref_row x, restarted at every step; Van Loan's method on the augmented
    (A_a, Qc_a) gives the exact joint covariance of the step's process noise and of rho (they
    are correlated: the noise of the step moves z_s, v_s and hence rho), so the standard KF
    with independent process and measurement noise is exact. With f_ref = 0, rho = 0 and the
    states are the previous velocities.

    ``road_hold``: the vehicle sees the road held over the step at its end-of-step value, as
    in ``discretise_held_road``: X_k = Phi0 X_{k-1} + Gamma0 z_r,k + W_k with z_r,k = e_r' X_k,
    hence X_k = M (Phi0 X_{k-1} + W_k), M = (I - Gamma0 e_r')^-1 (Sherman-Morrison)."""
    n = N_STATES
    # states 0-5 of A, then the two averaged-sampling states, then any state appended to A
    # (the force error of force_error_matrices) at its end
    idx = list(range(n)) + list(range(N_STATES_AVG, N_STATES_AVG + A.shape[0] - n))
    na = len(idx) + N_STATES_AVG - n
    Aa = np.zeros((na, na))
    Aa[np.ix_(idx, idx)] = A
    Aa[IVS_PREV, :n] = ref_row
    Aa[IVU_PREV, :n] = ref_row
    Qa = np.zeros((na, na))
    Qa[np.ix_(idx, idx)] = Qc
    b = np.zeros((na, 1))
    if road_hold:
        for r in (IVS, IVU):
            b[r, 0] = Aa[r, IZR]
            Aa[r, IZR] = 0.0
    Phi, Q = discretise(Aa, Qa, h)
    Phi[:, n:N_STATES_AVG] = 0.0  # rho restarts every step
    Phi[IVS_PREV, IVS] += 1.0  # ... and the previous velocities are carried
    Phi[IVU_PREV, IVU] += 1.0
    if road_hold:
        g = held_input_matrix(Aa, b, h)[:, 0]
        M = np.eye(na)
        M[:, IZR] += g / (1.0 - g[IZR])  # (I - g e_r')^-1
        Phi = M @ Phi
        Q = M @ Q @ M.T
    return np.ascontiguousarray(Phi), 0.5 * (Q + Q.T)


def force_error_matrices(A: np.ndarray, Qc: np.ndarray, H: np.ndarray, v: Vehicle, speed: float,
                         noise: ModelNoise) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, Qc, H) with the suspension-force error states appended as the LAST states.

    The suspension force is F_s = k_s d + c_s d' + e (+ b): the model's linear spring and damper
    plus a Gauss-Markov error e' = -e / tau_f + w, E[w w'] = q_f |speed| delta (N^2/s), acting
    as -e / m_s on the body and +e / m_u on the wheel. Whatever e is, m_s a_s + m_u a_u =
    k_t (z_r - z_u): the road follows from the whole-corner force balance, which holds for any
    spring and damper law, while the model's spring and damper still shape the prior. q_f = 0
    is the exact linear model; q_f -> inf makes a_s a pure input (the suspension-model-free
    filter). The intensity grows with speed because the suspension motion, and with it the
    force error of a wrong c_s or k_s, grows with the road-velocity intensity (white road
    velocity, PSD proportional to speed). With q_b > 0 a second, slow state b (tau_b, q_b
    |speed|) acts the same way: a mean force the linear spring does not explain (an asymmetric
    damper's jacking shifts the mean deflection by millimetres, which e, correlated over 0.1 s,
    cannot hold, and which the filter would otherwise read as a road offset). H gains the
    columns of the force states in the accelerations (end-of-step rows, set by the caller); in
    the averaged rows (velocity differences) they act through the dynamics.
    """
    n, nf = A.shape[0], noise.force_states
    taus = (noise.tau_f, noise.tau_b)[:nf]
    qs = (noise.q_f, noise.q_b)[:nf]
    A2 = np.zeros((n + nf, n + nf))
    A2[:n, :n] = A
    Q2 = np.zeros((n + nf, n + nf))
    Q2[:n, :n] = Qc
    for i in range(nf):
        A2[IVS, n + i], A2[IVU, n + i] = -1.0 / v.m_s, 1.0 / v.m_u
        A2[n + i, n + i] = -1.0 / taus[i]
        Q2[n + i, n + i] = qs[i] * max(abs(float(speed)), 0.1)
    H2 = np.zeros((H.shape[0], n + nf))
    H2[:, :n] = H
    return A2, Q2, H2


@dataclass
class DiscreteModel:
    """Phi, Q_d, H, R of the augmented model at one (vehicle, speed, Gd(n0), h).

    ``acc_sampling`` 0: 6 states, accelerations sampled at the end of the step (``output_matrix``);
    1: 8 states (the previous v_s, v_u plus the reference's velocity increment over the step
    appended, ``discretise_averaged``), accelerations averaged over the step
    (``averaged_output_matrix``). A stays the continuous 6-state matrix."""

    vehicle: Vehicle
    speed: float
    gd_n0: float
    h: float
    A: np.ndarray
    Phi: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    acc_sampling: int = 0

    @classmethod
    def build(cls, vehicle: Vehicle, speed: float, gd_n0: float, h: float,
              road: RoadModel = RoadModel(), noise: ModelNoise = ModelNoise(),
              deflection: bool = True, acc_sampling: int = 0,
              road_hold: bool = False) -> "DiscreteModel":
        A = state_matrix(vehicle, speed, road)
        Qc = noise_intensity(gd_n0, speed, road, noise)
        if acc_sampling == 1:
            H = averaged_output_matrix(h, deflection)
            nf = noise.force_states
            if nf:  # the force states act through the dynamics only: their H columns stay zero
                A, Qc, _ = force_error_matrices(A, Qc, A[:0], vehicle, speed, noise)
                H = np.hstack([H, np.zeros((H.shape[0], nf))])
            Phi, Q = discretise_averaged(A, Qc, h, reference_acceleration_row(road), road_hold)
        else:
            H = output_matrix(vehicle, deflection)
            nf = noise.force_states
            if nf:
                A, Qc, H = force_error_matrices(A, Qc, H, vehicle, speed, noise)
                H[0, -nf:], H[1, -nf:] = -1.0 / vehicle.m_s, 1.0 / vehicle.m_u
            Phi, Q = discretise_held_road(A, Qc, h) if road_hold else discretise(A, Qc, h)
        return cls(vehicle, float(speed), float(gd_n0), float(h), A, Phi, Q, H, int(acc_sampling))


def held_input_matrix(A: np.ndarray, G: np.ndarray, h: float) -> np.ndarray:
    """Gamma = int_0^h expm(A s) ds G: exact effect of an input G u held over the step (-> h G)."""
    n, m = G.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = G
    return np.ascontiguousarray(expm(M * h)[:n, n:])
