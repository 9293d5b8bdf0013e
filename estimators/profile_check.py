"""A plausibility check of road_profile_est's long wavelengths against the road's ISO class.

An error the road filter cannot absorb makes the estimate drift; in the distance band of the
profile that drift is long-wavelength content beyond what the road has (before the profile was
freed of the filter's reference, a 0.1 m/s^2 body accelerometer bias at 40 km/h on ISO C: 30-100 mm
of error against ~8 mm of true content between 30 and 91 m; docs/real-sensors.md). The filter's
covariance knows nothing of it. The check compares the running mean square of the profile between ``cutoff`` / 3 and
``cutoff`` m (a band-pass in distance) with the ISO 8608 expectation of that band for the assumed
class (``ratio`` 4: one class rougher, as a class spans a factor 4 in PSD and the class identified
online may be one off). While it is more than ``ratio`` times that expectation the state is ``EXCESS`` and
``excess`` (m^2, the mean square beyond the expectation) is what road_profile_std's variance gains.
"""
from __future__ import annotations

import math

import numpy as np

from ..plant import iso8608
from ..plant.profile_band import DistanceHighpass, band_response

CONSISTENT, EXCESS = "consistent", "excess"


def band_mean_square(gd_n0: float, cutoff: float, short: float) -> float:
    """ISO 8608 mean square (m^2) of a profile of Gd(n0) through the high-pass at ``cutoff`` m
    minus the one at ``short`` m (the band between the two wavelengths), over the ISO band."""
    n = np.geomspace(iso8608.N_MIN, iso8608.N_MAX, 2000)
    g = np.abs(band_response(n, cutoff) - band_response(n, short)) ** 2
    return float(np.trapezoid(g * iso8608.psd(n, gd_n0), n))


class LongWaveCheck:
    """Running mean square of the profile's long wavelengths over ``window`` m of travel, against
    the ISO expectation (see the module doc)."""

    def __init__(self, cutoff: float, window: float | None = None, ratio: float = 4.0):
        self.cutoff = float(cutoff)
        self.short = self.cutoff / 3.0
        self.window = float(window if window is not None else 2.0 * cutoff)
        self.ratio = float(ratio)
        self._short_band = DistanceHighpass(self.short)
        self.mean_square = 0.0  # m^2, running mean square of the long-wavelength band
        self.travelled = 0.0  # m since the start
        self.state = CONSISTENT
        self.excess = 0.0  # m^2
        self._expected: dict[int, float] = {}

    def expected(self, road_class: int) -> float:
        """ISO mean square (m^2) of the band for ``road_class``."""
        c = int(road_class)
        if c not in self._expected:
            self._expected[c] = band_mean_square(iso8608.class_psd_n0(c), self.cutoff, self.short)
        return self._expected[c]

    def step(self, ds: float, profile_input: float, profile: float, road_class: int) -> str:
        """One sample: ``ds`` m travelled, ``profile_input`` (m) the input of the profile's
        high-pass (DistanceHighpass.u), ``profile`` (m) its output; returns the state."""
        long_wave = profile - self._short_band.step(ds, profile_input)
        if ds > 0.0:
            self.travelled += ds
            w = ds / min(self.window, max(self.travelled, ds))
            self.mean_square += min(w, 1.0) * (long_wave * long_wave - self.mean_square)
        if self.travelled < self.window or not math.isfinite(self.mean_square):
            self.state, self.excess = CONSISTENT, 0.0
            return self.state
        limit = self.expected(road_class)
        self.state = EXCESS if self.mean_square > self.ratio * limit else CONSISTENT
        self.excess = self.mean_square - limit if self.state == EXCESS else 0.0
        return self.state
