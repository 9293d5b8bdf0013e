"""Self-diagnosis of the road filter: are its innovations what the model and the sensors'
calibration allowance explain?

A Kalman filter's innovation y_k = z_k - H x_k|k-1 has covariance S = H P H' + R when the model
and the sensors are what the filter assumes. A sensor error the filter cannot absorb (a bias far
beyond its range, a skew of many milliseconds, a dead channel, a scale error of tens of %) makes
the innovations larger than S says. Errors within the calibration allowance that road_height_std
already covers (``calibration_gain_std``, ``calibration_delay_std``) make them larger too, through
the filter: a delay on one channel shows mostly in another channel's innovation. So the expected
innovation variance of each channel i is

    s_i = S_ii + sigma_t^2 sum_j (G_ij [-dz_j/dt])^2 + sigma_g^2 sum_{j accel.} (G_ij [z_j])^2,

where G_ij is the steady filter's response of innovation i to an error on channel j
(dx_k = F dx_k-1 + K dy_k, dy_k = e_k - H F dx_k-1), driven by the filter's prediction of the
channel (H x_k|k-1, the signal without the sensor noise) for a gain error and by its rate for a
delay; sigma_t (s) and sigma_g (1) are the allowance's delay and gain stds.

The check compares the ratio r_i = <min(y_i^2, 9 s_i)> / <s_i> (both averaged exponentially over
``window`` s; the clip keeps a road's discrete events, bursts of tens of ms, out of it)
with ``limit``, and on the channels ``mean_channels`` the innovations' mean over the same window,
m_i = <y_i>, with its std under the same assumptions,

    u_i = sqrt(<S_ii> a / (2 - a) + sigma_t^2 sum_j <G_ij [-dz_j/dt]>^2 + sigma_g^2 sum_{j accel.} <G_ij [z_j]>^2),

a = h / window (the exponential average of white noise of variance s has variance s a / (2 - a));
|m_i| / u_i above ``mean_limit`` is a step the filter is taking up. A bias that appears mid-run
(a body accelerometer's bias stepping by 0.5 m/s^2) is taken up by the force-bias state within
seconds, so it leaves the innovations' variance as it was, but while it is taken up the whole
car is read as accelerating: the profile is wrong by decimetres for tens of seconds, and the
wheel's innovations, which the force-error states hardly reach (the whole-corner balance ties
the wheel to the body), keep a mean of the step's size meanwhile. Above either limit on any
channel the filter is ``INCONSISTENT``, and stays so until the
ratios are back below it and the car has travelled ``hold`` metres more (the filter's states
take up what is left of the error slowly, and the profile's high-pass carries it further). The
numbers behind the limit and the hold are in tuning.py (``diagnosis_*``) and docs/real-sensors.md.
What the test cannot see: errors the filter's states absorb whole, a deflection offset (the
default filter's force-bias state takes it as a force: tests/test_sensor_check.py) and a
body-accelerometer gain error (the mass takes it up); and it cannot tell a sensor error from a
suspension far from the model (the air-spring plant on ISO D).

``InnovationRatio`` is the plain form the half-car observer (half_car_imm.py) uses: the average
NIS per measurement, no allowance, no clip; its square root widens that observer's stds.
"""
from __future__ import annotations

import math

import numpy as np

CONSISTENT, INCONSISTENT = "consistent", "inconsistent"
# each sample's y_i^2 counts at most CLIP s_i: a pothole or a kerb is a burst of large innovations
# lasting tens of ms, a sensor error lasts; clipped at 3 sigma a 20 ms burst moves the 1 s average
# by at most 0.18 (a 30 mm pothole at 72 km/h held status 3 for 14 s unclipped)
CLIP = 9.0


class InnovationCheck:
    """The innovation test of the module doc for a filter with ``dim_z`` channels, of which the
    first ``n_acc`` are accelerometers (gain errors); ``gain_std`` (1) and ``delay_std`` (s) the
    allowance, ``window`` (s) the averaging time, ``limit`` the ratio, ``hold`` (m) the distance
    the state stays inconsistent after the ratios are back."""

    def __init__(self, dim_z: int, n_acc: int, gain_std: float, delay_std: float, window: float,
                 limit: float, hold: float, start: float = 0.0, mean_channels: tuple[int, ...] = (),
                 mean_limit: float = math.inf):
        self.dim_z, self.n_acc = dim_z, n_acc
        self.mean_channels, self.mean_limit = np.array(mean_channels, dtype=int), float(mean_limit)
        self.gain_var, self.delay_var = gain_std ** 2, delay_std ** 2
        self.window, self.limit, self.hold, self.start = window, limit, hold, start
        # the error sources, one column each: a delay on each channel, a gain on each accelerometer
        self._e = np.zeros((dim_z, dim_z + n_acc))
        self._delays = (np.arange(dim_z), np.arange(dim_z))
        self._gains = (np.arange(n_acc), dim_z + np.arange(n_acc))
        self._weights = np.array([self.delay_var] * dim_z + [self.gain_var] * n_acc)
        self.reset()

    def reset(self) -> None:
        self.state = CONSISTENT
        self._num = np.zeros(self.dim_z)
        self._den = np.zeros(self.dim_z)
        m = self.mean_channels.size
        self._mean = np.zeros(m)  # <y_i> on the mean channels
        self._s = np.zeros(m)  # <S_ii>
        self._dy_mean = np.zeros((m, self.dim_z + self.n_acc))  # <G_ij e_j>, one column per error source
        self._a = 0.0  # the averages' weight h / window at the last update (0: none yet)
        self._dx = None  # the error responses, one column per error source
        self._last = None  # the previous prediction H x_k|k-1
        self._age = 0.0  # s averaged so far
        self._clear = math.inf  # m travelled since the ratios were last above the limit

    @property
    def ratio(self) -> np.ndarray:
        """Each channel's averaged innovation variance over the expected (0 before the first update)."""
        return np.divide(self._num, self._den, out=np.zeros(self.dim_z), where=self._den > 0)

    @property
    def mean_ratio(self) -> np.ndarray:
        """|m_i| / u_i on each channel of ``mean_channels`` (0 before the first update)."""
        a = self._a
        var = self._s * a / (2.0 - a) + (self._dy_mean ** 2) @ self._weights
        return np.divide(np.abs(self._mean), np.sqrt(var), out=np.zeros(self._mean.size), where=var > 0)

    def update(self, y: np.ndarray, S: np.ndarray, prediction: np.ndarray, F: np.ndarray, K: np.ndarray,
               H: np.ndarray, h: float, ds: float) -> str:
        """One full update: its innovation ``y``, covariance ``S``, the filter's prediction of the
        measurement H x_k|k-1, the filter's F, K, H, the step ``h`` (s) and the distance ``ds``
        (m) travelled in it. Returns the state."""
        e = self._e
        if self._last is not None:
            e[self._delays] = (self._last - prediction) / h
        e[self._gains] = prediction[:self.n_acc]
        self._last = prediction
        if self._dx is None or self._dx.shape[0] != F.shape[0]:
            self._dx = np.zeros((F.shape[0], e.shape[1]))
        Fdx = F @ self._dx
        dy = e - H @ Fdx
        self._dx = Fdx + K @ dy
        a = min(1.0, h / self.window)
        expected = S.diagonal() + (dy * dy) @ self._weights
        self._num += a * (np.minimum(y * y, CLIP * expected) - self._num)
        self._den += a * (expected - self._den)
        if self.mean_channels.size:
            i = self.mean_channels
            self._mean += a * (y[i] - self._mean)
            self._s += a * (S.diagonal()[i] - self._s)
            self._dy_mean += a * (dy[i] - self._dy_mean)
            self._a = a
        self._age += h
        if self._age < max(self.window, self.start):
            return self.state
        if np.any(self._num > self.limit * self._den) or np.any(self.mean_ratio > self.mean_limit):
            self.state, self._clear = INCONSISTENT, 0.0
        else:
            self._clear += ds
            if self._clear >= self.hold:
                self.state = CONSISTENT
        return self.state

    def flag(self) -> None:
        """A sensor error seen otherwise (a body-accelerometer bias beyond the range taken up,
        bias_step.BIAS_LIMIT): INCONSISTENT, cleared as after a ratio above the limit."""
        self.state, self._clear = INCONSISTENT, 0.0


class InnovationRatio:
    """Is the car what the observer's model says? The exponential average over ``window`` s of
    NIS / m, the normalised innovation squared of each update over its number of measurements:
    1 on average when the car and the sensors are the model's (0.7-0.9 measured: the IMM's mixing),
    larger when they are not. Above ``limit`` the state is INCONSISTENT. Not clipped: its square
    root scales the output stds (covariance matching), and a pothole the linear model does not
    hold is as much a reason to widen them as a wrong spring."""

    def __init__(self, window: float = 1.0, limit: float = 2.5):
        self.window, self.limit = float(window), float(limit)
        self.ratio = 1.0
        self.age = 0.0  # s averaged
        self.state = CONSISTENT

    def update(self, nis: float, m: int, h: float) -> str:
        self.ratio += min(1.0, h / self.window) * (nis / m - self.ratio)
        self.age += h
        self.state = INCONSISTENT if self.age >= self.window and self.ratio > self.limit else CONSISTENT
        return self.state

    @property
    def std_scale(self) -> float:
        """The factor on the filter's stds: sqrt(ratio), at least 1."""
        return math.sqrt(max(self.ratio, 1.0))
