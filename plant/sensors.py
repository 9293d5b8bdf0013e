"""The errors of a real car's suspension sensors, beside their white noise (quarter_car.SensorNoise).

A channel reports ``scale * true(t - delay) + bias + noise`` (accelerometers) or
``true(t - delay) + offset + noise`` (the deflection sensor): a MEMS accelerometer's gain is off by
1-3 % and its zero by 0.01-0.1 m/s^2, a ride-height sensor's zero by tenths of a millimetre to
millimetres (and it moves with the payload), and a data logger skews channels by a few
milliseconds. The plant (quarter_car.QuarterCar) adds these errors to what it measures; the
estimator (estimators.suspension) takes the same parameters as the known calibration of the
sensors it is fed and removes them, so that a plant and an estimator given the same values cancel.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields

# (low, high), both ends included, by parameter name (SI units)
SENSOR_ERROR_RANGES: dict[str, tuple[float, float]] = {
    "deflection_offset": (-0.05, 0.05),  # m
    "acc_sprung_bias": (-5.0, 5.0),  # m/s2
    "acc_unsprung_bias": (-20.0, 20.0),  # m/s2
    "acc_sprung_scale": (0.5, 2.0),  # 1
    "acc_unsprung_scale": (0.5, 2.0),  # 1
    "acc_sprung_delay": (0.0, 0.05),  # s
    "acc_unsprung_delay": (0.0, 0.05),  # s
    "deflection_delay": (0.0, 0.05),  # s
}
CHANNELS = ("acc_sprung", "acc_unsprung", "deflection")
# what an estimator not told its sensors' calibration allows for (1-sigma): each accelerometer's
# gain error and each channel's delay, at the ends of what real sensors have (docs/real-sensors.md:
# a MEMS accelerometer's gain 1-3 % off, a logger's skew of a few ms); name: (default, range)
CALIBRATION_ALLOWANCE: dict[str, tuple[float, tuple[float, float]]] = {
    "calibration_gain_std": (0.03, (0.0, 0.5)),  # 1
    "calibration_delay_std": (0.002, (0.0, 0.05)),  # s
}


@dataclass(frozen=True)
class SensorErrors:
    """Offset, biases, gains and delays of the three channels (SI units; the defaults are none)."""

    deflection_offset: float = 0.0  # m, added to the deflection
    acc_sprung_bias: float = 0.0  # m/s^2
    acc_unsprung_bias: float = 0.0  # m/s^2
    acc_sprung_scale: float = 1.0  # measured / true
    acc_unsprung_scale: float = 1.0
    acc_sprung_delay: float = 0.0  # s the channel reports late
    acc_unsprung_delay: float = 0.0
    deflection_delay: float = 0.0

    @classmethod
    def of(cls, source) -> "SensorErrors":
        """The errors named like this class's fields, read from the attributes of ``source``."""
        return cls(**{f.name: float(getattr(source, f.name)) for f in fields(cls)})

    @property
    def delays(self) -> tuple[float, float, float]:
        return self.acc_sprung_delay, self.acc_unsprung_delay, self.deflection_delay

    @property
    def none(self) -> bool:
        return self == SensorErrors()

    def apply(self, a_s: float, a_u: float, d: float) -> tuple[float, float, float]:
        """The measured values of the true ones (delays aside, see ``DelayLine``)."""
        return (self.acc_sprung_scale * a_s + self.acc_sprung_bias,
                self.acc_unsprung_scale * a_u + self.acc_unsprung_bias, d + self.deflection_offset)

    def remove(self, a_s: float, a_u: float, d: float) -> tuple[float, float, float]:
        """The inverse of ``apply``: the true values of measured ones."""
        return ((a_s - self.acc_sprung_bias) / self.acc_sprung_scale,
                (a_u - self.acc_unsprung_bias) / self.acc_unsprung_scale, d - self.deflection_offset)


class DelayLine:
    """A signal delayed by ``delay`` s: linear interpolation between the samples pushed so far
    (any step sizes); before the first sample older than the delay, the oldest sample."""

    def __init__(self, delay: float):
        self.delay = float(delay)
        self._t: deque = deque()
        self._x: deque = deque()

    def push(self, t: float, x: float) -> float:
        """Add the sample x at time t (s) and return the value at t - delay."""
        if self.delay <= 0.0:
            return x
        ts, xs = self._t, self._x
        ts.append(t)
        xs.append(x)
        target = t - self.delay
        while len(ts) > 2 and ts[1] <= target:
            ts.popleft()
            xs.popleft()
        if ts[0] >= target:
            return xs[0]
        t0, t1, x0, x1 = ts[0], ts[1], xs[0], xs[1]
        return x0 + (x1 - x0) * (target - t0) / (t1 - t0)
