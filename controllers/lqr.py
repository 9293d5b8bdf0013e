"""LQR of the half car (paper 002, eqs. 10-14) on relative states, and its stationary response.

The design model is the half car of ``plant.half_car`` (eqs. 1-4 with the pitch sign corrected,
passive dampers c_f, c_r beside the actuators), written in the 8 relative states

    xi = [v_z, omega, v_uf, v_ur, d_f, d_r, e_f, e_r]

body heave velocity at the CG (m/s), pitch rate (rad/s, nose up), wheel velocities (m/s), the
suspension deflections d = body point above the axle minus wheel (m, eq. 3: d_f = z + l_f theta
- z_uf) and the tyre deflections e = wheel minus road (m), driven by the actuator forces
u = [f_f, f_r] (N, pushing body and wheel apart) and the road velocities w = [q_f', q_r'] (m/s):

    xi' = A xi + B u + G w,    G = [0; 0; -I] on the tyre deflections.

``relative_model`` builds A and B from ``plant.half_car.state_matrices`` by the change of
coordinates [d_f, d_r, e_f, e_r] = J q - S [q_f, q_r] (q = [z, theta, z_uf, z_ur]); the road
heights cancel (the springs feel only their elongations), so the model is closed without them.

Why these states: the plant FMU is fed absolute road elevations and settles on whatever level it
starts at, so absolute heights carry an arbitrary offset that a gain on them would turn into force.
Paper 002 designs on X = [x', x, q] with the first-order road q' = -2 pi f0 q + N omega (eqs. 5,
8-9). In the coordinates above that is xi' = A xi + B u - 2 pi f0 G q + G N omega: the heights q
enter only through the road's drift to its mean, 2 pi f0 q, and leave the equations as f0 -> 0
(the paper's f0 = 0.01 Hz); the cost of eq. 11 holds only relative quantities. So this 8-state
LQR is the paper's in the limit f0 -> 0, the road velocity white noise of one-sided PSD
4 pi^2 G_q(n0) n0^2 V (``road_intensity``; tests/test_controller.py checks that the paper's
10-state gain at f0 = 0.01 Hz is this one, its gain on the heights near 0).

Cost (eqs. 10-12): J0 = y' W y with y = [d_f, a_f, e_f, d_r, a_r, e_r], a_f and a_r the body
accelerations above the axles (eq. 3: x_H'' + l_f theta'', x_H'' - l_r theta''), W = diag(q1, q2,
q3, q4, q5, q6). y = C xi + E u (the accelerations depend on the forces), so

    Q = C' W C,   N = C' W E,   R = E' W E.

Only the accelerations depend on the forces, so with q5 = q2: R = q2 E_a' E_a, E_a = [[1/m + l_f^2/I,
1/m - l_f l_r/I], [1/m - l_f l_r/I, 1/m + l_r^2/I]], det E_a = L^2 / (m I) > 0, so R is positive
definite for q2 > 0 and no regularisation is needed; q2 = 0, which eq. 17's bounds allow, leaves
the R^-1 of eq. 14 undefined and is refused.

Eq. 14, the Riccati equation, is solved by ``scipy.linalg.solve_continuous_are`` with the cross
term N; eq. 13 as printed, f = -(B' P + N') x, lacks the R^-1 of the LQR: the gain here is

    K = R^-1 (B' P + N'),   u = -K xi.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_continuous_are, solve_continuous_lyapunov

from ..plant.half_car import HalfCarParams, state_matrices
from ..plant.iso8608 import N0

STATES = ("heave_velocity", "pitch_rate", "v_u_front", "v_u_rear", "susp_deflection_front",
          "susp_deflection_rear", "tire_deflection_front", "tire_deflection_rear")
# the output y of the cost (eq. 11), in the order of its weights q1 .. q6
COST_OUTPUTS = ("susp_deflection_front", "acc_body_front", "tire_deflection_front",
                "susp_deflection_rear", "acc_body_rear", "tire_deflection_rear")


def deflection_map(p: HalfCarParams) -> np.ndarray:
    """J (4x4): [d_f, d_r, z_uf, z_ur] = J [z, theta, z_uf, z_ur] (eq. 3)."""
    return np.array([[1.0, p.l_f, -1.0, 0.0], [1.0, -p.l_r, 0.0, -1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def relative_model(p: HalfCarParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A 8x8, B 8x2, G 8x2) of xi' = A xi + B u + G w (module doc) from the plant's matrices."""
    Aq, Bq = state_matrices(p)  # x = [q, q'], inputs [q_f, q_r, f_f, f_r]
    J = deflection_map(p)
    A = np.zeros((8, 8))
    A[:4, :4] = Aq[4:, 4:]
    A[:4, 4:] = Aq[4:, :4] @ np.linalg.inv(J)  # q = J^-1 ([d; e] + S q_road): the road part cancels
    A[4:, :4] = J
    B = np.zeros((8, 2))
    B[:4] = Bq[4:, 2:]
    G = np.zeros((8, 2))
    G[6:, :] = -np.eye(2)
    return A, B, G


def cost_outputs(p: HalfCarParams) -> tuple[np.ndarray, np.ndarray]:
    """(C 6x8, E 6x2) of y = C xi + E u, y = COST_OUTPUTS (eq. 11 with eq. 3)."""
    A, B, _ = relative_model(p)
    C = np.zeros((6, 8))
    E = np.zeros((6, 2))
    C[0, 4] = C[3, 5] = C[2, 6] = C[5, 7] = 1.0
    C[1], E[1] = A[0] + p.l_f * A[1], B[0] + p.l_f * B[1]
    C[4], E[4] = A[0] - p.l_r * A[1], B[0] - p.l_r * B[1]
    return C, E


@dataclass(frozen=True)
class DesignModel:
    """The matrices of one car (module doc), built once: the LQR and the stationary response."""

    car: HalfCarParams
    A: np.ndarray
    B: np.ndarray
    G: np.ndarray
    C: np.ndarray
    E: np.ndarray

    @classmethod
    def of(cls, p: HalfCarParams) -> "DesignModel":
        return cls(p, *relative_model(p), *cost_outputs(p))

    def cost(self, q1: float, q2: float, q3: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Q, R, N) of eq. 10 from the cost of eq. 11 with q4 = q1, q5 = q2, q6 = q3 (eq. 17's ties)."""
        W = np.diag([q1, q2, q3, q1, q2, q3])
        return self.C.T @ W @ self.C, self.E.T @ W @ self.E, self.C.T @ W @ self.E

    def gain(self, q1: float, q2: float, q3: float) -> np.ndarray:
        """K (2x8, N per state unit) of u = -K xi: eqs. 13-14 with R^-1. Raises ValueError for
        weights outside q1 >= 0, q2 > 0, q3 >= 0, or when eq. 14 has no stabilising solution."""
        if not (q1 >= 0.0 and q2 > 0.0 and q3 >= 0.0 and max(q1, q2, q3) < np.inf):
            raise ValueError(f"LQR weights q1 = {q1!r}, q2 = {q2!r}, q3 = {q3!r}: need q1 >= 0, q2 > 0, q3 >= 0, "
                             "finite")
        Q, R, N = self.cost(q1, q2, q3)
        try:
            P = solve_continuous_are(self.A, self.B, Q, R, s=N)
        except (np.linalg.LinAlgError, ValueError) as e:
            raise ValueError(f"the Riccati equation (eq. 14) with q1 = {q1:g}, q2 = {q2:g}, q3 = {q3:g} has no "
                             f"stabilising solution ({e})") from None
        K = np.linalg.solve(R, self.B.T @ P + N.T)
        if not np.all(np.isfinite(K)):
            raise ValueError(f"the LQR gain with q1 = {q1:g}, q2 = {q2:g}, q3 = {q3:g} is not finite")
        return K

    def closed_loop(self, K: np.ndarray) -> np.ndarray:
        """A - B K: the design model with u = -K xi."""
        return self.A - self.B @ K

    def margin(self, K: np.ndarray) -> float:
        """-max Re(eig(A - B K)) in 1/s: positive when the closed loop is asymptotically stable."""
        return float(-np.max(np.linalg.eigvals(self.closed_loop(K)).real))

    def covariance(self, K: np.ndarray, intensity: float = 1.0) -> np.ndarray:
        """Stationary covariance of xi (8x8) under u = -K xi with independent white road velocities
        of ``intensity`` under each tyre (paper 002's omega_f, omega_r; the wheelbase delay left
        out): (A - B K) S + S (A - B K)' + W G G' = 0."""
        return solve_continuous_lyapunov(self.closed_loop(K), -intensity * (self.G @ self.G.T))


def lqr_gain(p: HalfCarParams, q1: float, q2: float, q3: float) -> np.ndarray:
    """``DesignModel.gain`` of the car p."""
    return DesignModel.of(p).gain(q1, q2, q3)


def skyhook_gain(p: HalfCarParams, c_sky: float) -> np.ndarray:
    """K of the skyhook law f = -c_sky v_b at each axle, v_b the body point's velocity (eq. 3:
    v_z + l_f omega front, v_z - l_r omega rear), as u = -K xi."""
    K = np.zeros((2, 8))
    K[0, :2] = c_sky, c_sky * p.l_f
    K[1, :2] = c_sky, -c_sky * p.l_r
    return K


def road_intensity(gd_n0: float, speed: float) -> float:
    """Intensity (m^2/s, two-sided: E w(t) w(s) = W delta(t - s)) of the white road velocity of an
    ISO 8608 road of Gd(n0) (m^3) with waviness 2 at ``speed`` (m/s): its one-sided PSD is flat,
    (2 pi f)^2 Gd(n0) (n0 V / f)^2 / V = 4 pi^2 Gd(n0) n0^2 V, and W is half of it."""
    return 2.0 * np.pi ** 2 * gd_n0 * N0 ** 2 * speed
