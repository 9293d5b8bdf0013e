"""Linear quarter-car plant, advanced exactly over each step with the road held (or followed
linearly from the previous input, ``LINEAR``).

Equations of motion (displacements upwards from static equilibrium):

    m_s * a_s = -k_s (z_s - z_u) - c_s (v_s - v_u)
    m_u * a_u =  k_s (z_s - z_u) + c_s (v_s - v_u) - k_t (z_u - z_r)

State x = [z_s, v_s, z_u, v_u] (m, m/s), input the road height z_r (m). Over a step of length
h the road is held (zero-order hold) and the state advances with the exact discretisation
[Ad Bd; 0 1] = expm([A B; 0 0] h). With ``road_input`` = ``LINEAR`` the road moves linearly
from the previous input to this one over the step, x[k+1] = Ad x[k] + Bd r[k-1] + G1 (r[k] - r[k-1]),
G1 = (1/h) int_0^h e^{A(h-s)} B s ds (the same matrix exponential, one order up): a continuous
road sampled at the step, where the held road is a staircase whose jumps the point-sampled wheel
acceleration sees (on a ramp, a bias of -k_t v_r h / (2 m_u): 1.4 m/s2 on a 3 % grade at 72 km/h,
1 ms). Gravity is balanced by the static preload: when the sprung
mass changes the suspension is assumed levelled, so the equilibrium does not move.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .sensors import DelayLine, SensorErrors
from .step_size import same_step
from .vehicle import Vehicle


def state_matrices(v: Vehicle) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (4x4) and B (4,) with x' = A x + B z_r."""
    A = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [-v.k_s / v.m_s, -v.c_s / v.m_s, v.k_s / v.m_s, v.c_s / v.m_s],
        [0.0, 0.0, 0.0, 1.0],
        [v.k_s / v.m_u, v.c_s / v.m_u, -(v.k_s + v.k_t) / v.m_u, -v.c_s / v.m_u],
    ])
    B = np.array([0.0, 0.0, 0.0, v.k_t / v.m_u])
    return A, B


# how the road moves under the tyre over a step: held at the input (a zero-order hold, as an FMU's
# input between communication points), or linearly from the previous input to this one
HELD, LINEAR = "held", "linear"
ROAD_INPUTS = (HELD, LINEAR)


def discretise_linear_input(A: np.ndarray, B: np.ndarray, h: float) -> np.ndarray:
    """G1 of the first-order hold: x[k+1] = Ad x[k] + Bd u[k-1] + G1 (u[k] - u[k-1]) for an input
    moving linearly from u[k-1] to u[k] over the step."""
    n = A.shape[0]
    M = np.zeros((n + 2, n + 2))
    M[:n, :n] = A
    M[:n, n] = B
    M[n, n + 1] = 1.0
    return np.ascontiguousarray(expm(M * h)[:n, n + 1] / h)


def discretise(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation: x[k+1] = Ad x[k] + Bd u[k]."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    E = expm(M * h)
    # contiguous copies: a strided view takes other BLAS paths and rounds differently after a copy
    return np.ascontiguousarray(E[:n, :n]), np.ascontiguousarray(E[:n, n])


# Allowed noise stds a filter assumes for the sensors (low, high), both ends included: from
# sensors better than any automotive accelerometer (10 ug) or displacement sensor (0.1 um) to
# useless ones (a plant's own noise may also be 0).
NOISE_STD_RANGES: dict[str, tuple[float, float]] = {
    "acc_sprung_noise_std": (1e-4, 1e3),  # m/s2
    "acc_unsprung_noise_std": (1e-4, 1e3),  # m/s2
    "defl_noise_std": (1e-7, 1.0),  # m
}


@dataclass(frozen=True)
class SensorNoise:
    """White-noise standard deviations of the three measurements."""

    acc_sprung: float = 0.02  # m/s^2
    acc_unsprung: float = 0.2  # m/s^2
    deflection: float = 1e-4  # m


class QuarterCar:
    """The plant: true states, true and measured outputs.

    ``acc_sampling`` 0 reports the accelerations at the end of the step; 1 reports their
    average over the step, (v[k+1] - v[k]) / h, which is exact for either road input and is what
    an accelerometer integrating over the sample gives. ``road_input``: ``HELD`` or ``LINEAR``
    (module doc).
    """

    def __init__(self, vehicle: Vehicle, noise: SensorNoise = SensorNoise(), noise_seed: int = 1,
                 acc_sampling: int = 0, errors: SensorErrors = SensorErrors(), road_input: str = HELD):
        if road_input not in ROAD_INPUTS:
            raise ValueError(f"road_input = {road_input!r} must be one of {', '.join(ROAD_INPUTS)}")
        self.road_input = road_input
        self.vehicle = vehicle
        self.noise = noise
        self.errors = errors  # offsets, biases, gains and delays of the sensors (plant/sensors.py)
        self._start_delays()
        self.acc_sampling = int(acc_sampling)
        self.rng = np.random.default_rng(noise_seed)
        self.x = np.zeros(4)
        self.road = 0.0
        self.acc_true = (0.0, 0.0)  # sprung, unsprung (m/s^2)
        self.measured = (0.0, 0.0, 0.0)  # acc_sprung, acc_unsprung (m/s^2), deflection (m)
        self._key: tuple[float, float] | None = None
        self._A = self._B = self._Ad = self._Bd = self._G1 = None
        self._rows: tuple | None = None  # rows 1 and 3 of A and B as floats (end-of-step accelerations)
        self._noise: list[list[float]] = []
        self._noise_i = 0
        self.discretisations = 0  # matrix exponentials computed (one per step size and mass)

    def settle(self, road_height: float) -> None:
        """Put the car at rest in static equilibrium on a road at ``road_height`` (m)."""
        self.x = np.array([road_height, 0.0, road_height, 0.0])
        self.road = road_height
        self.acc_true = (0.0, 0.0)
        self.measured = self.errors.apply(0.0, 0.0, 0.0)
        self._start_delays()

    def _start_delays(self) -> None:
        """Empty delay lines holding the car at rest at time 0 (accelerations and deflection 0):
        until a channel's delay has passed it reports the rest it saw before the start, not the
        first step's values undelayed."""
        self.time = 0.0  # s since settle, the clock of the delays
        self._delays = None  # no sensor errors: the measured values are the true ones plus noise
        if not self.errors.none:
            self._delays = [DelayLine(d) for d in self.errors.delays]
            for line in self._delays:
                line.push(0.0, 0.0)

    def _matrices(self, m_s: float, h: float) -> None:
        if self._key != (m_s, h):
            self._A, self._B = state_matrices(self.vehicle.with_(m_s=m_s))
            self._Ad, self._Bd = discretise(self._A, self._B, h)
            if self.road_input == LINEAR:
                self._G1 = discretise_linear_input(self._A, self._B, h)
            self._key = (m_s, h)
            self.discretisations += 1

    def step(self, road_height: float, h: float, m_s: float | None = None) -> None:
        """Advance by h seconds to the road ``road_height`` (m), held over the step or reached
        linearly from the last one (``road_input``). A step that differs
        from the previous one by rounding only (plant.step_size) reuses its discretisation."""
        if self._key is not None:
            h = same_step(h, self._key[1])
        key = (self.vehicle.m_s if m_s is None else m_s, h)
        if self._key != key:
            self._matrices(*key)
            A, B = self._A, self._B
            self._rows = (A[1].tolist(), float(B[1]), A[3].tolist(), float(B[3]))
        x0 = self.x
        if self.road_input == LINEAR:
            r0 = self.road
            x = self._Ad @ x0 + self._Bd * r0 + self._G1 * (road_height - r0)
        else:
            x = self._Ad @ x0 + self._Bd * road_height
        self.x = x
        self.road = road_height
        z_s, v_s, z_u, v_u = x.tolist()
        if self.acc_sampling == 1:
            acc = ((v_s - float(x0[1])) / h, (v_u - float(x0[3])) / h)
        else:
            r1, b1, r3, b3 = self._rows
            acc = (r1[0] * z_s + r1[1] * v_s + r1[2] * z_u + r1[3] * v_u + b1 * road_height,
                   r3[0] * z_s + r3[1] * v_s + r3[2] * z_u + r3[3] * v_u + b3 * road_height)
        self.acc_true = acc
        self._measure(acc, z_s, z_u, h)

    def _measure(self, acc: tuple[float, float], z_s: float, z_u: float, h: float) -> None:
        """The sensors' readings of the true accelerations and deflection: their errors
        (``errors``: gain, bias, offset, then the delay) and the seeded noise."""
        # the noise is drawn in blocks: the same numbers as one draw of 3 per step
        if self._noise_i >= len(self._noise):
            self._noise = self.rng.standard_normal((256, 3)).tolist()
            self._noise_i = 0
        e = self._noise[self._noise_i]
        self._noise_i += 1
        n = self.noise
        clean = (acc[0], acc[1], z_s - z_u)
        if self._delays is not None:
            self.time += h
            clean = self.errors.apply(*(line.push(self.time, v) for line, v in zip(self._delays, clean)))
        self.measured = (clean[0] + n.acc_sprung * e[0], clean[1] + n.acc_unsprung * e[1],
                         clean[2] + n.deflection * e[2])

    @property
    def tire_deflection(self) -> float:
        return float(self.x[2] - self.road)

    @property
    def tire_force(self) -> float:
        """Dynamic tyre force k_t (z_r - z_u) in N (positive pushes the wheel up)."""
        return float(self.vehicle.k_t * (self.road - self.x[2]))
