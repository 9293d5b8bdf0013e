"""Observers of paper 003 on the nonlinear quarter car: EKF, UKF and the dual state + mass observer.

The model is the road estimators' augmented quarter car (estimators/model.py: state
x = [z_s, v_s, z_u, v_u, z_r, v_r], the ISO 8608 road shaping filter and the common-mode
reference) with the suspension's linear laws replaced by the plant's nonlinear force laws
(plant/suspension_forces.py, the same parameters and units as the QuarterCar contract). The
measurements are the contract's: body and wheel accelerations and the deflection.

- ``EKF``: filterpy's ExtendedKalmanFilter; the state propagates by RK4 over the step, its
  covariance by the Jacobian at the estimate (the linear state matrix with the spring's and the
  damper's local slopes), discretised by a 4th-order series (the step is far below the fastest
  mode: omega h < 0.1 at 1 ms).
- ``UKF``: the unscented Kalman filter (Merwe scaled sigma points), filterpy's algorithm with the
  model evaluated on all sigma points at once; ``FilterpyUKF`` is filterpy's own, which the tests
  hold it equal to.
- ``DualObserver`` (paper 003, Section 4): a state filter (the EKF or the UKF) and a sprung-mass
  filter, a scalar Kalman filter on theta = 1/m_s with the body acceleration as measurement,
  a_s = f_1(x) + theta (f_0(x) - F_d(v)), exchanging their estimates every step. With a
  self-levelling air spring the dynamic spring force is (A_e p_atm + m_s g) ((V_0/V)^kappa - 1),
  affine in m_s: f_1 is its part per kg (times 1 kg), f_0 the part at no load.

The paper's observer is a feedback-linearised KF; its transformation is not in the text, so the
state filter here is the EKF (or the UKF), which the paper compares it with. Process noise Q is
the linear model's at the static point (estimators/model.py), the same for all three filters. The
estimators do not model the bump stops or contact loss.

As codes of the SuspensionEstimator (estimators/interface.py; the end of this module):
road_estimator 3 = the EKF, 5 = the UKF, mass_estimator 3 = the dual observer (with road_estimator
3 or 5 as its state filter). They are told the nonlinear maps by ``spring_model``,
``damper_model`` and the plant's parameter names and units (air_area, ..., damper_c_rebound, ...);
with both models 0 they run on the linear k_s, c_s. Every object here holds data only (no
stored function), so that the FMU state saves it (suspension_fmi/state.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from ..plant.nonlinear_car import linearised_vehicle
from ..plant import iso8608
from ..plant.suspension_forces import FORCE_RANGES, AirSpring, PiecewiseDamper
from ..plant.vehicle import Vehicle, check_range

from .interface import RoadFilter, state_list
from .kalman import stationary_covariance
from .model import (IVS, IZS, N_STATES, DiscreteModel, RoadModel, measurement_covariance, output_matrix,
                    road_coefficients, state_matrix)


@dataclass(frozen=True)
class NonlinearModel:
    """The estimators' nonlinear quarter car at one speed (m/s) and road intensity Gd(n0) (m^3).

    ``vehicle`` gives m_u, k_t and the linear k_s, c_s used where ``spring`` or ``damper`` is None;
    the sprung mass is an argument of every map (the dual observer changes it).

    ``bias_q`` > 0 (N^2/s) appends a 7th state, a suspension-force bias e (N, a random walk of
    that intensity) acting as the suspension force does: +e on the body, -e on the wheel. It takes
    up the mean force the model gets wrong. Without it the asymmetric damper's mean force
    (pack-down), which depends on the spread of the suspension velocity and so comes out a
    fraction of a newton off in a filter, can only be explained by the common-mode reference:
    an offset of the body, wheel and road heights of dF / (m_s w_ref^2), 0.6 m per newton at
    f_ref = 0.01 Hz (EKF on the default car, ISO C, 40 km/h: raw road error 250 mm with the
    damper's asymmetry, 10 mm without).
    """

    vehicle: Vehicle
    spring: AirSpring | None
    damper: PiecewiseDamper | None
    speed: float
    gd_n0: float
    road: RoadModel = field(default_factory=RoadModel)
    bias_q: float = 0.0

    @property
    def n(self) -> int:
        """Length of the state: 6, or 7 with the force bias."""
        return N_STATES + 1 if self.bias_q > 0 else N_STATES

    def forces(self, x, m_s: float) -> tuple[float, float]:
        """(spring's dynamic force, damper force) in N at state x."""
        d = x[2] - x[0]
        v = x[1] - x[3]
        f_s = self.vehicle.k_s * d if self.spring is None else self.spring.force(d, m_s)
        f_d = self.vehicle.c_s * v if self.damper is None else self.damper.force(v)
        return f_s, f_d

    def _accelerations(self, x, m_s: float) -> tuple[float, float]:
        f_s, f_d = self.forces(x, m_s)
        if len(x) > N_STATES:
            f_s += x[N_STATES]  # the force bias
        return (f_s - f_d) / m_s, (f_d - f_s + self.vehicle.k_t * (x[4] - x[2])) / self.vehicle.m_u

    def measure(self, x: np.ndarray, m_s: float) -> np.ndarray:
        """[a_s, a_u, z_s - z_u]: the physical accelerations (m/s^2) and the deflection (m)."""
        return np.array([*self._accelerations(x, m_s), x[0] - x[2]])

    def _derivative(self, x, m_s: float) -> list[float]:
        # scalar floats: numpy's per-call overhead on 6-vectors would cost ten times the arithmetic
        a_s, a_u = self._accelerations(x, m_s)
        a1, a2 = road_coefficients(self.speed, self.road)
        a_r = -a1 * x[4] - a2 * x[5]
        if self.road.f_ref > 0:
            w = 2 * math.pi * self.road.f_ref
            ref = -w * w * x[IZS] - 2 * self.road.zeta_ref * w * x[IVS]
            a_s, a_u, a_r = a_s + ref, a_u + ref, a_r + ref
        return [x[1], a_s, x[3], a_u, x[5], a_r, 0.0] if len(x) > N_STATES else [x[1], a_s, x[3], a_u, x[5], a_r]

    def derivative(self, x: np.ndarray, m_s: float) -> np.ndarray:
        """x' without noise: the equations of motion, the road filter and the common-mode reference."""
        return np.array(self._derivative(list(map(float, x)), m_s))

    def propagate(self, x: np.ndarray, m_s: float, h: float) -> np.ndarray:
        """x after h seconds (one classical RK4 step)."""
        x0 = list(map(float, x))
        k1 = self._derivative(x0, m_s)
        k2 = self._derivative([a + 0.5 * h * b for a, b in zip(x0, k1)], m_s)
        k3 = self._derivative([a + 0.5 * h * b for a, b in zip(x0, k2)], m_s)
        k4 = self._derivative([a + h * b for a, b in zip(x0, k3)], m_s)
        return np.array([a + h / 6.0 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(x0, k1, k2, k3, k4)])

    # -- the same maps on many states at once (the UKF's sigma points): Y is 6 x k, a column per
    # state, so that each state variable is one contiguous row
    def _many_constants(self, m_s: float) -> tuple:
        key = self.__dict__.get("_many_key")
        if key != m_s:  # (a frozen dataclass: the cache goes through __dict__)
            s, c, v = self.spring, self.damper, self.vehicle
            air = None if s is None else (s.air_area * s.static_pressure(m_s), s.air_area / s.air_volume, -s.air_kappa)
            damp = None if c is None else (c.damper_c_rebound, c.damper_c_rebound_high, c.damper_knee_rebound,
                                           c.damper_c_compression, c.damper_c_compression_high,
                                           c.damper_knee_compression)
            a1, a2 = road_coefficients(self.speed, self.road)
            w = 2 * math.pi * self.road.f_ref
            consts = (air, damp, v.k_s, v.c_s, v.k_t, 1.0 / m_s, 1.0 / v.m_u, a1, a2, w * w,
                      2 * self.road.zeta_ref * w, self.road.f_ref > 0)
            object.__setattr__(self, "_many_consts", consts)
            object.__setattr__(self, "_many_key", m_s)
        return self._many_consts

    def _forces_many(self, Y: np.ndarray, consts: tuple) -> tuple[np.ndarray, np.ndarray]:
        air, damp, k_s, c_s = consts[:4]
        d = Y[2] - Y[0]
        v = Y[1] - Y[3]
        if air is None:
            f_s = k_s * d
        else:  # AirSpring.force
            a, b, mk = air
            ratio = 1.0 - b * d
            if not ratio.min() > 0.0:
                raise ValueError(f"a compression of {d.max()!r} m closes the air volume")
            f_s = a * (ratio ** mk - 1.0)
        if len(Y) > N_STATES:
            f_s = f_s + Y[N_STATES]  # the force bias
        if damp is None:
            f_d = c_s * v
        else:  # PiecewiseDamper.force: each term is zero outside its own range of v
            c_r, c_rh, kr, c_c, c_ch, kc = damp
            vp, vn = np.maximum(v, 0.0), np.minimum(v, 0.0)
            f_d = (c_r * np.minimum(vp, kr) + c_rh * np.maximum(vp - kr, 0.0)
                   + c_c * np.maximum(vn, -kc) + c_ch * np.minimum(vn + kc, 0.0))
        return f_s, f_d

    def measure_many(self, X: np.ndarray, m_s: float) -> np.ndarray:
        """``measure`` of every row of X (k x 6) -> k x 3."""
        c = self._many_constants(m_s)
        Y = X.T
        f_s, f_d = self._forces_many(Y, c)
        return np.array([(f_s - f_d) * c[5], (f_d - f_s + c[4] * (Y[4] - Y[2])) * c[6], Y[0] - Y[2]]).T

    def _derivative_many(self, Y: np.ndarray, c: tuple) -> np.ndarray:
        f_s, f_d = self._forces_many(Y, c)
        a_s = (f_s - f_d) * c[5]
        a_u = (f_d - f_s + c[4] * (Y[4] - Y[2])) * c[6]
        a_r = -c[7] * Y[4] - c[8] * Y[5]
        if c[11]:  # the common-mode reference
            ref = -c[9] * Y[IZS] - c[10] * Y[IVS]
            a_s, a_u, a_r = a_s + ref, a_u + ref, a_r + ref
        if len(Y) > N_STATES:
            return np.array([Y[1], a_s, Y[3], a_u, Y[5], a_r, np.zeros_like(a_r)])
        return np.array([Y[1], a_s, Y[3], a_u, Y[5], a_r])

    def propagate_many(self, X: np.ndarray, m_s: float, h: float) -> np.ndarray:
        """``propagate`` of every row of X (k x 6): one RK4 step of h seconds."""
        c = self._many_constants(m_s)
        Y = np.ascontiguousarray(X.T)
        k1 = self._derivative_many(Y, c)
        k2 = self._derivative_many(Y + 0.5 * h * k1, c)
        k3 = self._derivative_many(Y + 0.5 * h * k2, c)
        k4 = self._derivative_many(Y + h * k3, c)
        return (Y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)).T

    def local_vehicle(self, x: np.ndarray, m_s: float) -> Vehicle:
        """The linear vehicle with the spring's and the damper's slopes at x."""
        d, v = x[2] - x[0], x[1] - x[3]
        return self.vehicle.with_(m_s=m_s,
                                  k_s=self.vehicle.k_s if self.spring is None else self.spring.slope(d, m_s),
                                  c_s=self.vehicle.c_s if self.damper is None else self.damper.slope(v))

    def jacobian(self, x: np.ndarray, m_s: float) -> np.ndarray:
        """d x' / d x (n x n) at x."""
        J = state_matrix(self.local_vehicle(x, m_s), self.speed, self.road)
        if self.n == N_STATES:
            return J
        out = np.zeros((self.n, self.n))
        out[:N_STATES, :N_STATES] = J
        out[1, N_STATES], out[3, N_STATES] = 1.0 / m_s, -1.0 / self.vehicle.m_u
        return out

    def measurement_jacobian(self, x: np.ndarray, m_s: float) -> np.ndarray:
        """d measure / d x (3 x n) at x."""
        H = output_matrix(self.local_vehicle(x, m_s))
        if self.n == N_STATES:
            return H
        return np.hstack([H, [[1.0 / m_s], [-1.0 / self.vehicle.m_u], [0.0]]])

    def linear_model(self, m_s: float, h: float) -> DiscreteModel:
        """The linear model of the static point (its Q_d serves the nonlinear filters)."""
        return DiscreteModel.build(linearised_vehicle(self.vehicle, self.spring, self.damper, m_s),
                                   self.speed, self.gd_n0, h, self.road)

    def process_noise(self, m_s: float, h: float) -> np.ndarray:
        """Q over a step of h s: the static point's linear Q_d, and bias_q h for the force bias."""
        return _padded(self.linear_model(m_s, h).Q, self.n, self.bias_q * h)

    def start_covariance(self, m_s: float, h: float, R: np.ndarray) -> np.ndarray:
        """P at the start: the linear filter's stationary posterior, and BIAS_STD0^2 for the bias."""
        return _padded(_start_covariance(self.linear_model(m_s, h), R), self.n, BIAS_STD0 ** 2)

    def mass_terms(self, x: np.ndarray) -> tuple[float, float]:
        """(f_1, f_0 - F_d) in a_s = f_1 + (f_0 - F_d) / m_s: the spring force per kg of load (N/kg)
        and the suspension force at no load (N)."""
        f_0, f_d = self.forces(x, 0.0)
        f_1 = self.forces(x, 1.0)[0] - f_0
        if len(x) > N_STATES:
            f_0 += float(x[N_STATES])  # the force bias
        return f_1, f_0 - f_d


BIAS_STD0 = 20.0  # N, start std of the force bias


def _padded(M: np.ndarray, n: int, extra: float) -> np.ndarray:
    """M with zero rows and columns up to n x n and ``extra`` on the new diagonal."""
    if M.shape[0] == n:
        return M.copy()
    out = np.zeros((n, n))
    out[:M.shape[0], :M.shape[0]] = M
    out[M.shape[0]:, M.shape[0]:] = np.eye(n - M.shape[0]) * extra
    return out


def _start_covariance(lin: DiscreteModel, R: np.ndarray) -> np.ndarray:
    """The linear filter's stationary posterior covariance (a consistent start), else Q."""
    ss = stationary_covariance(lin.Phi, lin.Q, lin.H, R)
    return lin.Q.copy() if ss is None else ss[1].copy()


class _FilterpyEKF(ExtendedKalmanFilter):
    """filterpy's EKF whose prediction is the model's RK4 step (a method, not a stored lambda:
    the FMU state saves the filter as data)."""

    def __init__(self, model: NonlinearModel, h: float, m_s: float):
        super().__init__(dim_x=model.n, dim_z=3)
        self.model, self.h, self.m_s = model, float(h), float(m_s)

    def predict_x(self, u=0) -> None:
        self.x = self.model.propagate(self.x, self.m_s, self.h)


def _rows_of(rows) -> np.ndarray | None:
    """None (every channel) or the valid channels as an index array."""
    return None if rows is None else np.asarray(rows, dtype=int)


class EKF:
    """Extended Kalman filter on ``NonlinearModel`` (filterpy's ExtendedKalmanFilter).

    Predict: x_{k|k-1} = RK4 of the model over h, P = F P F' + Q with F the 4th-order series of
    expm(J h), J the Jacobian at x_{k-1|k-1}; update with the Jacobian of ``measure`` at
    x_{k|k-1} (filterpy's Joseph form). ``step(z, rows)`` takes z = [acc_sprung, acc_unsprung,
    deflection] (m/s^2, m/s^2, m), ``rows`` None (all) or the valid channels, and returns x_{k|k}."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s: float):
        self.kf = _FilterpyEKF(model, h, m_s)
        self.kf.x = np.zeros(model.n)  # 1-D, as the maps return it (filterpy's default is a column)
        self.kf.Q, self.kf.R = model.process_noise(m_s, h), np.asarray(R, float)
        self.kf.P = model.start_covariance(m_s, h, self.kf.R)
        self.nis = 0.0

    # the model, step and mass live on the filterpy object (its predict_x reads them)
    model = property(lambda self: self.kf.model)
    h = property(lambda self: self.kf.h)

    @property
    def m_s(self) -> float:
        return self.kf.m_s

    @m_s.setter
    def m_s(self, value: float) -> None:
        self.kf.m_s = float(value)

    @property
    def x(self) -> np.ndarray:
        return self.kf.x

    @property
    def P(self) -> np.ndarray:
        return self.kf.P

    @property
    def x_prior(self) -> np.ndarray:
        return self.kf.x_prior

    def set_model(self, model: NonlinearModel, h: float, Q: np.ndarray) -> None:
        """Another speed or step: the model, h and Q change, the estimate and P stay."""
        self.kf.model, self.kf.h, self.kf.Q = model, float(h), Q

    def reset(self, R: np.ndarray) -> None:
        self.kf.x = np.zeros(self.model.n)
        self.kf.P = self.model.start_covariance(self.m_s, self.h, R)

    def step(self, z: np.ndarray, rows=None) -> np.ndarray:
        m, h, kf, m_s = self.model, self.h, self.kf, self.m_s
        Ah = m.jacobian(kf.x, m_s) * h
        Ah2 = Ah @ Ah
        kf.F = np.eye(len(Ah)) + Ah + Ah2 / 2 + Ah2 @ Ah / 6 + Ah2 @ Ah2 / 24
        kf.predict()
        rows = _rows_of(rows)
        z = np.asarray(z, float)
        if rows is None:
            kf.update(z, lambda x: m.measurement_jacobian(x, m_s), lambda x: m.measure(x, m_s))
        elif len(rows):
            kf.update(z[rows], lambda x: m.measurement_jacobian(x, m_s)[rows], lambda x: m.measure(x, m_s)[rows],
                      R=kf.R[np.ix_(rows, rows)])
        else:
            self.nis = 0.0
            return kf.x
        self.nis = float(kf.y @ np.linalg.solve(kf.S, kf.y))
        return kf.x


class UKF:
    """Unscented Kalman filter on ``NonlinearModel``: the algorithm of filterpy's
    UnscentedKalmanFilter with Merwe's scaled sigma points (alpha, beta = 2, kappa = 3 - n), the
    model evaluated on all 2n + 1 sigma points at once (``propagate_many``). filterpy calls the
    model once per point and takes 1.6-5 times as long per step (benchmarks/run.py, "UKF core");
    tests/test_airspring_observers.py holds the two equal to 1e-9 on the same data.

    Weights (Merwe): lambda = alpha^2 (n + kappa) - n, Wm_0 = lambda / (n + lambda),
    Wc_0 = Wm_0 + 1 - alpha^2 + beta, Wm_i = Wc_i = 1 / (2 (n + lambda)); sigma points x,
    x + U_i, x - U_i with U the upper Cholesky factor of (n + lambda) P (rows U_i).
    Predict: propagate the points of x_{k-1|k-1}, P_{k-1|k-1}; x, P = their weighted mean and
    covariance + Q; the update draws new points from x_{k|k-1}, P_{k|k-1} (as filterpy does)."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s: float, alpha: float = 0.5,
                 beta: float = 2.0, kappa: float | None = None):
        self.model, self.h, self.m_s = model, float(h), float(m_s)
        n = model.n
        kappa = 3.0 - n if kappa is None else kappa
        lam = alpha * alpha * (n + kappa) - n
        self.scale = n + lam
        self.Wm = np.full(2 * n + 1, 0.5 / self.scale)
        self.Wc = self.Wm.copy()
        self.Wm[0] = lam / self.scale
        self.Wc[0] = lam / self.scale + 1.0 - alpha * alpha + beta
        self.Q, self.R = model.process_noise(m_s, h), np.asarray(R, float)
        self.x = np.zeros(n)
        self.P = model.start_covariance(m_s, h, self.R)
        self.x_prior = self.x.copy()
        self.nis = 0.0

    def sigma_points(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:
        """(2n + 1) x n sigma points of mean x and covariance P."""
        U = np.linalg.cholesky(self.scale * P).T  # upper: U' U = (n + lambda) P (filterpy: scipy's)
        return np.vstack([x, x + U, x - U])

    def set_model(self, model: NonlinearModel, h: float, Q: np.ndarray) -> None:
        self.model, self.h, self.Q = model, float(h), Q

    def reset(self, R: np.ndarray) -> None:
        self.x = np.zeros(self.model.n)
        self.P = self.model.start_covariance(self.m_s, self.h, R)

    def predict(self) -> None:
        sf = self.model.propagate_many(self.sigma_points(self.x, self.P), self.m_s, self.h)
        self.x = self.Wm @ sf
        d = sf - self.x
        self.P = d.T @ (self.Wc[:, None] * d) + self.Q
        self.x_prior = self.x.copy()

    def update(self, z: np.ndarray, rows=None) -> None:
        sig = self.sigma_points(self.x, self.P)
        sh = self.model.measure_many(sig, self.m_s)
        R = self.R
        if rows is not None:
            sh, z, R = sh[:, rows], z[rows], R[np.ix_(rows, rows)]
        zp = self.Wm @ sh
        dz = sh - zp
        S = dz.T @ (self.Wc[:, None] * dz) + R
        SI = np.linalg.inv(S)
        K = ((sig - self.x).T @ (self.Wc[:, None] * dz)) @ SI
        y = z - zp
        self.x = self.x + K @ y
        self.P = self.P - K @ S @ K.T
        self.nis = float(y @ SI @ y)

    def step(self, z: np.ndarray, rows=None) -> np.ndarray:
        self.predict()
        rows = _rows_of(rows)
        if rows is None or len(rows):
            self.update(np.asarray(z, float), rows)
        else:
            self.nis = 0.0
        return self.x


class FilterpyUKF:
    """filterpy's UnscentedKalmanFilter on ``NonlinearModel``, set up as ``UKF``: the independent
    implementation the tests hold ``UKF`` to (its fx and hx are lambdas: not for the FMU)."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s: float, alpha: float = 0.5):
        self.model, self.h, self.m_s = model, float(h), float(m_s)
        points = MerweScaledSigmaPoints(model.n, alpha=alpha, beta=2.0, kappa=3.0 - model.n)
        self.kf = UnscentedKalmanFilter(dim_x=model.n, dim_z=3, dt=h, points=points,
                                        fx=lambda x, dt: model.propagate(x, self.m_s, dt),
                                        hx=lambda x: model.measure(x, self.m_s))
        self.kf.Q, self.kf.R = model.process_noise(m_s, h), R
        self.kf.P = model.start_covariance(m_s, h, R)

    @property
    def x(self) -> np.ndarray:
        return self.kf.x

    def step(self, z: np.ndarray) -> np.ndarray:
        self.kf.predict()
        self.kf.update(np.asarray(z, float))
        return self.kf.x


# Dual observer's mass filter (beyond the contract): theta = 1/m_s random walk of intensity
# Q_THETA (1/kg^2/s), the body-acceleration error it assumes ACC_STD (m/s^2: sensor noise plus the
# state estimate's model error), the start std of theta THETA_REL0 times the start value.
Q_THETA = 1e-10
ACC_STD = 0.05
THETA_REL0 = 0.3


class DualObserver:
    """Paper 003's dual observer (Section 4): the state filter (``EKF`` or ``UKF``) runs at the
    mass estimate, and a scalar Kalman filter on theta = 1/m_s (random walk, intensity ``q_theta``
    in 1/kg^2/s) updates that estimate from the body acceleration,

        a_s = f_1(x) + theta g(x),   g = f_0 - F_d   (``NonlinearModel.mass_terms``),

    with the regressor taken at the state filter's prediction x_{k|k-1} (which does not yet
    contain this step's acceleration noise); the two exchange their estimates every step.

    ``acc_std`` (m/s^2) is the body-acceleration error the mass filter assumes: sensor noise plus
    the state estimate's model error."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s0: float,
                 q_theta: float = Q_THETA, acc_std: float = ACC_STD, theta_std0: float | None = None,
                 state: type = EKF):
        self.state = state(model, h, R, m_s0)
        self.theta = 1.0 / m_s0
        self.p_theta = (THETA_REL0 / m_s0) ** 2 if theta_std0 is None else theta_std0 ** 2
        self.q_theta = float(q_theta)
        self.r_acc = acc_std ** 2

    @property
    def mass(self) -> float:
        """The sprung-mass estimate (kg)."""
        return 1.0 / self.theta

    @property
    def x(self) -> np.ndarray:
        return self.state.x

    def step(self, z: np.ndarray, rows=None) -> np.ndarray:
        x = self.state.step(z, rows)
        self.p_theta += self.q_theta * self.state.h
        rows = _rows_of(rows)
        if rows is None or 0 in rows:  # the body acceleration is this filter's measurement
            f_1, g = self.state.model.mass_terms(self.state.x_prior)
            s = g * g * self.p_theta + self.r_acc
            k = self.p_theta * g / s
            self.theta += k * (float(z[0]) - f_1 - g * self.theta)
            self.p_theta *= 1.0 - k * g
            self.state.m_s = self.mass
        return x


# --------------------------------------------------------------------------------------------------
# the codes of the SuspensionEstimator (estimators/interface.py): road_estimator 3 (EKF) and 5
# (UKF), mass_estimator 3 (the dual observer, with either as its state filter)
# --------------------------------------------------------------------------------------------------
NONLINEAR_ROADS = (3, 5)  # road_estimator codes of this module
DUAL_MASS = 3  # mass_estimator code of the dual observer
# the contract's force-law parameters the estimator takes (the plant's, without the bump stops,
# which the estimators do not model)
SPRING_PARAMS = tuple(AirSpring.__dataclass_fields__)
DAMPER_PARAMS = tuple(PiecewiseDamper.__dataclass_fields__)
SPEED_REBUILD_TOL = 0.01  # relative speed change that rebuilds the model (road filter and Q)
SPEED_MIN = 0.1  # m/s, the slowest speed a model is built for (the road filter needs one)
BIAS_Q = 1.0  # N^2/s, the codes' force-bias intensity (NonlinearModel.bias_q)


def force_laws(cfg) -> tuple[AirSpring | None, PiecewiseDamper | None]:
    """The air spring and the damper the configuration tells (None: the linear k_s, c_s)."""
    spring = AirSpring(**{n: float(getattr(cfg, n)) for n in SPRING_PARAMS}) if cfg.spring_model == 1 else None
    damper = PiecewiseDamper(**{n: float(getattr(cfg, n)) for n in DAMPER_PARAMS}) if cfg.damper_model == 1 else None
    return spring, damper


def config_problems(cfg) -> list[str]:
    """Messages for the nonlinear-model parameters of an ``EstimatorConfig``: the ranges of the
    plant's force laws (plant/suspension_forces.FORCE_RANGES), a load the air spring cannot carry
    (AirSpring.problems, as the plant), and settings the nonlinear codes do not take."""
    msgs = []
    for name in ("spring_model", "damper_model"):
        if getattr(cfg, name) not in (0, 1):
            msgs.append(f"{name} = {getattr(cfg, name)!r} is outside the allowed values {{0, 1}}")
    for name in SPRING_PARAMS + DAMPER_PARAMS:
        msgs.append(check_range(name, float(getattr(cfg, name)), *FORCE_RANGES[name]))
    msgs = [m for m in msgs if m]
    if not msgs and cfg.spring_model == 1:
        msgs += force_laws(cfg)[0].problems(float(cfg.m_s_nominal))
    road, mass = int(cfg.road_estimator), int(cfg.mass_estimator)
    nonlinear = road in NONLINEAR_ROADS or mass == DUAL_MASS
    if (cfg.spring_model == 1 or cfg.damper_model == 1) and not nonlinear:
        msgs.append(f"spring_model = {cfg.spring_model} / damper_model = {cfg.damper_model}: only road_estimator "
                    f"{' or '.join(map(str, NONLINEAR_ROADS))} models the nonlinear suspension, not "
                    f"road_estimator = {road} (it takes the linear k_s and c_s)")
    if (cfg.spring_model == 1 or cfg.damper_model == 1) and mass == 1:
        # on the default nonlinear car from 492 kg it ends near 200 kg and takes the road with it
        msgs.append(f"mass_estimator = 1 (RLS) regresses on the linear k_s and c_s: with spring_model = "
                    f"{cfg.spring_model} / damper_model = {cfg.damper_model} use mass_estimator 0 (off) or "
                    f"{DUAL_MASS} (dual observer)")
    if nonlinear and int(cfg.acc_sampling) != 0:
        msgs.append(f"acc_sampling = {cfg.acc_sampling!r}: road_estimator {road} takes accelerations sampled at "
                    "the end of the step only (acc_sampling = 0)")
    return msgs


class NonlinearRoadFilter(RoadFilter):
    """A ``RoadFilter`` over ``EKF`` / ``UKF`` (class attribute ``state_class``) on the nonlinear
    model the configuration tells (``spring_model``, ``damper_model`` and the plant's parameter
    names; the linear k_s, c_s of the model otherwise).

    Process noise is that of the linear model at the static point for the road intensity of
    ``road_class`` (1..8), or of ``default_class`` while it is 0 (the online class is not fed
    back). The model is rebuilt when the speed moves by more than 1 % or the step changes, the
    estimate and covariance kept; ``set_mass`` (the composer's RLS) changes the mass the maps
    are evaluated at. Not modelled: the bump stops, contact loss, the start height."""

    state_class: type = EKF

    def __init__(self, cfg):
        super().__init__(cfg)
        self.spring, self.damper = force_laws(cfg)
        self.R = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std, cfg.defl_noise_std)
        self.gd_n0 = iso8608.class_psd_n0(int(cfg.road_class) or int(cfg.tuning.default_class))
        self.m_s = float(cfg.m_s_nominal)
        self.filter = None
        self.speed: float | None = None

    def _model(self, speed: float) -> NonlinearModel:
        return NonlinearModel(self.cfg.vehicle(), self.spring, self.damper, speed, self.gd_n0, self.cfg.tuning.road_model,
                              BIAS_Q)

    def _ensure(self, speed: float, h: float) -> None:
        speed = max(speed, SPEED_MIN)
        if self.filter is None:
            self.filter = self._new_filter(self._model(speed), h)
        elif h != self.h or abs(speed - self.speed) > SPEED_REBUILD_TOL * self.speed:
            model = self._model(speed)
            self.filter_state().set_model(model, h, model.process_noise(self.m_s, h))
        else:
            return
        self.speed, self.h = speed, h
        self.model_builds += 1

    def _new_filter(self, model: NonlinearModel, h: float):
        return self.state_class(model, h, self.R, self.m_s)

    def filter_state(self):
        """The state filter (``EKF`` / ``UKF``)."""
        return self.filter

    def step(self, z, rows, speed, h) -> None:
        self._ensure(speed, h)
        st = self.filter_state()
        try:
            self.filter.step(z, rows)
        except (ValueError, np.linalg.LinAlgError):  # a closed air volume, a lost covariance:
            self.x, self.road_variance, self.nis = [math.nan] * N_STATES, math.nan, math.nan
            return  # the composer re-initialises (reset, status 2)
        self.x = state_list(st.x)
        self.road_variance = float(st.P[4, 4])
        self.nis = float(st.nis)

    def set_mass(self, m_s: float) -> None:
        self.m_s = float(m_s)
        if self.filter is not None:
            self.filter_state().m_s = self.m_s

    def reset(self) -> None:
        if self.filter is not None:
            self.filter_state().reset(self.R)
        self.x = [0.0] * N_STATES


class UKFRoadFilter(NonlinearRoadFilter):
    """road_estimator 5: the UKF on the nonlinear model."""

    state_class = UKF


class DualObserverFilter(NonlinearRoadFilter):
    """mass_estimator 3: paper 003's dual observer, its state filter the EKF (road_estimator 3)
    or the UKF (5), starting at m_s_nominal; gives the road and its own mass."""

    def __init__(self, cfg):
        super().__init__(cfg)
        self.state_class = UKF if int(cfg.road_estimator) == 5 else EKF
        self.mass = self.m_s

    def _new_filter(self, model: NonlinearModel, h: float):
        return DualObserver(model, h, self.R, self.m_s, state=self.state_class)

    def filter_state(self):
        return self.filter.state

    def step(self, z, rows, speed, h) -> None:
        super().step(z, rows, speed, h)
        self.mass = self.filter.mass

    def set_mass(self, m_s: float) -> None:  # it has its own
        pass

    def reset(self) -> None:
        super().reset()
        if self.filter is not None:  # the mass filter keeps its estimate, its uncertainty reopens
            self.filter.p_theta = (THETA_REL0 * self.filter.theta) ** 2
