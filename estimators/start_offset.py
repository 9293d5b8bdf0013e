"""The road height the car started on, estimated from the road estimate itself.

Used only with ``EstimatorConfig.start_offset`` True, where ``road_height_est`` is the absolute
height of a zero-mean stationary ISO road. The default estimate is relative to the start level
(harness.metrics.reference_road), where z_0 is zero by definition; on a road with grades or
vertical curves the zero-mean assumption below does not hold and this estimate of z_0 is wrong
(docs/real-roads.md).

The accelerations and the deflection observe only relative motion, so the KF's road estimate
x(t) is relative to its common-mode reference (model.py). After a start on a road at the unknown
height z_0 it carries -z_0 g(t), g the reference's step response (``reference_step_response``;
0.30 at 10 s, -0.19 at 30 s):

    x(t) = z_r(t) - z_0 g(t) + d(t)

with d the filter's own raw error (the stationary part of ``road_height_std``). The road is a
zero-mean stationary ISO 8608 profile, so the distance driven tells z_0 apart from the road: on
ISO D (z_0 ~ 30 mm) the start height was the largest part of the raw error over the first
minute. ``StartOffset`` is a three-state Kalman filter on x sampled every ``dt`` with
Gauss-Markov surrogates of the three parts:

    r = z_r: variance sigma_0^2 (``iso_road_height_std`` of the assumed class), time constant
             tau_r = 1 / (pi^2 n_min V) at speed V: the OU spectrum 4 sigma_0^2 tau_r /
             (1 + (2 pi f tau_r)^2) then has the ISO band's variance and, above its corner, the
             ISO level sigma_0^2 n_min V / f^2 (waviness 2, n_max >> n_min);
    d:       the filter's raw-error variance s^2(t) as it builds up (given at every sample),
             time constant tau_d = 1 / (2 pi f_ref), the reference's;
    b = z_0: constant, with r(0) = b (the car stands on the road at the start).

The corrected estimate x + g b^ has the error d - g (b - b^), whose variance is
s^2(t) + g^2 P_bb - 2 g P_db (the estimate is orthogonal to its error), in place of
s^2(t) + g^2 sigma_0^2 without the correction. The surrogates are approximations: the ISO
band has no content below n_min V, the OU road has some, so P_bb errs on the large side
(benchmarks/std_calibration.py: ISO D, 40 km/h, seeds 1-20, 10-70 s, rms raw error 5.45 mm
against a reported 5.75 mm). The samples are kept, so that a change of the assumed class
(sigma_0) re-runs the filter over them with the new prior (at most 8000 samples, 320 kB: the
estimator drops the filter 400 s after the start, where g ~ 1e-8).

A re-run moves the estimate of z_0 at once (by 9-15 mm at the first identification or a class
change on a measured road), and the road estimate with it. So the reported ``b`` is the
filter's estimate plus a blend term that starts at the difference (old reported - re-run) and
decays as exp(-t / BLEND_TIME): ``b`` stays continuous, and from one sample to the next (50 ms)
the blend moves by at most 1 % of the change (0.15 mm for a 15 mm change; the tolerance is 0.5
mm per sample up to a 50 mm change). While it lasts the blend adds (g blend)^2 to
``start_variance``.

``SuspensionEstimator`` shifts body, wheel and road positions by g(t) b^ (the deflections are
unchanged). The velocities are not shifted: the rate |g'(t)| b^ <= 2 zeta_ref w_ref b^, 0.09 b^
per s (3 mm/s for b^ = 30 mm, the ISO D height std). A re-filter after a mass rebuild changes
road estimates already sampled here; they are not re-taken. MME&KF keeps its uncorrected
estimate and the prior term g^2 sigma_0^2.
"""
from __future__ import annotations

import math
from array import array

SAMPLE_INTERVAL = 0.05  # s between the samples of x the filter takes
BLEND_TIME = 5.0  # s, time constant over which a re-run's change of b^ is blended in
OBS_VAR = 1e-8  # m^2, a (0.1 mm)^2 floor under the observation of x


class StartOffset:
    """Kalman filter for z_0 (see the module doc). State [r, d, b] in m, covariance P in m^2."""

    def __init__(self, n_min: float, f_ref: float, sigma0: float, d0_var: float = 0.0):
        """``n_min``: low end of the ISO band (cycle/m); ``f_ref``: the reference's corner (Hz);
        ``sigma0``: road-height std (m) of the assumed class; ``d0_var``: variance (m^2) of d
        at the start, 0 after a start from rest."""
        self.n_min = float(n_min)
        self.tau_d = 1.0 / (2.0 * math.pi * f_ref)
        self.d0_var = float(d0_var)
        self.samples = array("d")  # (t, x, V, s^2, g) after each other: 40 bytes a sample
        self.blend = 0.0  # m, what is left of a re-run's change of b^ (see the module doc)
        self._restart(float(sigma0))

    def _restart(self, sigma0: float) -> None:
        s2 = sigma0 * sigma0
        self.sigma0 = sigma0
        self.x = [0.0, 0.0, 0.0]
        self.P = [[s2, 0.0, s2], [0.0, self.d0_var, 0.0], [s2, 0.0, s2]]
        self._t = 0.0
        self._s2 = self.d0_var

    @property
    def b(self) -> float:
        """Estimate of z_0 (m) as reported: the filter's x[2] plus the blend of a re-run."""
        return self.x[2] + self.blend

    def start_variance(self, g: float) -> float:
        """g^2 (P_bb + blend^2) - 2 g P_db (m^2): what the start height adds to the variance of the
        corrected road estimate x + g b^ at a time where the reference's step response is g."""
        return g * g * (self.P[2][2] + self.blend * self.blend) - 2.0 * g * self.P[1][2]

    def due(self, t: float, h: float) -> bool:
        """True when a sample of x is due at t (s) with the step h (s)."""
        return t >= (len(self.samples) // 5 + 1) * SAMPLE_INTERVAL - 0.5 * h

    def add(self, t: float, x: float, speed: float, s2: float, g: float, sigma0: float) -> None:
        """Take the sample x (m) of the road estimate at t (s) since the start, at speed (m/s),
        with the filter's raw-error variance s2 (m^2) then, the step response g and the road
        height std sigma0 (m) of the assumed class; a new sigma0 re-runs over the samples."""
        if self.blend != 0.0:
            self.blend *= math.exp(-(t - self._t) / BLEND_TIME)
        self.samples.extend((t, x, speed, s2, g))
        if sigma0 != self.sigma0:
            before = self.b
            self._restart(sigma0)
            v = self.samples
            for i in range(0, len(v) - 5, 5):
                self._update(v[i], v[i + 1], v[i + 2], v[i + 3], v[i + 4])
            self.blend = before - self.x[2]  # continuous across the re-run ...
        self._update(t, x, speed, s2, g)  # ... and this sample's update as usual

    def _update(self, t: float, y: float, speed: float, s2: float, g: float) -> None:
        dt = t - self._t
        self._t = t
        fr = math.exp(-dt * math.pi * math.pi * self.n_min * max(abs(speed), 0.1))
        fd = math.exp(-dt / self.tau_d)
        f = (fr, fd, 1.0)
        s0 = self.sigma0
        q = (s0 * s0 * (1.0 - fr * fr), max(s2 - fd * fd * self._s2, 0.0), 0.0)  # d follows s^2(t)
        self._s2 = s2
        x, P = self.x, self.P
        for i in range(3):
            x[i] *= f[i]
            for j in range(3):
                P[i][j] *= f[i] * f[j]
            P[i][i] += q[i]
        ph = [P[i][0] + P[i][1] - g * P[i][2] for i in range(3)]
        s = ph[0] + ph[1] - g * ph[2] + OBS_VAR
        innov = y - (x[0] + x[1] - g * x[2])
        for i in range(3):
            k = ph[i] / s
            x[i] += k * innov
            for j in range(3):
                P[i][j] -= k * ph[j]
