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
- ``UKF``: filterpy's UnscentedKalmanFilter (Merwe scaled sigma points) on the same maps.
- ``DualObserver`` (paper 003, Section 4): a state filter (the EKF) and a sprung-mass filter, a
  scalar Kalman filter on theta = 1/m_s with the body acceleration as measurement,
  a_s = f_1(x) + theta (f_0(x) - F_d(v)), exchanging their estimates every step. With a
  self-levelling air spring the dynamic spring force is (A_e p_atm + m_s g) ((V_0/V)^kappa - 1),
  affine in m_s: f_1 is its part per kg (times 1 kg), f_0 the part at no load.

The paper's observer is a feedback-linearised KF; its transformation is not in the text, so the
state filter here is the EKF, which the paper compares it with. Process noise Q is the linear
model's at the static point (estimators/model.py), the same for all three filters. The estimators
do not model the bump stops or contact loss.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from plant.nonlinear_car import linearised_vehicle
from plant.suspension_forces import AirSpring, PiecewiseDamper
from plant.vehicle import Vehicle

from .kalman import stationary_covariance
from .model import IVS, IZS, N_STATES, DiscreteModel, RoadModel, output_matrix, road_coefficients, state_matrix


@dataclass(frozen=True)
class NonlinearModel:
    """The estimators' nonlinear quarter car at one speed (m/s) and road intensity Gd(n0) (m^3).

    ``vehicle`` gives m_u, k_t and the linear k_s, c_s used where ``spring`` or ``damper`` is None;
    the sprung mass is an argument of every map (the dual observer changes it).
    """

    vehicle: Vehicle
    spring: AirSpring | None
    damper: PiecewiseDamper | None
    speed: float
    gd_n0: float
    road: RoadModel = field(default_factory=RoadModel)

    def forces(self, x, m_s: float) -> tuple[float, float]:
        """(spring's dynamic force, damper force) in N at state x."""
        d = x[2] - x[0]
        v = x[1] - x[3]
        f_s = self.vehicle.k_s * d if self.spring is None else self.spring.force(d, m_s)
        f_d = self.vehicle.c_s * v if self.damper is None else self.damper.force(v)
        return f_s, f_d

    def _accelerations(self, x, m_s: float) -> tuple[float, float]:
        f_s, f_d = self.forces(x, m_s)
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
        return [x[1], a_s, x[3], a_u, x[5], a_r]

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

    def local_vehicle(self, x: np.ndarray, m_s: float) -> Vehicle:
        """The linear vehicle with the spring's and the damper's slopes at x."""
        d, v = x[2] - x[0], x[1] - x[3]
        return self.vehicle.with_(m_s=m_s,
                                  k_s=self.vehicle.k_s if self.spring is None else self.spring.slope(d, m_s),
                                  c_s=self.vehicle.c_s if self.damper is None else self.damper.slope(v))

    def jacobian(self, x: np.ndarray, m_s: float) -> np.ndarray:
        """d x' / d x (6x6) at x."""
        return state_matrix(self.local_vehicle(x, m_s), self.speed, self.road)

    def measurement_jacobian(self, x: np.ndarray, m_s: float) -> np.ndarray:
        """d measure / d x (3x6) at x."""
        return output_matrix(self.local_vehicle(x, m_s))

    def linear_model(self, m_s: float, h: float) -> DiscreteModel:
        """The linear model of the static point (its Q_d serves the nonlinear filters)."""
        return DiscreteModel.build(linearised_vehicle(self.vehicle, self.spring, self.damper, m_s),
                                   self.speed, self.gd_n0, h, self.road)

    def mass_terms(self, x: np.ndarray) -> tuple[float, float]:
        """(f_1, f_0 - F_d) in a_s = f_1 + (f_0 - F_d) / m_s: the spring force per kg of load (N/kg)
        and the suspension force at no load (N)."""
        f_0, f_d = self.forces(x, 0.0)
        f_1 = self.forces(x, 1.0)[0] - f_0
        return f_1, f_0 - f_d


def _start_covariance(lin: DiscreteModel, R: np.ndarray) -> np.ndarray:
    """The linear filter's stationary posterior covariance (a consistent start), else Q."""
    ss = stationary_covariance(lin.Phi, lin.Q, lin.H, R)
    return lin.Q.copy() if ss is None else ss[1].copy()


class EKF:
    """Extended Kalman filter on ``NonlinearModel`` (filterpy's ExtendedKalmanFilter).

    ``step(z)`` takes z = [acc_sprung, acc_unsprung, deflection] and returns x_{k|k}."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s: float):
        self.model, self.h, self.m_s = model, float(h), float(m_s)
        lin = model.linear_model(m_s, h)
        self.kf = ExtendedKalmanFilter(dim_x=N_STATES, dim_z=3)
        self.kf.x = np.zeros(N_STATES)  # 1-D, as the maps return it (filterpy's default is a column)
        self.kf.Q, self.kf.R = lin.Q, R
        self.kf.P = _start_covariance(lin, R)
        self.kf.predict_x = lambda u=0: setattr(self.kf, "x", model.propagate(self.kf.x, self.m_s, self.h))

    @property
    def x(self) -> np.ndarray:
        return self.kf.x

    def step(self, z: np.ndarray) -> np.ndarray:
        m, h, kf = self.model, self.h, self.kf
        Ah = m.jacobian(kf.x, self.m_s) * h
        Ah2 = Ah @ Ah
        kf.F = np.eye(N_STATES) + Ah + Ah2 / 2 + Ah2 @ Ah / 6 + Ah2 @ Ah2 / 24
        kf.predict()
        kf.update(np.asarray(z, float), lambda x: m.measurement_jacobian(x, self.m_s), lambda x: m.measure(x, self.m_s))
        return kf.x


class UKF:
    """Unscented Kalman filter on ``NonlinearModel`` (filterpy's UnscentedKalmanFilter, Merwe's
    scaled sigma points)."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s: float, alpha: float = 0.5):
        self.model, self.h, self.m_s = model, float(h), float(m_s)
        lin = model.linear_model(m_s, h)
        points = MerweScaledSigmaPoints(N_STATES, alpha=alpha, beta=2.0, kappa=3.0 - N_STATES)
        self.kf = UnscentedKalmanFilter(dim_x=N_STATES, dim_z=3, dt=h, points=points,
                                        fx=lambda x, dt: model.propagate(x, self.m_s, dt),
                                        hx=lambda x: model.measure(x, self.m_s))
        self.kf.Q, self.kf.R = lin.Q, R
        self.kf.P = _start_covariance(lin, R)

    @property
    def x(self) -> np.ndarray:
        return self.kf.x

    def step(self, z: np.ndarray) -> np.ndarray:
        self.kf.predict()
        self.kf.update(np.asarray(z, float))
        return self.kf.x


class DualObserver:
    """Paper 003's dual observer: the state filter (``EKF``) runs at the mass estimate, and a scalar
    Kalman filter on theta = 1/m_s (random walk, intensity ``q_theta`` in 1/kg^2/s) updates that
    estimate from the body acceleration, with the regressor taken at the state filter's prediction
    (which does not yet contain this step's acceleration noise).

    ``acc_std`` (m/s^2) is the body-acceleration error the mass filter assumes: sensor noise plus
    the state estimate's model error."""

    def __init__(self, model: NonlinearModel, h: float, R: np.ndarray, m_s0: float,
                 q_theta: float = 1e-10, acc_std: float = 0.05, theta_std0: float | None = None):
        self.state = EKF(model, h, R, m_s0)
        self.model, self.h = model, float(h)
        self.theta = 1.0 / m_s0
        self.p_theta = (0.3 / m_s0) ** 2 if theta_std0 is None else theta_std0 ** 2
        self.q_theta = q_theta * h
        self.r_acc = acc_std ** 2

    @property
    def mass(self) -> float:
        """The sprung-mass estimate (kg)."""
        return 1.0 / self.theta

    def step(self, z: np.ndarray) -> np.ndarray:
        x = self.state.step(z)
        f_1, g = self.model.mass_terms(self.state.kf.x_prior)
        self.p_theta += self.q_theta
        s = g * g * self.p_theta + self.r_acc
        k = self.p_theta * g / s
        self.theta += k * (z[0] - f_1 - g * self.theta)
        self.p_theta *= 1.0 - k * g
        self.state.m_s = self.mass
        return x
