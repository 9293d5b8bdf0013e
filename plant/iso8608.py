"""ISO 8608 road-roughness constants and the grade index.

Gd(n) = Gd(n0) * (n / n0)**-w with n0 = 0.1 cycle/m; class A..H (1..8) has the geometric-mean
value Gd(n0) = 16e-6 * 4**(class - 1) m^3 and spans a factor 4 around it. The grade index of
the IMMAKF paper (eq. 7) is d = log2(Gd(n0) * 1e6): 4 for A, 6 for B, ... 18 for H.
"""
from __future__ import annotations

import numpy as np

N0 = 0.1  # reference spatial frequency, cycle/m
GD_N0_A = 16e-6  # Gd(n0) of class A, m^3
WAVINESS = 2.0  # standard PSD exponent w
N_MIN = 0.011  # default band of a generated profile, cycle/m
N_MAX = 2.83
CLASSES = "ABCDEFGH"


def class_psd_n0(road_class: int) -> float:
    """Gd(n0) in m^3 of ISO class 1..8 (A..H)."""
    if not 1 <= int(road_class) <= 8:
        raise ValueError(f"road_class = {road_class!r} is outside the allowed range [1, 8] (A..H)")
    return GD_N0_A * 4.0 ** (int(road_class) - 1)


def psd(n: np.ndarray, gd_n0: float, waviness: float = WAVINESS) -> np.ndarray:
    """One-sided displacement PSD Gd(n) in m^3 at spatial frequency n in cycle/m."""
    return gd_n0 * (np.asarray(n, dtype=float) / N0) ** (-waviness)


def grade_index(gd_n0: float) -> float:
    """Grade index d = log2(Gd(n0) * 1e6) (IMMAKF paper, eq. 7)."""
    return float(np.log2(gd_n0 * 1e6))


def class_from_grade_index(d: float) -> int:
    """ISO class 1..8 whose band [d_c - 1, d_c + 1) holds d, with d_c = 2 * class + 2."""
    return int(np.clip(np.floor((d - 3.0) / 2.0) + 1, 1, 8))


def class_from_psd_n0(gd_n0: float) -> int:
    return class_from_grade_index(grade_index(gd_n0))


def class_name(road_class: int) -> str:
    return CLASSES[int(road_class) - 1]


def band_psd_errors(height: np.ndarray, dx: float, gd_n0: float, waviness: float = WAVINESS,
                    f_low: float = 0.02, f_high: float = 2.0,
                    segment: float = 500.0) -> list[tuple[float, float, float]]:
    """Relative error of the measured one-sided PSD against Gd(n) in octave bands.

    ``height`` is sampled every ``dx`` m. Welch (Hann, ``segment`` m, 50 % overlap); in each band
    [lo, min(2 lo, f_high)) the error is mean(measured) / mean(Gd) - 1.
    Returns [(lo, hi, error), ...].
    """
    from scipy.signal import welch

    nper = int(round(segment / dx))
    f, p = welch(np.asarray(height, float), fs=1.0 / dx, nperseg=nper, detrend="constant")
    out = []
    lo = f_low
    while lo < f_high * (1 - 1e-9):
        hi = min(2 * lo, f_high)
        m = (f >= lo) & (f < hi)
        out.append((lo, hi, float(p[m].mean() / psd(f[m], gd_n0, waviness).mean() - 1.0)))
        lo = hi
    return out
