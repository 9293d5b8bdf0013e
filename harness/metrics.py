"""Scores of road and mass estimates (pure numpy/scipy), fixed so that numbers compare.

Road error-STD % (Wang et al., *Road profile estimation for suspension system based on the minimum
model error criterion combined with a Kalman filter*, Table 2): 100 std(z_r_est - z_r) / std(z_r)
after a warm-up, both *raw* and *HP*: in the HP variant estimate and truth first pass through the
same zero-phase 0.5 Hz Butterworth high-pass (sosfiltfilt), because accelerations cannot observe
road drift below it. The HP filter runs over the whole record and the warm-up is cut afterwards,
so its edge transient falls in the warm-up.

What ``road_height_est`` estimates (docs/real-sensors.md): not the absolute elevation, which the
accelerations and the deflection do not observe, but the profile as inertial profilers report
it, the elevation high-passed in distance at the cut-off (``reference_profile``): the start
level, grades and vertical curves fall in its stop band. The truth of every score is that
profile of the true elevation: the *raw* scores and the 2-sigma coverage compare the estimate
with it, and the HP scores compare the HP of both.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfiltfilt

from ..plant.profile_band import PROFILE_CUTOFF, highpass_profile

HP_CUTOFF = 0.5  # Hz
HP_ORDER = 4
WARMUP = 10.0  # s


def warmup_for(t: np.ndarray) -> float:
    """The warm-up (s) a run of times ``t`` (s) is scored after: ``WARMUP``, or half the run if
    that is shorter."""
    return min(WARMUP, 0.5 * float(t[-1] - t[0]))


def highpass(x: np.ndarray, h: float, cutoff: float = HP_CUTOFF, order: int = HP_ORDER) -> np.ndarray:
    """Zero-phase Butterworth high-pass of a signal sampled every h s."""
    sos = butter(order, cutoff, btype="highpass", fs=1.0 / h, output="sos")
    return sosfiltfilt(sos, np.asarray(x, float))


def _cut(t: np.ndarray, *xs: np.ndarray, warmup: float) -> list[np.ndarray]:
    keep = np.asarray(t) >= np.asarray(t)[0] + warmup
    return [np.asarray(x)[keep] for x in xs]


def road_scores(t: np.ndarray, est: np.ndarray, truth: np.ndarray, std: np.ndarray | None = None, *,
                distance: np.ndarray, warmup: float = WARMUP, cutoff: float = PROFILE_CUTOFF) -> dict[str, float]:
    """Road scores of an estimate ``est`` (m, road_height_est) against the true elevation
    ``truth`` (m) at ``distance`` (m) sampled at times t (s, uniform) from the start of the run,
    both as ``reference_profile`` at ``cutoff`` m makes the truth (what the estimate estimates).

    Keys: err_std_raw_pct, err_std_hp_pct (100 std(err)/std(truth)), gain_hp
    (std(HP est)/std(HP truth), the in-band gain), rmse_raw_mm, rmse_hp_mm, profile_rms_mm (of the
    truth) and, with ``std`` (the reported 1-sigma, m), coverage_2sigma: fraction of raw errors
    within +-2 std.
    """
    t = np.asarray(t, float)
    h = float(np.median(np.diff(t)))
    est = np.asarray(est, float)
    truth = reference_profile(np.asarray(distance, float), np.asarray(truth, float), cutoff)
    hp_est, hp_truth = highpass(est, h), highpass(truth, h)
    e, r, he, hr = _cut(t, est, truth, hp_est, hp_truth, warmup=warmup)
    out = {
        "err_std_raw_pct": float(100 * np.std(e - r) / np.std(r)),
        "err_std_hp_pct": float(100 * np.std(he - hr) / np.std(hr)),
        "gain_hp": float(np.std(he) / np.std(hr)),
        "rmse_raw_mm": float(1e3 * np.sqrt(np.mean((e - r) ** 2))),
        "rmse_hp_mm": float(1e3 * np.sqrt(np.mean((he - hr) ** 2))),
        "profile_rms_mm": float(1e3 * np.sqrt(np.mean(r ** 2))),
    }
    if std is not None:
        (s,) = _cut(t, np.asarray(std, float), warmup=warmup)
        out["coverage_2sigma"] = float(np.mean(np.abs(e - r) <= 2 * s))
    return out


def reference_profile(distance: np.ndarray, height: np.ndarray, cutoff: float = PROFILE_CUTOFF) -> np.ndarray:
    """What ``road_height_est`` estimates: the profile in a distance band, as inertial profilers
    report it (m): the true elevation ``height`` (m) at ``distance`` (m, non-decreasing)
    high-passed in distance at the wavelength ``cutoff`` (m; plant.profile_band: third order,
    from rest at the first point, so the start level, a constant grade and a vertical curve give
    0). It does not depend on the speed, and a stop changes nothing."""
    return highpass_profile(distance, height, cutoff)


def mass_error_pct(est: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """100 (m_est - m_true) / m_true, element-wise."""
    return 100 * (np.asarray(est, float) - np.asarray(truth, float)) / np.asarray(truth, float)


def settling_time(t: np.ndarray, est: np.ndarray, truth: float, t_step: float, t_end: float | None = None,
                  band: float = 0.05) -> float:
    """Time (s) after ``t_step`` from which ``est`` stays within +-band*truth until ``t_end``
    (default: end of record); inf if it never settles, 0 if it is inside from the start."""
    t, est = np.asarray(t, float), np.asarray(est, float)
    sel = (t >= t_step) & (t < (np.inf if t_end is None else t_end))
    ts, es = t[sel], est[sel]
    if len(ts) == 0:
        return float("nan")
    out = np.abs(es - truth) > band * abs(truth)
    if not out.any():
        return 0.0
    last = int(np.nonzero(out)[0][-1])
    if last == len(ts) - 1:
        return float("inf")
    return float(ts[last + 1] - t_step)


def steady_mass_error_pct(t: np.ndarray, est: np.ndarray, truth: float, t0: float, t1: float) -> float:
    """Mean absolute mass error in % over [t0, t1) (steady-state accuracy)."""
    t = np.asarray(t, float)
    sel = (t >= t0) & (t < t1)
    return float(np.mean(np.abs(mass_error_pct(np.asarray(est)[sel], truth))))


def iri_segments(distance: np.ndarray, iri_true: np.ndarray,
                 iri_est: np.ndarray) -> list[tuple[float, float, float, float]]:
    """Per completed IRI segment, from the records of ISORoad.iri and SuspensionEstimator.iri_est
    (m/km, each the IRI of the last completed segment, 0 before the first): rows (distance m at
    which the segment was reported, IRI true, IRI estimated, error % = 100 (est / true - 1)).
    A segment is taken where the true IRI changes; the estimate completes the same segment in the
    same step (same distance grid)."""
    d, tr, es = (np.asarray(x, float) for x in (distance, iri_true, iri_est))
    idx = np.flatnonzero(np.diff(tr) != 0) + 1
    return [(float(d[i]), float(tr[i]), float(es[i]), float(100 * (es[i] / tr[i] - 1))) for i in idx
            if tr[i] > 0]
