"""Nonlinear quarter car (paper 003): air spring, asymmetric damper, bump stops, contact loss.

Equations of motion (displacements upwards from static equilibrium, as in the linear plant):

    m_s a_s =  F_s(delta) + F_b(delta) - F_d(v)
    m_u a_u = -F_s(delta) - F_b(delta) + F_d(v) + F_t

with delta = z_u - z_s the compression, v = v_s - v_u, F_s the air spring's (or the linear
spring's) dynamic force, F_b the bump stops, F_d the damper and F_t = max(k_t (z_r - z_u),
-(m_s + m_u) g) the dynamic tyre force, which cannot make the total tyre force pull
(plant/suspension_forces.py). Gravity is balanced by the preloads, so the car at rest on the road
has every displacement equal to the road height and every force zero.

Integration: classical RK4 in scalar Python with substeps of at most ``H_MAX`` inside each
communication step, the road held over the step. The force laws are continuous (the damper knees,
the stops and the contact loss only break their slopes), so RK4 keeps its accuracy across them at
this substep (tests/test_nonlinear_plant.py checks it against scipy's DOP853).
"""
from __future__ import annotations

import math

import numpy as np

from .quarter_car import HELD, LINEAR, QuarterCar, SensorNoise
from .sensors import SensorErrors
from .suspension_forces import DEFAULT_BUMP_STOPS, G, AirSpring, BumpStops, PiecewiseDamper, tyre_force
from .vehicle import Vehicle

H_MAX = 0.5e-3  # s, the longest RK4 substep: wheel hop (11 Hz) and the stops at omega*h < 0.1
# The model holds while the air volume stays above this fraction of V_0 (the bump stop keeps the
# car far from it): beyond it a step is refused, and the force is held finite until then.
_MIN_VOLUME_RATIO = 0.01


def linearised_vehicle(vehicle: Vehicle, spring: AirSpring | None, damper: PiecewiseDamper | None,
                       m_s: float | None = None) -> Vehicle:
    """The linear vehicle of the static point at sprung mass ``m_s`` (kg): k_s from the air
    spring's slope there, c_s from the damper's mean low-speed slope (the linear values of
    ``vehicle`` where ``spring`` or ``damper`` is None)."""
    m_s = vehicle.m_s if m_s is None else m_s
    return vehicle.with_(m_s=m_s, k_s=vehicle.k_s if spring is None else spring.stiffness(m_s),
                         c_s=vehicle.c_s if damper is None else damper.damping())


def _constants(vehicle: Vehicle, spring: AirSpring | None, damper: PiecewiseDamper | None,
               stops: BumpStops, m_s: float) -> tuple:
    """Everything the right-hand side needs, as plain floats (picklable, fast to unpack)."""
    if spring is None:
        air = (0.0, 0.0, 0.0)
        closed = math.inf
    else:
        air = (spring.air_area * spring.static_pressure(m_s), spring.air_area / spring.air_volume,
               spring.air_kappa)
        closed = (1.0 - _MIN_VOLUME_RATIO) * spring.air_volume / spring.air_area
    if damper is None:
        c = vehicle.c_s
        damp = (c, c, math.inf, math.inf, c, c)
    else:
        damp = (damper.damper_c_rebound, damper.damper_c_compression, damper.damper_knee_rebound,
                damper.damper_knee_compression, damper.damper_c_rebound_high, damper.damper_c_compression_high)
    k_b = stops.bump_stop_stiffness
    gaps = (stops.bump_stop_gap, stops.rebound_stop_gap) if k_b > 0 else (math.inf, math.inf)
    return (spring is not None, vehicle.k_s, *air, *damp, *gaps, k_b, vehicle.k_t, m_s, vehicle.m_u,
            (m_s + vehicle.m_u) * G, closed)


def _rhs(c: tuple, z_s: float, v_s: float, z_u: float, v_u: float, road: float) -> tuple[float, float, float]:
    """(a_s, a_u, damper power F_d v) at the state, road held at ``road``."""
    air, k_s, a, b, kappa, c_r, c_c, v_r, v_c, c_rh, c_ch, gap_c, gap_r, k_b, k_t, m_s, m_u, load, _ = c
    d = z_u - z_s
    if air:
        ratio = 1.0 - b * d
        if ratio < _MIN_VOLUME_RATIO:
            ratio = _MIN_VOLUME_RATIO
        f_s = a * (ratio ** -kappa - 1.0)
    else:
        f_s = k_s * d
    if d > gap_c:
        f_s += k_b * (d - gap_c)
    elif d < -gap_r:
        f_s += k_b * (d + gap_r)
    v = v_s - v_u
    if v >= 0.0:
        f_d = c_r * v if v <= v_r else c_r * v_r + c_rh * (v - v_r)
    else:
        f_d = c_c * v if v >= -v_c else -c_c * v_c + c_ch * (v + v_c)
    f_t = k_t * (road - z_u)  # suspension_forces.tyre_force, inlined: this runs 4 times a substep
    if f_t < -load:
        f_t = -load
    return (f_s - f_d) / m_s, (f_d - f_s + f_t) / m_u, f_d * v


class NonlinearQuarterCar(QuarterCar):
    """The plant with the nonlinear force laws; the interface of :class:`QuarterCar`.

    ``spring`` None is the linear spring k_s of ``vehicle``, ``damper`` None its linear damper
    c_s. Beyond QuarterCar it reports ``tire_contact`` (1 when the tyre stayed on the road over
    the last step, 0 when it left it), ``bump_stop`` (0 free, 1 the compression stop, 2 the
    rebound stop touched during the last step) and ``dissipated``, the work done by the damper
    since ``settle`` (J). A sprung-mass change is levelled: the air spring's pressure follows the
    load so the static point stays (AirSpring).
    """

    def __init__(self, vehicle: Vehicle, spring: AirSpring | None = None, damper: PiecewiseDamper | None = None,
                 stops: BumpStops = DEFAULT_BUMP_STOPS, noise: SensorNoise = SensorNoise(), noise_seed: int = 1,
                 acc_sampling: int = 0, errors: SensorErrors = SensorErrors(), road_input: str = HELD):
        super().__init__(vehicle, noise, noise_seed, acc_sampling, errors, road_input)
        self.spring, self.damper, self.stops = spring, damper, stops
        self._c: tuple = ()
        self._m_s: float | None = None
        self.tire_contact = 1
        self.bump_stop = 0
        self.dissipated = 0.0
        self._set_mass(vehicle.m_s)

    def problems(self, m_s: float) -> list[str]:
        """Messages for a sprung mass (kg) this car cannot carry (empty when it can)."""
        return [] if self.spring is None else self.spring.problems(m_s)

    def _set_mass(self, m_s: float) -> None:
        if m_s != self._m_s:
            problems = self.problems(m_s)
            if problems:
                raise ValueError("; ".join(problems))
            self._c = _constants(self.vehicle, self.spring, self.damper, self.stops, m_s)
            self._m_s = m_s

    def linearisation(self, m_s: float | None = None) -> Vehicle:
        """The linear vehicle of the static point at sprung mass ``m_s`` (kg)."""
        return linearised_vehicle(self.vehicle, self.spring, self.damper, m_s)

    def settle(self, road_height: float) -> None:
        super().settle(road_height)
        self.tire_contact = 1
        self.bump_stop = 0
        self.dissipated = 0.0

    def step(self, road_height: float, h: float, m_s: float | None = None) -> None:
        """Advance by h seconds to the road ``road_height`` (m), held over the step or reached
        linearly from the last one (``road_input``); RK4 substeps."""
        self._set_mass(self.vehicle.m_s if m_s is None else m_s)
        c = self._c
        gap_c, gap_r, k_t, load, closed = c[11], c[12], c[14], c[17], c[18]
        n = max(1, math.ceil(h / H_MAX - 1e-9))
        dt = h / n
        r = road_height
        r0 = self.road if self.road_input == LINEAR else r
        dr = (r - r0) / n  # the road's move over a substep (0 held)
        z_s, v_s, z_u, v_u = x0 = self.x.tolist()
        e = self.dissipated
        contact, stop, d_max = 1, 0, 0.0
        for j in range(n):
            ra, rm, rb = r0 + j * dr, r0 + (j + 0.5) * dr, r0 + (j + 1) * dr
            a1, b1, p1 = _rhs(c, z_s, v_s, z_u, v_u, ra)
            q = 0.5 * dt
            a2, b2, p2 = _rhs(c, z_s + q * v_s, v_s + q * a1, z_u + q * v_u, v_u + q * b1, rm)
            s2, w2 = v_s + q * a1, v_u + q * b1
            a3, b3, p3 = _rhs(c, z_s + q * s2, v_s + q * a2, z_u + q * w2, v_u + q * b2, rm)
            s3, w3 = v_s + q * a2, v_u + q * b2
            a4, b4, p4 = _rhs(c, z_s + dt * s3, v_s + dt * a3, z_u + dt * w3, v_u + dt * b3, rb)
            s4, w4 = v_s + dt * a3, v_u + dt * b3
            k = dt / 6.0
            z_s += k * (v_s + 2 * s2 + 2 * s3 + s4)
            z_u += k * (v_u + 2 * w2 + 2 * w3 + w4)
            v_s += k * (a1 + 2 * a2 + 2 * a3 + a4)
            v_u += k * (b1 + 2 * b2 + 2 * b3 + b4)
            e += k * (p1 + 2 * p2 + 2 * p3 + p4)
            d = z_u - z_s
            if d > d_max:
                d_max = d
            if d > gap_c:
                stop = 1
            elif d < -gap_r:
                stop = 2
            if k_t * (rb - z_u) < -load:
                contact = 0
        if not d_max < closed:
            raise ValueError(f"at road_height = {r!r} m the suspension was compressed by {d_max:.4g} m, past "
                             f"{closed:.4g} m = 99 % of the air spring's stroke air_volume/air_area: the model "
                             "does not hold there")
        if not all(map(math.isfinite, (z_s, v_s, z_u, v_u))):
            raise ValueError(f"at road_height = {r!r} m the plant's state became non-finite")
        if self.acc_sampling == 1:
            acc = ((v_s - x0[1]) / h, (v_u - x0[3]) / h)
        else:
            acc = _rhs(c, z_s, v_s, z_u, v_u, r)[:2]
        self.x = np.array([z_s, v_s, z_u, v_u])
        self.road = r
        self.dissipated = e
        self.tire_contact, self.bump_stop = contact, stop
        self.acc_true = acc
        self._measure(acc, z_s, z_u, h)

    @property
    def tire_force(self) -> float:
        """Dynamic tyre force (N, pushes the wheel up), >= -(m_s + m_u) g: the tyre cannot pull."""
        return tyre_force(self.vehicle.k_t, self.road, float(self.x[2]), self._c[17])
