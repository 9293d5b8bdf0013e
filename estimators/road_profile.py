"""road_height_est from the road filter's road estimate: freed of its common-mode reference and
high-passed in distance (``Profiler``).

The road filters of the KF family (codes 0-2) pin the car's absolute height with a weak
reference: the common mode of body, wheel and road passes the high-pass
T(s) = s^2 / (s^2 + 2 zeta w s + w^2) in time (model.RoadModel, f_ref = 0.01 Hz, zeta 0.7071), so
the road estimate is T applied to the road, and a constant error (a body accelerometer bias b)
reaches it as T (b / s^2): b / w^2 = 25 m over a minute or two, whose tail the profile's
high-pass in distance cannot remove. ``Unreference`` applies T^-1 = 1 + 2 zeta w / s + w^2 / s^2
to the estimate (trapezoidal integrals): the road itself again, and the bias's response the
parabola b t^2 / 2, which the third-order high-pass of plant/profile_band.py removes as it
removes a vertical curve (the same measurements). ISO C, 40 km/h, exact vehicle, 40 s, seeds 1-2,
band error after 10 s (mm): ideal sensors 0.69 / 1.06 through the high-pass alone, 0.19 / 0.20
un-referenced; a 0.1 m/s^2 body bias 31 / 30 (second order), 6.3 / 6.3 (third order), 0.82 /
0.73 (third order, un-referenced): docs/real-sensors.md.
"""
from __future__ import annotations

import math

from ..plant.profile_band import DistanceHighpass


class Unreference:
    """T^-1 of the reference (``f_ref`` Hz, ``zeta_ref``) in time, one sample per step of h s;
    ``step`` returns the increment of its output since the last sample. ``f_ref`` = 0: the
    identity (an estimator without a reference)."""

    def __init__(self, f_ref: float, zeta_ref: float):
        w = 2.0 * math.pi * float(f_ref)
        self.a1, self.a0 = 2.0 * float(zeta_ref) * w, w * w
        self.restart()

    def restart(self) -> None:
        """The estimate restarts (from zero, or after a gap): the next sample only sets the level."""
        self.r: float | None = None  # m, the last estimate
        self.i1 = 0.0  # m.s, its integral since the restart

    def step(self, r: float, h: float) -> float:
        """The increment (m) of T^-1 r from the last sample to ``r`` (m), h s later (0 after a
        restart)."""
        last, self.r = self.r, r
        if last is None:
            return 0.0
        d1 = 0.5 * h * (r + last)
        i1 = self.i1
        self.i1 = i1 + d1
        return (r - last) + self.a1 * d1 + self.a0 * 0.5 * h * (i1 + self.i1)


class Profiler:
    """The profile (m) of a road estimate: ``Unreference`` with ``reference`` (f_ref Hz,
    zeta_ref; None: the identity), its increments fed while the car moves into the high-pass in
    distance at ``cutoff`` m (plant.profile_band), so that the profile holds while the car stands
    and a restart of the estimate adds no jump."""

    def __init__(self, cutoff: float, reference: tuple[float, float] | None = None):
        self.unreference = Unreference(*(reference or (0.0, 0.0)))
        self.band = DistanceHighpass(cutoff)
        self.u = 0.0  # m, the sum of the un-referenced increments while moving

    def restart(self) -> None:
        """The estimate restarts: its next sample only sets the level."""
        self.unreference.restart()

    def step(self, road: float, h: float, ds: float) -> float:
        """One sample of the estimate ``road`` (m) h s after the last, ``ds`` m travelled (0: the
        car stands); a value that is not finite restarts. Returns the profile (m)."""
        if not math.isfinite(road):
            self.unreference.restart()
        else:
            du = self.unreference.step(road, h)
            if ds > 0.0:
                self.u += du
        return self.band.step(ds, self.u)
