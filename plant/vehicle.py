"""Quarter-car vehicle parameters: the one source of truth for defaults and allowed ranges.

Defaults are Table 1 of Wang et al., *Road profile estimation for suspension system based on
the minimum model error criterion combined with a Kalman filter* (J. Vibroengineering 2017).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Vehicle:
    """Linear quarter car. SI units: kg, N/m, N.s/m."""

    m_s: float = 410.0  # sprung mass, kg
    m_u: float = 39.0  # unsprung mass, kg
    k_s: float = 20000.0  # suspension stiffness, N/m
    k_t: float = 183000.0  # tyre stiffness, N/m
    c_s: float = 2000.0  # suspension damping, N.s/m

    def with_(self, **changes: float) -> "Vehicle":
        return replace(self, **changes)

    def problems(self) -> list[str]:
        """Messages for every parameter outside its allowed range (empty when valid)."""
        return [msg for name in ("m_s", "m_u", "k_s", "k_t", "c_s")
                if (msg := check_range(name, getattr(self, name), *VEHICLE_RANGES[name]))]

    def natural_frequencies(self) -> tuple[float, float]:
        """Damped body-bounce and wheel-hop frequencies in Hz, from the eigenvalues of A."""
        from .quarter_car import state_matrices

        lam = np.linalg.eigvals(state_matrices(self)[0])
        f = np.sort(np.abs(lam[lam.imag > 0].imag)) / (2 * np.pi)
        return float(f[0]), float(f[1])


DEFAULT_VEHICLE = Vehicle()

# Li, Wang, Zhang, Yang, *Kalman Filter Method Based Vehicle Mass Estimation for Automobile
# Suspension System*: the vehicle of its simulation (sprung mass starts at 260 kg).
PAPER001_VEHICLE = Vehicle(m_s=260.0, m_u=40.0, k_s=16000.0, k_t=183000.0, c_s=1200.0)

# Allowed ranges (low, high, low_inclusive): road-vehicle corners from a scaled test rig or a
# light motorcycle to a heavy truck's axle end, with margin; narrow enough to refuse a unit slip
# (grams for kg, N/mm for N/m). Beyond them (a 1 kg wheel on a 1e9 N/m tyre: wheel hop at
# 5 kHz) no road vehicle lies, and the road filter's covariance cannot be held in double
# precision.
VEHICLE_RANGES: dict[str, tuple[float, float, bool]] = {
    "m_s": (10.0, 2e4, True),  # kg
    "m_u": (1.0, 5e3, True),  # kg
    "k_s": (100.0, 1e7, True),  # N/m
    "k_t": (1e3, 1e8, True),  # N/m
    "c_s": (0.0, 1e5, True),  # N.s/m
}


def check_range(name: str, value: float, low: float, high: float, low_inclusive: bool = True,
                high_inclusive: bool = True) -> str | None:
    """Return a message naming ``name`` and its allowed range if ``value`` is outside it."""
    ok = np.isfinite(value) and (value >= low if low_inclusive else value > low) and (
        value <= high if high_inclusive else value < high)
    if ok:
        return None
    lo = "[" if low_inclusive else "("
    hi = "]" if high_inclusive else ")"
    return f"{name} = {value!r} is outside the allowed range {lo}{low:g}, {high:g}{hi}"
