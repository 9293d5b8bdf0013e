"""A road profile high-passed in distance, as inertial profilers report it.

Accelerometers cannot see hills: an inertial profiler (ASTM E950, AASHTO R56) reports elevation
high-passed in *distance* at a long-wavelength cut-off, so that the result holds at every speed
and does not move while the vehicle stands. ``PROFILE_CUTOFF`` is 300 ft (91.44 m), the usual
cut-off of profile processing (ProVAL's default high-pass): every wavelength the IRI responds to
(up to ~30 m) and ISO 8608's classification band (up to ~90 m, n >= 0.011 cycle/m) pass.

The filter is the second-order Butterworth high-pass H(p) = p^2 / (p^2 + sqrt(2) w p + w^2) in
distance (p = d/ds, w = 2 pi / cutoff rad/m), discretised exactly for a profile linear in
distance between samples: any spacing, the same result at the points two spacings share (to
rounding), and a step with no distance travelled passes the change of the input unfiltered (a
high-pass passes a jump); the caller decides whether a change while standing is a change of the
road (it is not: ``DistanceHighpass.step`` with ``ds`` = 0 and the same height holds the output).
"""
from __future__ import annotations

import math

import numpy as np

PROFILE_CUTOFF = 91.44  # m, 300 ft
CUTOFF_RANGE = (1.0, 10000.0)  # m


def band_response(n: np.ndarray, cutoff: float = PROFILE_CUTOFF) -> np.ndarray:
    """Complex gain of the high-pass at spatial frequencies n (cycle/m)."""
    w = 2.0 * math.pi / cutoff
    p = 2j * np.pi * np.asarray(n, float)
    return p * p / (p * p + math.sqrt(2.0) * w * p + w * w)


class DistanceHighpass:
    """The high-pass of a profile sampled at increasing distances (``cutoff`` m); ``y`` the last
    output (m). Starts from rest at the first height it is given (output 0 there)."""

    def __init__(self, cutoff: float = PROFILE_CUTOFF):
        if not CUTOFF_RANGE[0] <= cutoff <= CUTOFF_RANGE[1]:
            raise ValueError(f"profile cutoff = {cutoff!r} m is outside the allowed range "
                             f"[{CUTOFF_RANGE[0]:g}, {CUTOFF_RANGE[1]:g}]")
        self.cutoff = float(cutoff)
        self.w = 2.0 * math.pi / self.cutoff
        self.x1 = self.x2 = 0.0  # states of p / (p^2 + sqrt(2) w p + w^2) driven by du/ds; y = x2
        self.u: float | None = None  # the last input height (m)
        self._ds = None  # the step the coefficients below are for
        self._c: tuple[float, ...] = ()

    @property
    def y(self) -> float:
        return self.x2

    def _coefficients(self, ds: float) -> tuple[float, ...]:
        """(Phi as 4 numbers, G as 2): x <- Phi x + G du over a distance ds, G = Gamma / ds."""
        w = self.w
        r2 = math.sqrt(2.0)
        sig, beta = -w / r2, w / r2
        if ds <= 0.0:
            return 1.0, 0.0, 0.0, 1.0, 0.0, 1.0
        e, c, s = math.exp(sig * ds), math.cos(beta * ds), math.sin(beta * ds)
        # expm(A ds) = e^(sig ds) [cos I + sin / beta (A - sig I)], A = [[0, 1], [-w^2, -sqrt(2) w]]
        k = s / beta
        p11, p12 = e * (c - k * sig), e * k
        p21, p22 = e * (-k * w * w), e * (c + k * (-r2 * w - sig))
        if w * ds < 1e-4:  # G = B + A B ds / 2 + A^2 B ds^2 / 6, B = (0, 1)
            g1 = ds / 2.0 - r2 * w * ds * ds / 6.0
            g2 = 1.0 - r2 * w * ds / 2.0 + w * w * ds * ds / 6.0
        else:  # G = A^-1 (Phi - I) B / ds, A^-1 = [[-sqrt(2) w, -1], [w^2, 0]] / w^2
            g1 = (-r2 * w * p12 - (p22 - 1.0)) / (w * w * ds)
            g2 = p12 / ds
        return p11, p12, p21, p22, g1, g2

    def step(self, ds: float, height: float) -> float:
        """Advance by ``ds`` m (>= 0) to a point of height ``height`` m; returns the output (m)."""
        if self.u is None:
            self.u = float(height)
            return self.x2
        if ds != self._ds:
            self._c, self._ds = self._coefficients(ds), ds
        p11, p12, p21, p22, g1, g2 = self._c
        du = height - self.u
        self.u = float(height)
        x1, x2 = self.x1, self.x2
        self.x1 = p11 * x1 + p12 * x2 + g1 * du
        self.x2 = p21 * x1 + p22 * x2 + g2 * du
        return self.x2


def highpass_profile(distance: np.ndarray, height: np.ndarray, cutoff: float = PROFILE_CUTOFF) -> np.ndarray:
    """``DistanceHighpass`` over a whole profile (distance non-decreasing, m; height m), from rest
    at its first point."""
    d, z = np.asarray(distance, float), np.asarray(height, float)
    if d.shape != z.shape or d.ndim != 1:
        raise ValueError("distance and height must be 1-d arrays of the same length")
    if np.any(np.diff(d) < 0):
        raise ValueError("distance must not decrease")
    f = DistanceHighpass(cutoff)
    out = np.empty_like(z)
    prev = d[0] if len(d) else 0.0
    for i, (s, h) in enumerate(zip(d.tolist(), z.tolist())):
        out[i] = f.step(s - prev, h)
        prev = s
    return out
