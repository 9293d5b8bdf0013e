"""The half car of paper 002 as its observers see it, and the Kalman filter on it.

State (eqs. 8-9's X = [x'; x; q], reordered as plant/half_car.py's [q, q'] with the roads last):

    x = [z, theta, z_uf, z_ur, z', theta', z_uf', z_ur', q_f, q_r]   (m, rad, m, m, m/s, rad/s, m/s, m/s, m, m)

The vehicle rows are plant/half_car.py's equations of motion (its ``state_matrices``, with the
pitch sign of eqs. 1-4 corrected and the passive dampers beside the actuators), the actuator
forces u = [f_f, f_r] (N) a known input. The road under each axle is eq. 5's first-order process

    q' = -2 pi f0 q + 2 pi n0 sqrt(Gd(n0) V) w,    f0 = 0.01 Hz, n0 = 0.1 1/m, w unit white noise,

front and rear independent (the rear road is the front one a wheelbase later; the paper's model
does not use that, nor does this one). Eq. 9 prints N = 2 pi sqrt(Gq(n0) V) without the n0 of
eq. 5; eq. 5's level is the ISO one (a waviness-2 road has the white road-velocity PSD
4 pi^2 n0^2 Gd(n0) V), so N keeps n0 here. The process noise drives only the roads.

Discretisation is exact over a step h with the inputs held, as the plant holds them: the forces
over the step, the roads at their end-of-step values (as ISORoad gives them; estimators/model.py's
``discretise_held_road`` for two roads). With A0 the matrix without the roads' action b on the
vehicle, Phi0, Q0 by Van Loan's method, Gamma0 = int_0^h expm(A0 s) ds b and q_k = E' x_k:
x_k = M (Phi0 x_{k-1} + Bd0 u + w_k), M = (I - Gamma0 E')^-1.

Measurements y_k = C x_k + D u (end of step, the forces' direct feed-through in D):

    sensors 0 (a real car, HalfCar.fmu's outputs): body accelerations above the front and rear
              axles, wheel accelerations front and rear (m/s^2), suspension deflections front
              and rear (body point above the axle minus wheel, m);
    sensors 1 (the paper's, eq. 41): z', theta', z_uf', z_ur' (absolute velocities). Eq. 41's H is
              printed 4 x 9 for X of 10 states; it is 4 x 10 here.

Process noise, two rules:

    ISO       Qc = 4 pi^2 n0^2 Gd(n0) V on each road (eq. 5), Q_d by Van Loan: exact at any step
              and speed;
    paper     eq. 38, Q = Gamma Q_RV Q_RV' Gamma' (printed H Q_RV Q_RV' B', a transposition slip:
              a covariance is G S G'), Gamma the road-velocity input held over the step and
              Q_RV(d) eq. 40's cubic in the grade index. Eq. 40 is the mean |road velocity| of the
              ISO road at 20 m/s (within 5 % for classes A-D), so this Q is a per-sample white
              road velocity: at 10 ms it is 0.36 of the ISO rule's, at 1 ms 0.036, and it does not
              follow the speed.

Force errors (``force_error_q`` > 0, the default of ``half_car_imm.ObserverSettings``): two
more states, x[10:12] = [df_f, df_r] (N), a force on each axle acting as the actuator's does (body
and wheel apart), random walks driven by white noise of intensity force_error_q (N^2/s).
They take up what the model's forces get wrong at low frequency: a spring 15 % softer than the
model's, seen through deflection and acceleration sensors, otherwise shows as a steady velocity
of the body proportional to the deflection (the model's spring force must be balanced by a
damper force), and an LQR fed those velocities acts as a negative spring: the closed loop of
paper 002 diverges in pitch (docs/half-car-estimator.md). The velocities of the paper's sensors
(sensors 1) are not affected, and they cannot see a steady force error (it moves only positions,
which they do not measure): with them the model has none (``has_force_errors``). force_error_q = 0
is the paper's 10-state model.

The road states hold the absolute road level only weakly (the 0.01 Hz pole), and no sensor of
either set sees it: a heave and a pitch of body, wheels and roads together leave every
measurement unchanged. The estimated roads are the road relative to a level that the filter lets
go at the 0.01 Hz pole; the relative states (deflections, tyre deflections) and the velocities do
not depend on it. The filter's covariance is bounded (the pole is stable), so the gain converges.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..plant import iso8608
from ..plant.half_car import HalfCarParams, input_matrix, state_matrices, stiffness_matrix
from .kalman import LinearKF
from .model import discretise, held_input_matrix

F0 = 0.01  # Hz, eq. 5's lowest cut-off frequency of the road
N_STATES = 10  # the paper's model; force errors add two (module doc)
IZ, ITH, IZF, IZR, IVZ, IVTH, IVF, IVR, IQF, IQR = range(N_STATES)
IDF = N_STATES  # first of the two force-error states
SENSORS = {0: ("acc_body_front", "acc_body_rear", "acc_unsprung_front", "acc_unsprung_rear",
               "susp_deflection_front", "susp_deflection_rear"),
           1: ("heave_velocity", "pitch_rate", "v_u_front", "v_u_rear")}
ROAD_NOISE_RULES = ("iso", "paper")
# the estimates a controller needs, in this order (``estimate_matrix``)
ESTIMATES = ("heave_velocity", "pitch_rate", "v_u_front", "v_u_rear", "susp_deflection_front",
             "susp_deflection_rear", "tire_deflection_front", "tire_deflection_rear", "road_height_front",
             "road_height_rear")
MIN_SPEED = 0.1  # m/s: the road noise of a slower car, so that a standing car's filter still listens


def has_force_errors(sensors: int, force_error_q: float) -> bool:
    """Whether the model carries the force-error states: asked for (``force_error_q`` > 0, N^2/s)
    and seen by the sensor set (0: velocities see no steady force, module doc)."""
    return force_error_q > 0.0 and sensors == 0


def state_count(force_errors: bool) -> int:
    """States of the model: the paper's 10, and the two force errors."""
    return N_STATES + 2 * bool(force_errors)


def continuous_model(p: HalfCarParams, force_errors: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A (n x n, 1/s) and B (n x 2) of x' = A x + B u + noise, u = [f_f, f_r] (N): eq. 8 with eq.
    4's pitch row corrected (plant/half_car.py); n = 10, or 12 with the force errors, which act
    on the vehicle as the forces do."""
    n = state_count(force_errors)
    A8, B8 = state_matrices(p)  # x = [q, q'], u = [q_f, q_r, f_f, f_r]
    A = np.zeros((n, n))
    A[:8, :8] = A8
    A[:8, IQF:IQR + 1] = B8[:, :2]
    A[IQF, IQF] = A[IQR, IQR] = -2 * math.pi * F0
    B = np.zeros((n, 2))
    B[:8] = B8[:, 2:]
    if force_errors:
        A[:8, IDF:] = B8[:, 2:]
    return A, B


def output_matrices(p: HalfCarParams, sensors: int, force_errors: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """C (m x n) and D (m x 2) of the measurements of sensor set ``sensors`` (module doc)."""
    n = state_count(force_errors)
    if sensors == 1:
        C = np.zeros((4, n))
        C[:, IVZ:IVZ + 4] = np.eye(4)
        return C, np.zeros((4, 2))
    if sensors != 0:
        raise ValueError(f"sensors = {sensors!r} is not one of {sorted(SENSORS)}")
    A, B = continuous_model(p, force_errors)
    body = np.array([[1.0, p.l_f, 0.0, 0.0], [1.0, -p.l_r, 0.0, 0.0]])  # eq. 3 at the axles
    C = np.zeros((6, n))
    D = np.zeros((6, 2))
    C[:2] = body @ A[IVZ:IVZ + 4]
    D[:2] = body @ B[IVZ:IVZ + 4]
    C[2:4], D[2:4] = A[IVF:IVR + 1], B[IVF:IVR + 1]
    C[4:, :4] = [[1.0, p.l_f, -1.0, 0.0], [1.0, -p.l_r, 0.0, -1.0]]
    return C, D


def estimate_matrix(p: HalfCarParams, n: int = N_STATES) -> np.ndarray:
    """T (10 x n): T x are the ``ESTIMATES`` (m/s, rad/s, m) of the state x of n states."""
    T = np.zeros((len(ESTIMATES), n))
    T[:4, IVZ:IVZ + 4] = np.eye(4)
    T[4, [IZ, ITH, IZF]] = [1.0, p.l_f, -1.0]
    T[5, [IZ, ITH, IZR]] = [1.0, -p.l_r, -1.0]
    T[6, [IZF, IQF]] = [1.0, -1.0]
    T[7, [IZR, IQR]] = [1.0, -1.0]
    T[8, IQF] = T[9, IQR] = 1.0
    return T


def equilibrium(p: HalfCarParams, forces, n: int = N_STATES) -> np.ndarray:
    """The state (n states) at rest on a level road (q = 0) with the actuator forces (N) applied
    and no force error."""
    x = np.zeros(n)
    x[:4] = np.linalg.solve(stiffness_matrix(p), input_matrix(p)[:, 2:] @ np.asarray(forces, float))
    return x


def road_intensity(gd_n0: float, speed: float) -> float:
    """Eq. 5's noise intensity (m^2/s) on each road: (2 pi n0)^2 Gd(n0) V, Gd(n0) in m^3, V in
    m/s (at least MIN_SPEED)."""
    return (2 * math.pi * iso8608.N0) ** 2 * gd_n0 * max(abs(float(speed)), MIN_SPEED)


def paper_road_velocity(d: float) -> float:
    """Eq. 40: Q_RV (m/s) of the grade index d = log2(Gd(n0) 1e6) (eq. 7)."""
    return 0.00138 * d ** 3 - 0.01516 * d ** 2 + 0.07753 * d - 0.08562


@dataclass
class HalfCarModel:
    """The discretised observer model of one half car (its ``params.m_s`` the model's sprung
    mass) at a step h (s): x_k = Phi x_{k-1} + Bd u + w_k, y_k = C x_k + D u + v_k; 10 states,
    12 with the force errors (``has_force_errors``, module doc).

    ``Q_iso`` is the roads' part of Q_d at unit road intensity (Qc = 1 m^2/s on each road): it
    scales with the intensity; ``Q_paper`` is Gamma Gamma' (s^2), eq. 38's Q at Q_RV = 1 m/s;
    ``Q_force`` the force errors' part of Q_d."""

    params: HalfCarParams
    h: float
    sensors: int
    Phi: np.ndarray
    Bd: np.ndarray
    Q_iso: np.ndarray
    Q_paper: np.ndarray
    Q_force: np.ndarray
    C: np.ndarray
    D: np.ndarray

    @classmethod
    def build(cls, params: HalfCarParams, h: float, sensors: int, force_error_q: float = 0.0) -> "HalfCarModel":
        force_errors = has_force_errors(sensors, force_error_q)
        A, B = continuous_model(params, force_errors)
        n = len(A)
        A0 = A.copy()
        b = np.zeros((n, 2))
        b[:8] = A[:8, IQF:IQR + 1]
        A0[:8, IQF:IQR + 1] = 0.0
        E = np.zeros((n, 2))
        E[IQF, 0] = E[IQR, 1] = 1.0
        Phi0, Q0 = discretise(A0, E @ E.T, h)
        M = np.linalg.inv(np.eye(n) - held_input_matrix(A0, b, h) @ E.T)
        Gamma = M @ held_input_matrix(A0, E, h)
        C, D = output_matrices(params, sensors, force_errors)
        Q_iso = M @ Q0 @ M.T
        Q_paper = Gamma @ Gamma.T
        Q_force = np.zeros((n, n))
        if force_errors:
            Ef = np.zeros((n, n))
            Ef[IDF, IDF] = Ef[IDF + 1, IDF + 1] = float(force_error_q)
            Q_force = M @ discretise(A0, Ef, h)[1] @ M.T
        return cls(params, float(h), int(sensors), np.ascontiguousarray(M @ Phi0),
                   np.ascontiguousarray(M @ held_input_matrix(A0, B, h)), 0.5 * (Q_iso + Q_iso.T),
                   0.5 * (Q_paper + Q_paper.T), 0.5 * (Q_force + Q_force.T), C, D)

    @property
    def n(self) -> int:
        return len(self.Phi)

    def process_noise(self, road_class: int, speed: float, rule: str = "iso") -> np.ndarray:
        """Q_d (state units squared) on a road of ISO class ``road_class`` (1..8) at ``speed`` (m/s),
        the force errors' part included."""
        gd = iso8608.class_psd_n0(road_class)
        if rule == "iso":
            return road_intensity(gd, speed) * self.Q_iso + self.Q_force
        if rule == "paper":
            return paper_road_velocity(iso8608.grade_index(gd)) ** 2 * self.Q_paper + self.Q_force
        raise ValueError(f"road noise rule {rule!r} is not one of {ROAD_NOISE_RULES}")


def measurement_noise(sensors: int, acc_sprung_std: float, acc_unsprung_std: float, defl_std: float,
                      velocity_std: float) -> np.ndarray:
    """R (diagonal) of sensor set ``sensors`` from the stds of each kind (m/s^2, m/s^2, m, m/s)."""
    if sensors == 1:
        return np.diag(np.full(4, float(velocity_std) ** 2))
    return np.diag(np.square([acc_sprung_std, acc_sprung_std, acc_unsprung_std, acc_unsprung_std,
                              defl_std, defl_std]).astype(float))


class HalfCarKF:
    """Paper 002's KF on the half car: one ``HalfCarModel`` and a ``LinearKF`` at the fixed point
    of its covariance recursion (the gain of a steady model is constant: ``LinearKF.stationary``).

    Each step: x = Phi x + Bd u (eq. 21 with its input), then the update with y - D u (the
    forces' feed-through); a step without a usable measurement predicts only. The gain is solved
    again when Q changes (the road class, or the speed by more than ``speed_tol``, relative: Q is
    proportional to the speed under the ISO rule) or the step does.
    """

    def __init__(self, model: HalfCarModel, R: np.ndarray, x0: np.ndarray, speed_tol: float = 0.02):
        self.model = model
        self.kf = LinearKF(model.n, model.C.shape[0], freeze_tol=1e-6)
        self.kf.x = np.array(x0, float)
        self.R = R
        self.speed_tol = float(speed_tol)
        self.key: tuple[int, float, str] | None = None  # (class, speed, rule) of the current Q

    def set_model(self, model: HalfCarModel) -> None:
        """Another step (or vehicle): the state is kept, the gain solved again at the next step."""
        self.model = model
        self.key = None

    def _noise(self, road_class: int, speed: float, rule: str) -> None:
        if self.key is not None:
            c, v, r = self.key
            if c == road_class and r == rule and abs(max(speed, MIN_SPEED) - v) <= self.speed_tol * v:
                return
        m = self.model
        self.kf.set_model(m.Phi, m.process_noise(road_class, speed, rule), m.C, self.R)
        if not self.kf.stationary():
            raise ValueError("the half car's Kalman filter has no steady state: the model is not detectable")
        self.key = (road_class, max(speed, MIN_SPEED), rule)

    def step(self, y: np.ndarray | None, u: np.ndarray, road_class: int, speed: float, rule: str = "iso") -> None:
        """One step: ``y`` the measurements (None: predict only), ``u`` the forces (N) held over it."""
        self._noise(road_class, speed, rule)
        kf, m = self.kf, self.model
        if y is None:
            kf.predict_only()
            kf.x = kf.x + m.Bd @ u
            return
        kf.predict()
        kf.x = kf.x + m.Bd @ u
        kf.update(y - m.D @ u)

    @property
    def x(self) -> np.ndarray:
        return self.kf.x

    @property
    def P(self) -> np.ndarray:
        return self.kf.P

    @property
    def nis(self) -> float:
        """Normalised innovation squared of the last update, y' S^-1 y."""
        return float(self.kf.nis)
