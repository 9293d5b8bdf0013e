"""Road profiles as functions of travelled distance: synthetic ISO 8608 and measured.

Both give the elevation h(s) in m and the slope dh/ds at a distance s in m, with a cubic
Hermite interpolant between nodes whose values and slopes are exact (synthetic) or PCHIP
(measured), so the slope is the exact derivative of the height that is reported. The road
velocity at speed v is dh/dt = dh/ds * v.
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from . import iso8608
from .profile_formats import ProfileError, read_profile  # noqa: F401 - re-exported

SYNTH_DX = 0.05  # m between nodes of the synthetic profile
SYNTH_NODES = 2 ** 20  # nodes per period: the synthetic road repeats every 52.4288 km


class _Hermite:
    """Piecewise cubic Hermite curve through (s_i, h_i) with slopes m_i."""

    def __init__(self, s: np.ndarray, h: np.ndarray, m: np.ndarray, period: float | None = None):
        self.s, self.h, self.m = s, h, m
        self.period = period
        self.uniform_dx = float(s[1] - s[0]) if period is not None else None
        self.start, self.end = float(s[0]), float(s[-1])

    def _locate(self, s: float) -> tuple[int, float, float]:
        if self.period is not None:
            s = s % self.period
            i = min(int(s / self.uniform_dx), len(self.s) - 1)
        else:
            i = int(np.searchsorted(self.s, s, side="right")) - 1
            i = min(max(i, 0), len(self.s) - 2)
        return i, s, float(self.s[i])

    def eval(self, s: float) -> tuple[float, float]:
        """(h, dh/ds) at distance s."""
        i, s, s0 = self._locate(s)
        n = len(self.s)
        j = i + 1
        if j == n:  # only for a periodic curve: the segment closing the period
            j = 0
            d = self.period - s0
        else:
            d = float(self.s[j]) - s0
        t = (s - s0) / d
        h0, h1 = float(self.h[i]), float(self.h[j])
        m0, m1 = float(self.m[i]) * d, float(self.m[j]) * d
        t2 = t * t
        t3 = t2 * t
        h = (2 * t3 - 3 * t2 + 1) * h0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * h1 + (t3 - t2) * m1
        dh = ((6 * t2 - 6 * t) * h0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * h1
              + (3 * t2 - 2 * t) * m1) / d
        return h, dh


@lru_cache(maxsize=4)
def _synthetic_nodes(gd_n0: float, waviness: float, n_min: float, n_max: float,
                     seed: int) -> tuple[np.ndarray, np.ndarray]:
    n_nodes, dx = SYNTH_NODES, SYNTH_DX
    length = n_nodes * dx
    k = np.arange(n_nodes // 2 + 1)
    n = k / length
    band = (n >= n_min) & (n <= n_max)
    # Harmonic superposition with exact amplitudes and random phases:
    # h(s) = sum_k sqrt(2 Gd(n_k) dn) cos(2 pi n_k s + phi_k), dn = 1 / length.
    amp = np.zeros(len(k))
    amp[band] = np.sqrt(2.0 * iso8608.psd(n[band], gd_n0, waviness) / length)
    phase = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, len(k))
    spec = 0.5 * n_nodes * amp * np.exp(1j * phase)
    h = np.fft.irfft(spec, n_nodes)
    slope = np.fft.irfft(spec * (2j * np.pi * n), n_nodes)
    h.setflags(write=False)
    slope.setflags(write=False)
    return h, slope


class SyntheticRoad:
    """ISO 8608 road: one-sided PSD Gd(n) = gd_n0 (n/n0)^-waviness for n_min <= n <= n_max.

    The same seed gives the same elevation at the same distance, whatever the speed.
    """

    def __init__(self, gd_n0: float, waviness: float = iso8608.WAVINESS, n_min: float = iso8608.N_MIN,
                 n_max: float = iso8608.N_MAX, seed: int = 1):
        if not (gd_n0 > 0 and np.isfinite(gd_n0)):
            raise ValueError(f"psd_n0 = {gd_n0!r} must be > 0")
        if not 0 < n_min < n_max <= 0.5 / SYNTH_DX:
            raise ValueError(f"need 0 < n_min < n_max <= {0.5 / SYNTH_DX:g} 1/m, got n_min = {n_min!r}, "
                             f"n_max = {n_max!r}")
        if not 0 <= waviness <= 5:
            raise ValueError(f"waviness = {waviness!r} is outside the allowed range [0, 5]")
        self.gd_n0 = gd_n0
        self._args = (float(gd_n0), float(waviness), float(n_min), float(n_max), int(seed))
        h, slope = _synthetic_nodes(float(gd_n0), float(waviness), float(n_min), float(n_max), int(seed))
        s = np.arange(SYNTH_NODES) * SYNTH_DX
        self._curve = _Hermite(s, h, slope, period=SYNTH_NODES * SYNTH_DX)
        self.length = math.inf

    def __reduce__(self):
        # pickled (process pools) by its parameters: the 16 MB of nodes are rebuilt (cached)
        return SyntheticRoad, self._args

    def height(self, s: float) -> float:
        return self._curve.eval(s)[0]

    def slope(self, s: float) -> float:
        return self._curve.eval(s)[1]

    def eval(self, s: float) -> tuple[float, float]:
        """(height m, slope dh/ds) at distance s in m."""
        return self._curve.eval(s)


PROFILE_END = {0: "stop", 1: "hold", 2: "loop"}


def _pchip_slopes(s: np.ndarray, h: np.ndarray, block: int = 1 << 20) -> np.ndarray:
    """PCHIP's slopes dh/ds at the nodes, ``block`` nodes at a time: a node's slope depends on its
    neighbours only, so the same values as of the whole profile at once, in the memory of a block
    (PchipInterpolator holds about 80 bytes a node while it works)."""
    from scipy.interpolate import PchipInterpolator

    out = np.empty(len(s))
    for a in range(0, len(s), block):
        b = min(a + block, len(s))
        lo, hi = max(a - 2, 0), min(b + 2, len(s))  # two neighbours: an end node's slope takes three nodes
        out[a:b] = PchipInterpolator(s[lo:hi], h[lo:hi]).derivative()(s[a:b])
    return out


class MeasuredRoad:
    """A measured profile: driving starts at its first distance; PCHIP between samples.

    ``profile_end`` says what lies past the last sample: 0 = nothing (``eval`` raises a
    ProfileError that says so), 1 = the last elevation, held flat, 2 = the profile again, shifted
    by its end-to-start rise per lap so that the road stays continuous. Before the first sample
    (a negative distance: a rear tyre behind the start) the first elevation is held flat.
    """

    def __init__(self, distance: np.ndarray, elevation: np.ndarray, name: str = "profile", profile_end: int = 0):
        if profile_end not in PROFILE_END:
            raise ValueError(f"profile_end = {profile_end!r} is not one of {PROFILE_END}")
        slope = _pchip_slopes(distance, elevation)
        self._curve = _Hermite(np.asarray(distance, float), np.asarray(elevation, float), slope)
        self.name = name
        self.length = float(distance[-1] - distance[0])
        self.profile_end = int(profile_end)
        self._rise = float(elevation[-1] - elevation[0])

    @classmethod
    def from_file(cls, path: str | Path, units: str = "", lateral_offset: float = 0.0,
                  profile_end: int = 0) -> "MeasuredRoad":
        return cls(*read_profile(path, units, lateral_offset), name=str(path), profile_end=profile_end)

    def eval(self, s: float) -> tuple[float, float]:
        if s < 0.0:
            return float(self._curve.h[0]), 0.0
        if s > self.length * (1 + 1e-12):
            if self.profile_end == 1:
                return self._curve.eval(self._curve.end)[0], 0.0
            if self.profile_end == 2:
                lap = math.floor(s / self.length)
                h, dh = self._curve.eval(self._curve.start + (s - lap * self.length))
                return h + lap * self._rise, dh
            raise ProfileError(f"end of the profile: travelled distance {s:.3f} m is past the end of {self.name} "
                               f"({self.length:.3f} m long); profile_end = 0 stops here (1 holds the last "
                               "elevation, 2 loops)")
        return self._curve.eval(self._curve.start + s)

    def height(self, s: float) -> float:
        return self.eval(s)[0]

    def slope(self, s: float) -> float:
        return self.eval(s)[1]
