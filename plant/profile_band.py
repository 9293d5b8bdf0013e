"""A road profile high-passed in distance, as inertial profilers report it.

Accelerometers cannot see hills: an inertial profiler (ASTM E950, AASHTO R56) reports elevation
high-passed in *distance* at a long-wavelength cut-off, so that the result holds at every speed
and does not move while the vehicle stands. ``PROFILE_CUTOFF`` is 300 ft (91.44 m), the usual
cut-off of profile processing (ProVAL's default high-pass): every wavelength the IRI responds to
(up to ~30 m) and ISO 8608's classification band (up to ~90 m, n >= 0.011 cycle/m) pass.

The filter is the third-order Butterworth high-pass
H(p) = p^3 / ((p + w) (p^2 + w p + w^2)) in distance (p = d/ds, w = 2 pi / cutoff rad/m).
Third order because a vertical curve (an elevation of constant curvature k, a parabola in
distance) and a constant bias on both accelerometers are the same measurements (a car on the
curve at speed v accelerates at v^2 k, body and wheel alike, with a static deflection of
m_s v^2 k / k_s: tests/test_profile_band.py shows it on the plant). A second-order high-pass
turns the parabola into a constant k / w^2 (a 0.1 m/s^2 bias at 40 km/h: 172 mm), which no
estimator can tell from the road; a third-order one removes it, as it removes a level and a grade.

It is discretised exactly for a profile linear in distance between samples: any spacing, the
same result at the points two spacings share (to rounding), and a step with no distance travelled
passes the change of the input unfiltered (a high-pass passes a jump); the caller decides whether
a change while standing is a change of the road (it is not: ``DistanceHighpass.step`` with ``ds``
= 0 and the same height holds the output).
"""
from __future__ import annotations

import cmath
import math
from functools import lru_cache

import numpy as np

from . import iso8608

PROFILE_CUTOFF = 91.44  # m, 300 ft
PROFILE_ORDER = 3
CUTOFF_RANGE = (1.0, 10000.0)  # m


def band_response(n: np.ndarray, cutoff: float = PROFILE_CUTOFF) -> np.ndarray:
    """Complex gain of the high-pass at spatial frequencies n (cycle/m)."""
    w = 2.0 * math.pi / cutoff
    p = 2j * np.pi * np.asarray(n, float)
    return p ** 3 / ((p + w) * (p * p + w * p + w * w))


def class_band_rms(road_class: int, cutoff: float = PROFILE_CUTOFF) -> float:
    """m: the rms in the band of a road at the upper limit of ISO 8608 class ``road_class``
    (1..8 = A..H: Gd(n0) twice the class's geometric mean), waviness 2:
    integral of Gd(n0) (n0 / n)^2 |H(n)|^2 dn over n > 0 = (pi / 3) Gd(n0) n0^2 cutoff,
    since the integral of u^4 / (1 + u^6) du over u > 0 is pi / 3."""
    gd = 2.0 * iso8608.class_psd_n0(road_class)
    return math.sqrt(math.pi / 3.0 * gd * iso8608.N0 ** 2 * cutoff)


@lru_cache(maxsize=16)
def _eigen(w: float) -> tuple:
    """(eigenvalues, V^-1) of the companion matrix of D(p) (``DistanceHighpass``): its
    eigenvectors are (1, l, l^2), so row i of V^-1 holds the coefficients of the Lagrange
    polynomial of l_i, (l^2 - (a + b) l + a b) / ((l_i - a) (l_i - b))."""
    r3 = math.sqrt(3.0)
    lam = (complex(-w, 0.0), complex(-0.5 * w, 0.5 * r3 * w), complex(-0.5 * w, -0.5 * r3 * w))
    vinv = []
    for i, li in enumerate(lam):
        a, b = (lam[j] for j in range(3) if j != i)
        den = (li - a) * (li - b)
        vinv.append((a * b / den, -(a + b) / den, 1.0 / den))
    return lam, tuple(vinv)


class DistanceHighpass:
    """The high-pass of a profile sampled at increasing distances (``cutoff`` m); ``y`` the last
    output (m). Starts from rest at the first height it is given (output 0 there).

    State space of p^2 / D(p) driven by the slope du/ds, constant between samples (controllable
    form, D(p) = p^3 + 2 w p^2 + 2 w^2 p + w^3, y = x3); over a distance ds
    x <- Phi x + G du with Phi = V e^(L ds) V^-1 and G = V ((e^(L ds) - 1) / (L ds)) V^-1 B
    from the eigenvalues L (-w, w (-1 +- i sqrt(3)) / 2) of the companion matrix."""

    def __init__(self, cutoff: float = PROFILE_CUTOFF):
        if not CUTOFF_RANGE[0] <= cutoff <= CUTOFF_RANGE[1]:
            raise ValueError(f"profile cutoff = {cutoff!r} m is outside the allowed range "
                             f"[{CUTOFF_RANGE[0]:g}, {CUTOFF_RANGE[1]:g}]")
        self.cutoff = float(cutoff)
        self.w = 2.0 * math.pi / self.cutoff
        self.x = [0.0, 0.0, 0.0]
        self.u: float | None = None  # the last input height (m)
        self._ds = None  # the step the coefficients below are for
        self._c: tuple = ()

    @property
    def y(self) -> float:
        return self.x[2]

    def _coefficients(self, ds: float) -> tuple:
        """(Phi as 3 rows, G): x <- Phi x + G du over a distance ds."""
        if ds <= 0.0:
            return ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), (0.0, 0.0, 1.0)
        lam, vinv = _eigen(self.w)
        e = [cmath.exp(li * ds) for li in lam]
        g = [(1.0 + 0.5 * li * ds) if abs(li * ds) < 1e-5 else (ei - 1.0) / (li * ds) for li, ei in zip(lam, e)]
        phi = tuple(tuple(sum((lam[i] ** r) * e[i] * vinv[i][c] for i in range(3)).real for c in range(3))
                    for r in range(3))
        G = tuple(sum((lam[i] ** r) * g[i] * vinv[i][2] for i in range(3)).real for r in range(3))
        return phi, G

    def step(self, ds: float, height: float) -> float:
        """Advance by ``ds`` m (>= 0) to a point of height ``height`` m; returns the output (m)."""
        if self.u is None:
            self.u = float(height)
            return self.x[2]
        if ds != self._ds:
            self._c, self._ds = self._coefficients(ds), ds
        (r0, r1, r2), G = self._c
        du = height - self.u
        self.u = float(height)
        x0, x1, x2 = self.x
        self.x = [r0[0] * x0 + r0[1] * x1 + r0[2] * x2 + G[0] * du,
                  r1[0] * x0 + r1[1] * x1 + r1[2] * x2 + G[1] * du,
                  r2[0] * x0 + r2[1] * x1 + r2[2] * x2 + G[2] * du]
        return self.x[2]


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
