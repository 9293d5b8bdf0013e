"""Force laws of the nonlinear quarter car (paper 003): air spring, asymmetric damper, bump stops.

Sign conventions (the same as the linear plant, displacements upwards from static equilibrium):
the compression is delta = z_u - z_s (m, > 0 when the suspension shortens), the suspension
velocity is v = v_s - v_u (m/s, > 0 in rebound = extension). Every force here is the *dynamic*
force, i.e. the total force minus the static preload that carries the sprung mass, in N, positive
when it pushes the body up (and the wheel down). Gravity is then balanced by the preload exactly
as in the linear plant.

The parameters have the names and units of the QuarterCar contract's parameters, so that an
estimator can be given the same maps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from .vehicle import DEFAULT_VEHICLE

G = 9.81  # gravitational acceleration, m/s2
P_ATM = 101325.0  # atmospheric pressure, Pa


@dataclass(frozen=True)
class AirSpring:
    """Polytropic air spring with a self-levelling valve (paper 003, Section 2).

    Total force F(delta) = A_e [p_0 (V_0 / (V_0 - A_e delta))^kappa - p_atm]. The levelling valve
    keeps the static ride height: at a sprung mass m_s the air mass is such that the static
    absolute pressure is p_0 = p_atm + m_s g / A_e (at the same volume V_0), so a payload change
    leaves the static point where it is and stiffens the spring in proportion to p_0.
    """

    air_area: float  # effective area A_e, m2
    air_volume: float  # gas volume at the static ride height V_0, m3
    air_kappa: float  # polytropic exponent (1 isothermal .. 1.4 adiabatic)
    air_pressure_max: float  # highest absolute pressure the levelling system can supply, Pa

    def static_pressure(self, m_s: float) -> float:
        """p_0 (Pa, absolute) that carries ``m_s`` (kg) at the static ride height."""
        return P_ATM + m_s * G / self.air_area

    def force(self, delta: float, m_s: float) -> float:
        """Dynamic force F(delta) - m_s g in N at a compression ``delta`` in m (delta < V_0/A_e)."""
        ratio = 1.0 - self.air_area / self.air_volume * delta
        if ratio <= 0.0:
            raise ValueError(f"compression {delta!r} m closes the air volume (V_0/A_e = "
                             f"{self.air_volume / self.air_area:.4g} m)")
        return self.air_area * self.static_pressure(m_s) * (ratio ** -self.air_kappa - 1.0)

    def energy(self, delta: float, m_s: float) -> float:
        """Potential energy (J) of the dynamic force from the static point to ``delta``."""
        b = self.air_area / self.air_volume
        ratio = 1.0 - b * delta
        a = self.air_area * self.static_pressure(m_s)
        k = self.air_kappa
        integral = -math.log(ratio) / b if k == 1.0 else (ratio ** (1.0 - k) - 1.0) / (b * (k - 1.0))
        return a * (integral - delta)

    def slope(self, delta: float, m_s: float) -> float:
        """dF/d delta (N/m) at compression ``delta`` (m): kappa p_0 A_e^2 / V_0 (V_0 / V)^(kappa + 1)."""
        ratio = 1.0 - self.air_area / self.air_volume * delta
        return self.stiffness(m_s) * ratio ** (-self.air_kappa - 1.0)

    def stiffness(self, m_s: float) -> float:
        """Linearisation dF/d delta at the static point (N/m): kappa p_0 A_e^2 / V_0."""
        return self.air_kappa * self.static_pressure(m_s) * self.air_area ** 2 / self.air_volume

    def problems(self, m_s: float) -> list[str]:
        """Messages for a static load the spring cannot carry (empty when it can)."""
        p_0 = self.static_pressure(m_s)
        if p_0 <= self.air_pressure_max:
            return []
        return [f"sprung_mass = {m_s!r} kg needs a static pressure of {p_0:.4g} Pa on air_area = "
                f"{self.air_area!r} m2, above air_pressure_max = {self.air_pressure_max!r} Pa: the air spring "
                f"cannot carry it (at most {self.max_sprung_mass():.4g} kg)"]

    def max_sprung_mass(self) -> float:
        """The largest sprung mass (kg) the levelling system can carry."""
        return (self.air_pressure_max - P_ATM) * self.air_area / G

    @classmethod
    def matching(cls, m_s: float, k_s: float, p_0: float, air_kappa: float,
                 air_pressure_max: float) -> "AirSpring":
        """The air spring that carries ``m_s`` at static pressure ``p_0`` (Pa abs) with stiffness ``k_s``
        there: A_e = m_s g / (p_0 - p_atm), V_0 = kappa p_0 A_e^2 / k_s."""
        area = m_s * G / (p_0 - P_ATM)
        return cls(area, air_kappa * p_0 * area ** 2 / k_s, air_kappa, air_pressure_max)


@dataclass(frozen=True)
class PiecewiseDamper:
    """Asymmetric piecewise-linear damper (paper 003, Section 2: a slope and a knee per direction).

    F(v) = c_r v up to the rebound knee v_r, then c_r v_r + c_r,high (v - v_r); in compression
    (v < 0) the same with c_c, v_c, c_c,high. F is the force the damper exerts against the
    extension (N), so the body feels -F.
    """

    damper_c_rebound: float  # low-speed rebound slope, N.s/m
    damper_c_compression: float  # low-speed compression slope, N.s/m
    damper_knee_rebound: float  # rebound knee velocity, m/s
    damper_knee_compression: float  # compression knee velocity, m/s
    damper_c_rebound_high: float  # rebound slope beyond the knee, N.s/m
    damper_c_compression_high: float  # compression slope beyond the knee, N.s/m

    def force(self, v: float) -> float:
        """Damper force (N) at suspension velocity v = v_s - v_u (m/s)."""
        if v >= 0.0:
            knee = self.damper_knee_rebound
            if v <= knee:
                return self.damper_c_rebound * v
            return self.damper_c_rebound * knee + self.damper_c_rebound_high * (v - knee)
        knee = self.damper_knee_compression
        if v >= -knee:
            return self.damper_c_compression * v
        return -self.damper_c_compression * knee + self.damper_c_compression_high * (v + knee)

    def slope(self, v: float) -> float:
        """dF/dv (N.s/m) at suspension velocity v (m/s); at v = 0 the rebound side's."""
        if v >= 0.0:
            return self.damper_c_rebound if v <= self.damper_knee_rebound else self.damper_c_rebound_high
        return self.damper_c_compression if v >= -self.damper_knee_compression else self.damper_c_compression_high

    def damping(self) -> float:
        """Equivalent linear damping (N.s/m) at the static point: the mean of the two low-speed
        slopes, which is the first-harmonic (describing-function) gain of a sinusoidal motion
        that stays within the knees."""
        return 0.5 * (self.damper_c_rebound + self.damper_c_compression)


@dataclass(frozen=True)
class BumpStops:
    """Linear end stops: a spring of ``bump_stop_stiffness`` that acts beyond a compression of
    ``bump_stop_gap`` and beyond an extension of ``rebound_stop_gap`` (both m from the static
    point). A stiffness of 0 switches them off."""

    bump_stop_gap: float  # m
    rebound_stop_gap: float  # m
    bump_stop_stiffness: float  # N/m

    def force(self, delta: float) -> float:
        """Dynamic force (N, pushes the body up) at compression ``delta`` (m)."""
        if delta > self.bump_stop_gap:
            return self.bump_stop_stiffness * (delta - self.bump_stop_gap)
        if delta < -self.rebound_stop_gap:
            return self.bump_stop_stiffness * (delta + self.rebound_stop_gap)
        return 0.0

    def energy(self, delta: float) -> float:
        """Potential energy (J) stored in the stops at compression ``delta`` (m)."""
        f = self.force(delta)
        return 0.5 * f * f / self.bump_stop_stiffness if f else 0.0


def tyre_force(k_t: float, road: float, z_u: float, static_load: float) -> float:
    """Dynamic tyre force (N, pushes the wheel up): k_t (z_r - z_u), but the tyre cannot pull, so
    the total force static_load + k_t (z_r - z_u) stays >= 0 (contact loss below)."""
    return max(k_t * (road - z_u), -static_load)


def in_contact(tire_force: float, m_s: float, m_u: float) -> int:
    """1 when a dynamic tyre force (N) leaves the tyre pressed on the road, 0 when it would pull."""
    return int(tire_force > -(m_s + m_u) * G)


# Allowed ranges (low, high, low_inclusive, high_inclusive) of the parameters above: physical
# (positive areas, volumes, slopes; kappa between isothermal and adiabatic air) and wide enough for
# a motorcycle's or a truck's suspension; beyond them lies a unit slip.
FORCE_RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "air_area": (0.0, 1.0, False, True),  # m2
    "air_volume": (0.0, 1.0, False, True),  # m3
    "air_kappa": (1.0, 1.4, True, True),  # 1
    "air_pressure_max": (P_ATM, 1e7, False, True),  # Pa, absolute
    "damper_c_rebound": (0.0, 1e5, False, True),  # N.s/m
    "damper_c_compression": (0.0, 1e5, False, True),
    "damper_knee_rebound": (0.0, 10.0, False, True),  # m/s
    "damper_knee_compression": (0.0, 10.0, False, True),
    "damper_c_rebound_high": (0.0, 1e5, False, True),
    "damper_c_compression_high": (0.0, 1e5, False, True),
    "bump_stop_gap": (0.0, 1.0, False, True),  # m
    "rebound_stop_gap": (0.0, 1.0, False, True),
    "bump_stop_stiffness": (0.0, 1e8, True, True),  # N/m, 0 = off
}

# Defaults. Air spring: a static absolute pressure of 6 bar at the default sprung mass (passenger-
# car air springs run at about 5..10 bar static), adiabatic exponent 1.4 (the ride frequencies are
# too fast for heat exchange with the walls), area and volume then follow from carrying the default
# sprung mass with the linear default k_s at the static point; a 16 bar levelling supply. Area and
# volume are rounded to the 6 significant digits the written contract shows (docs/fmu-interface.md),
# which leaves the slope at the static point 2e-6 off 20000 N/m.
AIR_STATIC_PRESSURE = 6e5  # Pa, absolute, at the default sprung mass
_MATCHING = AirSpring.matching(DEFAULT_VEHICLE.m_s, DEFAULT_VEHICLE.k_s, AIR_STATIC_PRESSURE,
                               air_kappa=1.4, air_pressure_max=16e5)
DEFAULT_AIR_SPRING = replace(_MATCHING, air_area=float(f"{_MATCHING.air_area:.6g}"),
                             air_volume=float(f"{_MATCHING.air_volume:.6g}"))
# Damper: a 3:1 rebound-to-compression ratio with the mean low-speed slope equal to the linear
# default c_s, digressive (high-speed slopes 40 % of the low-speed ones) beyond a knee at 0.3 m/s.
DEFAULT_DAMPER = PiecewiseDamper(
    damper_c_rebound=1.5 * DEFAULT_VEHICLE.c_s, damper_c_compression=0.5 * DEFAULT_VEHICLE.c_s,
    damper_knee_rebound=0.3, damper_knee_compression=0.3,
    damper_c_rebound_high=0.6 * DEFAULT_VEHICLE.c_s, damper_c_compression_high=0.2 * DEFAULT_VEHICLE.c_s)
# Bump stops 0.1 m from the static point each way (a passenger car's travel), 10 k_s stiff: roads
# up to ISO C at 80 km/h and ISO D at 40 km/h do not touch them; ISO D at 80 km/h does, rarely
# (benchmarks/nonlinear_plant.py).
DEFAULT_BUMP_STOPS = BumpStops(bump_stop_gap=0.1, rebound_stop_gap=0.1,
                               bump_stop_stiffness=10 * DEFAULT_VEHICLE.k_s)
