"""Paper 002's closed loop with a car that is not the observer's model: the eigenvalues of the
discrete loop plant -> observer -> LQR -> plant, the plant discretised here from its own matrices
(plant/half_car.py, no road), the observer's steady-state gain from scipy's Riccati solver on the
observer's model (estimators/half_car_kf.py), the controller's scheduled gain. The paper's
10-state observer on acceleration and deflection sensors turns the LQR into a negative spring
when the springs are softer than it is told (a real eigenvalue above 1: a slow divergence); the
force-error states of the default observer keep the loop stable."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_are

from suspension_estimation.controllers.controller import LQR_SCHEDULED, SuspensionController
from suspension_estimation.estimators.half_car_imm import ObserverSettings
from suspension_estimation.estimators.half_car_kf import HalfCarModel, estimate_matrix, measurement_noise
from suspension_estimation.plant.half_car import DEFAULT_HALF_CAR, state_matrices
from suspension_estimation.plant.quarter_car import SensorNoise

H = 0.01  # s, paper 002's step
P = DEFAULT_HALF_CAR
DEFAULT_Q = ObserverSettings().force_error_q
NOISE = SensorNoise()  # HalfCar's and the observer's defaults


def plant_loop_matrices(p, h: float):
    """Phi, Gamma (forces held over the step), the sensors' C, D and the map to lqr.STATES of the
    half car x = [z, theta, z_uf, z_ur, velocities] on a road at rest."""
    A, B = state_matrices(p)
    B = B[:, 2:]
    M = np.zeros((10, 10))
    M[:8, :8], M[:8, 8:] = A, B
    E = expm(M * h)
    body = np.array([[1.0, p.l_f, 0.0, 0.0], [1.0, -p.l_r, 0.0, 0.0]])
    J = np.array([[1.0, p.l_f, -1.0, 0.0], [1.0, -p.l_r, 0.0, -1.0]])
    C = np.vstack([body @ A[4:], A[6:8], np.hstack([J, np.zeros((2, 4))])])
    D = np.vstack([body @ B[4:], B[6:8], np.zeros((2, 2))])
    S = np.zeros((8, 8))
    S[:4, 4:] = np.eye(4)
    S[4:6, :4] = J
    S[6, 2] = S[7, 3] = 1.0  # tyre deflection: the wheel over a road at 0
    return E[:8, :8], E[:8, 8:], C, D, S


def growth_rate(plant, told, force_error_q: float, road_class: int = 3, speed: float = 20.0) -> float:
    """ln of the largest |eigenvalue| of the closed loop per second (> 0: diverges)."""
    Phi, Gam, Cp, Dp, _ = plant_loop_matrices(plant, H)
    o = HalfCarModel.build(told, H, 0, force_error_q)
    R = measurement_noise(0, NOISE.acc_sprung, NOISE.acc_unsprung, NOISE.deflection, 0.0)
    Pp = solve_discrete_are(o.Phi.T, o.C.T, o.process_noise(road_class, speed), R)
    L = Pp @ o.C.T @ np.linalg.inv(o.C @ Pp @ o.C.T + R)
    K, _ = SuspensionController(told, LQR_SCHEDULED, 3000.0).gain(speed, road_class, told.m_s)
    F = -K @ estimate_matrix(told, o.n)[:8]  # u_k = F xhat_k
    n, m = len(Phi), o.n
    I = np.eye(m)
    # x_k = Phi x + Gam F xhat; xhat_k = (I - L C)(Phi_o + Bd_o F) xhat + L (Cp x_k + (Dp - D_o) F xhat)
    A = np.zeros((n + m, n + m))
    A[:n, :n], A[:n, n:] = Phi, Gam @ F
    A[n:, :n] = L @ Cp @ Phi
    A[n:, n:] = (I - L @ o.C) @ (o.Phi + o.Bd @ F) + L @ Cp @ Gam @ F + L @ (Dp - o.D) @ F
    return float(np.log(np.max(np.abs(np.linalg.eigvals(A)))) / H)


def test_the_plant_matrices_here_are_the_observers_on_the_exact_car():
    """The loop's two halves agree where they should: the observer's model, restricted to the
    vehicle, is this plant (so an unstable loop below is the mismatch, not a slip here)."""
    Phi, Gam, C, D, _ = plant_loop_matrices(P, H)
    o = HalfCarModel.build(P, H, 0)
    assert np.allclose(o.Phi[:8, :8], Phi, atol=1e-12)
    assert np.allclose(o.Bd[:8], Gam, rtol=1e-9, atol=1e-15)
    assert np.allclose(o.C[:, :8], C) and np.allclose(o.D, D)


def test_the_loop_on_the_exact_car_is_stable_with_either_observer():
    for q in (0.0, DEFAULT_Q):
        assert growth_rate(P, P, q) < 0.0


@pytest.mark.parametrize("springs", [0.85, 0.7])
def test_the_papers_observer_diverges_with_softer_springs(springs):
    """Doubling in about 2 s at -15 % (docs/paper-reproductions.md: 224-271 mm in 20 s)."""
    soft = P.with_(k_f=springs * P.k_f, k_r=springs * P.k_r)
    assert growth_rate(soft, P, 0.0) > 0.2


@pytest.mark.parametrize("road_class,speed,mass", [(2, 10.0, 0.75), (3, 20.0, 1.0), (4, 30.0, 1.25)])
def test_the_default_observer_keeps_the_loop_stable_on_a_car_that_is_not_its_model(road_class, speed, mass):
    told = P.with_(m_s=mass * P.m_s)
    errors = [dict(k_f=0.7, k_r=0.7), dict(k_f=0.85, k_r=0.85), dict(k_f=1.3, k_r=1.3), dict(k_f=0.7),
              dict(k_r=0.7), dict(c_f=0.5, c_r=0.5), dict(c_f=1.5, c_r=1.5), dict(k_tf=0.8, k_tr=0.8),
              dict(k_tf=1.2, k_tr=1.2), dict(pitch_inertia=0.7), dict(pitch_inertia=1.3), dict(m_uf=1.3, m_ur=1.3)]
    for e in errors:
        plant = told.with_(**{k: s * getattr(told, k) for k, s in e.items()})
        assert growth_rate(plant, told, DEFAULT_Q, road_class, speed) < 0.0, e
