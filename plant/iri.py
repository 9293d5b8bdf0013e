"""International Roughness Index (IRI) of a longitudinal profile: the golden quarter car.

ASTM E1926 (World Bank technical paper 46, Sayers, Gillespie & Paterson 1986): a quarter car with
parameters normalised by the sprung mass, k1 = k_t/m_s = 653 s^-2, k2 = k_s/m_s = 63.3 s^-2,
c = c_s/m_s = 6.0 s^-1, mu = m_u/m_s = 0.15, driven at V = 80 km/h over the profile slope

    x' = A x + B y',  x = [z_s, z_s', z_u, z_u'] / V  (units of slope),

    A = [[0, 1, 0, 0], [-k2, -c, k2, c], [0, 0, 0, 1], [k2/mu, c/mu, -(k1 + k2)/mu, -c/mu]],
    B = [0, 0, 0, k1/mu].

The profile (spacing dx) is first smoothed by a 250 mm moving average: the input over each
interval is the slope (Y[i+k] - Y[i]) / (k dx), k = max(1, round(0.25 / dx)). The state moves
over each interval dt = dx / V with the exact transition for an input held over the interval,
ST = expm(A dt), PR = A^-1 (ST - I) B (E1926 eq. 3-4: exact for the piecewise-linear smoothed
profile). It starts from the standard initialisation x = [s, 0, s, 0] with s = (Y(11 m) - Y(0))
/ 11 m, the slope of the first 11 m. The IRI is the mean rectified slope |x_1 - x_3| over the
intervals, in m/m, reported here in m/km (x 1000).

The simulation is in distance: the vehicle's own speed plays no part. ``IRIMeter`` takes a
profile sampled at arbitrary travelled distances (e.g. once per co-simulation step), resamples it
linearly on a grid of ``dx`` m and reports the IRI of each completed segment of ``segment`` m.
Hand-written (a 4-state loop of a few lines): no maintained Python package implements E1926.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

K1, K2, C, MU = 653.0, 63.3, 6.0, 0.15  # golden car, normalised by the sprung mass
SPEED = 80.0 / 3.6  # m/s
BASE = 0.25  # m, moving-average base length
INIT_LENGTH = 11.0  # m, length whose slope initialises the car
DX = 0.05  # m, default grid of the streaming meter
SEGMENT_RANGE = (1.0, 1e5)  # m, the iri_segment a user may ask for (at least 10 DX)


def golden_car() -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (4x4, 1/s) and B (4,) of the golden car with the profile slope as input."""
    A = np.array([[0.0, 1.0, 0.0, 0.0],
                  [-K2, -C, K2, C],
                  [0.0, 0.0, 0.0, 1.0],
                  [K2 / MU, C / MU, -(K1 + K2) / MU, -C / MU]])
    B = np.array([0.0, 0.0, 0.0, K1 / MU])
    return A, B


@lru_cache(maxsize=8)
def transition(dx: float) -> tuple[tuple[tuple[float, ...], ...], tuple[float, ...]]:
    """ST = expm(A dt) and PR = A^-1 (ST - I) B for dt = dx / 80 km/h (E1926 eqs. 3-4)."""
    A, B = golden_car()
    ST = expm(A * (dx / SPEED))
    PR = np.linalg.solve(A, (ST - np.eye(4)) @ B)
    return tuple(map(tuple, ST.tolist())), tuple(PR.tolist())


def smoothing_samples(dx: float) -> int:
    """k: samples spanned by the 250 mm moving average at spacing dx (m)."""
    return max(1, int(round(BASE / dx)))


def initial_state(profile: np.ndarray, dx: float) -> list[float]:
    """The standard initialisation from the slope of the first 11 m of ``profile`` (m)."""
    a = int(round(INIT_LENGTH / dx))
    if a >= len(profile):
        raise ValueError(f"a profile of {(len(profile) - 1) * dx:g} m is shorter than the {INIT_LENGTH:g} m "
                         "the IRI initialisation needs")
    s = float(profile[a] - profile[0]) / (a * dx)
    return [s, 0.0, s, 0.0]


def _simulate(slopes: np.ndarray, x: list[float], dx: float) -> tuple[np.ndarray, list[float]]:
    """Rectified slope |x1 - x3| after each interval of held input slope; returns (rs, final x)."""
    ST, PR = transition(float(dx))
    (a0, a1, a2, a3), (b0, b1, b2, b3), (c0, c1, c2, c3), (d0, d1, d2, d3) = ST
    p0, p1, p2, p3 = PR
    x0, x1, x2, x3 = x
    rs = np.empty(len(slopes))
    for i, u in enumerate(slopes.tolist()):
        x0, x1, x2, x3 = (a0 * x0 + a1 * x1 + a2 * x2 + a3 * x3 + p0 * u,
                          b0 * x0 + b1 * x1 + b2 * x2 + b3 * x3 + p1 * u,
                          c0 * x0 + c1 * x1 + c2 * x2 + c3 * x3 + p2 * u,
                          d0 * x0 + d1 * x1 + d2 * x2 + d3 * x3 + p3 * u)
        rs[i] = abs(x0 - x2)
    return rs, [x0, x1, x2, x3]


def rectified_slope(profile: np.ndarray, dx: float) -> np.ndarray:
    """|z_s' - z_u'| / V (m/m) of the golden car over each of the len(profile) - k intervals of
    the smoothed profile ``profile`` (m, spacing dx m), from the standard initialisation."""
    y = np.asarray(profile, float)
    k = smoothing_samples(dx)
    slopes = (y[k:] - y[:-k]) / (k * dx)
    return _simulate(slopes, initial_state(y, dx), dx)[0]


def iri(profile: np.ndarray, dx: float) -> float:
    """IRI in m/km of a whole profile (m) sampled every dx (m) (ASTM E1926)."""
    return 1e3 * float(np.mean(rectified_slope(profile, dx)))


def segment_iri(profile: np.ndarray, dx: float, segment: float) -> np.ndarray:
    """IRI in m/km of each complete segment of ``segment`` m of the profile (the car runs on
    through the segments; interval i, from i dx to (i + 1) dx, belongs to segment floor(i dx /
    segment))."""
    rs = rectified_slope(profile, dx)
    n = int(round(segment / dx))
    full = len(rs) // n
    return 1e3 * rs[:full * n].reshape(full, n).mean(axis=1)


class IRIMeter:
    """Streaming IRI of a profile fed as (travelled distance, height) pairs in any spacing.

    Heights are interpolated linearly on the grid s_0 + j dx; the car starts when 11 m of grid are
    in (the standard initialisation), then runs on every new interval whose 250 mm window is
    complete. ``iri`` is the IRI (m/km) of the last completed segment of ``segment`` m (segment j
    covers [s_0 + j segment, s_0 + (j + 1) segment)); 0 before the first (no road has an IRI of
    exactly 0). ``history`` keeps the
    (end distance, IRI) of every completed segment.
    """

    def __init__(self, segment: float = 100.0, dx: float = DX, start: float | None = None):
        """``start``: distance (m) of the grid origin; the first height is held back to it
        (default: the first distance fed)."""
        if not (math.isfinite(segment) and segment >= 10 * dx):
            raise ValueError(f"iri_segment = {segment!r} m must be at least {10 * dx:g} m")
        self.segment, self.dx = float(segment), float(dx)
        self.k = smoothing_samples(dx)
        self.per_segment = int(round(segment / dx))
        self._grid: list[float] = []  # heights on the grid not yet consumed by the car
        self._offset = 0  # grid index of _grid[0]
        self._s0: float | None = start
        self._last: tuple[float, float] | None = None
        self._x: list[float] | None = None
        self._done = 0  # intervals simulated
        self._sum = 0.0  # rectified slope summed over the current segment
        self.iri = 0.0
        self.history: list[tuple[float, float]] = []

    def update(self, s: float, z: float) -> float:
        """Add the height z (m) at travelled distance s (m, non-decreasing); return ``iri``."""
        if self._last is None:
            if self._s0 is None or self._s0 > s:
                self._s0 = s
            self._last = (self._s0, z)
            self._grid.append(z)
        s_prev, z_prev = self._last
        if s <= s_prev:
            return self.iri
        dx, s0 = self.dx, self._s0
        j = self._offset + len(self._grid)  # next grid index
        while s0 + j * dx <= s:
            sj = s0 + j * dx
            self._grid.append(z_prev + (z - z_prev) * (sj - s_prev) / (s - s_prev))
            j += 1
        self._last = (s, z)
        self._run()
        return self.iri

    def _run(self) -> None:
        grid, k = self._grid, self.k
        if self._x is None:
            a = int(round(INIT_LENGTH / self.dx))
            if len(grid) <= a:
                return
            self._x = initial_state(np.asarray(grid[:a + 1]), self.dx)
        n = len(grid) - k  # intervals whose smoothing window is complete
        if n <= 0 or (n < 64 and self._done % self.per_segment + n < self.per_segment):
            return  # in batches (cost), but a segment is reported as soon as it is complete
        y = np.asarray(grid)
        slopes = (y[k:k + n] - y[:n]) / (k * self.dx)
        rs, self._x = _simulate(slopes, self._x, self.dx)
        per = self.per_segment
        i = 0
        while i < n:
            take = min(n - i, per - self._done % per)
            self._sum += float(rs[i:i + take].sum())
            self._done += take
            i += take
            if self._done % per == 0:
                self.iri = 1e3 * self._sum / per
                self.history.append((self._done * self.dx, self.iri))
                self._sum = 0.0
        del grid[:n]
        self._offset += n
