"""The accelerometers' biases, learned while the car stands.

A standing car's body and wheels do not accelerate (engine vibration and a passenger's weight
shift average out), so what the accelerometers read then is their bias: exactly, whatever the
vehicle model, which is what the road filters cannot tell apart from a slow motion while the car
moves (docs/real-sensors.md). A car tilted on a slope reads the gravity it sees as a bias too,
and keeps it while it drives that slope.

``StandstillBias`` averages each accelerometer over all the time the car has stood, leaving out
the first ``settle`` s of each stand (the body still pitches and bounces after braking); with at
least ``min_time`` s of such data the state is ``LEARNED`` and ``bias`` the means (m/s^2), else
``UNKNOWN`` and zero. ``removable`` is the part worth removing: each mean, or 0 below its floor
(``FLOORS``).
"""
from __future__ import annotations

import math

UNKNOWN, LEARNED = "unknown", "learned"
# m/s^2, body and wheel: a standing mean below these is not removed. It is then noise and the
# settling of the body after braking as much as a bias, and a bias that small costs the profile
# nothing (docs/real-sensors.md: 0.01 m/s^2 on the body, 0.5 on the wheel, within 3 % on the
# linear plant), while road_height_est integrates any step of its input (1e-3 m/s^2 -> 0.25 m)
FLOORS = (0.005, 0.05)


class StandstillBias:
    def __init__(self, settle: float = 1.0, min_time: float = 1.0):
        self.settle = float(settle)
        self.min_time = float(min_time)
        self.standing_for = 0.0  # s of the current stand
        self.time = 0.0  # s of averaged standing data
        self._sums = [0.0, 0.0]
        self.state = UNKNOWN
        self.bias = (0.0, 0.0)  # m/s^2, body and wheel accelerometer

    def step(self, standing: bool, acc_sprung: float, acc_unsprung: float, h: float) -> str:
        """One sample (m/s^2) of ``h`` s; returns the state."""
        if not standing:
            self.standing_for = 0.0
            return self.state
        self.standing_for += h
        if self.standing_for > self.settle and math.isfinite(acc_sprung + acc_unsprung):
            self._sums[0] += acc_sprung * h
            self._sums[1] += acc_unsprung * h
            self.time += h
            if self.time >= self.min_time:
                self.state = LEARNED
                self.bias = (self._sums[0] / self.time, self._sums[1] / self.time)
        return self.state

    @property
    def removable(self) -> tuple[float, float]:
        """The biases to remove (m/s^2): each learned mean, or 0 below its floor."""
        return tuple(b if abs(b) >= f else 0.0 for b, f in zip(self.bias, FLOORS))
