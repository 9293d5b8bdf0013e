"""Scores of road and mass estimates (pure numpy/scipy), fixed so that numbers compare.

Road error-STD % (Wang et al., *Road profile estimation for suspension system based on the minimum
model error criterion combined with a Kalman filter*, Table 2): 100 std(z_r_est - z_r) / std(z_r)
after a warm-up, both *raw* and *HP*: in the HP variant estimate and truth first pass through the
same zero-phase 0.5 Hz Butterworth high-pass (sosfiltfilt), because accelerations cannot observe
road drift below it. The HP filter runs over the whole record and the warm-up is cut afterwards,
so its edge transient falls in the warm-up.

What ``road_height_est`` estimates (docs/real-roads.md): not the absolute elevation, which the
accelerations and the deflection do not observe, but the elevation above the level the car
started on, passed through the estimator's common-mode reference, the causal high-pass
s^2 / (s^2 + 2 zeta w s + w^2) at f_ref = 0.01 Hz, zeta = 0.7071, in time, from rest at the
start (``reference_road``). Long grades and the start level fall in its stop band; vertical
curves of 100-300 m at 40-72 km/h (0.04-0.2 Hz) pass at 0.9-1.0 gain with a phase lead. The
*raw* scores and the 2-sigma coverage compare the estimate with that truth; ``rmse_abs_mm``
keeps the comparison with the absolute road (before this definition, "raw" meant that).
"""
from __future__ import annotations

import numpy as np
from scipy.signal import butter, lsim, sosfiltfilt

from ..estimators.model import RoadModel
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


def reference_road(t: np.ndarray, road: np.ndarray, f_ref: float = RoadModel.f_ref,
                   zeta_ref: float = RoadModel.zeta_ref, v0: float = 0.0, start: float | None = None) -> np.ndarray:
    """What ``road_height_est`` estimates (m) at times t (s), from the true road elevation
    ``road`` (m) there: y'' + 2 zeta w y' + w^2 y = road'' with y = y' = 0 at t[0], w = 2 pi
    f_ref, i.e. the high-pass s^2 / (s^2 + 2 zeta w s + w^2) of road - road[0] - v0 (t - t[0]).
    ``v0`` (m/s) is the body's vertical velocity at t[0]: 0 for a car that starts at rest, as
    QuarterCar.fmu does (it settles on the first road value); ``start`` (m) the level the car
    stood at rest on before t[0], default road[0] (a plant that starts at 0 under a road that
    starts elsewhere: start = 0, and the step passes through the high-pass). The start level and a constant
    grade from the start give 0; a grade that begins later gives a transient that decays over
    ~1 / (zeta w) = 23 s. Exact for a road linear between the samples (scipy.signal.lsim)."""
    t = np.asarray(t, float)
    z = np.asarray(road, float)
    if not f_ref > 0:
        return z - z[0]
    w = 2 * np.pi * f_ref
    u = z - (z[0] if start is None else float(start)) - v0 * (t - t[0])
    _, y, _ = lsim(([1.0, 0.0, 0.0], [1.0, 2 * zeta_ref * w, w * w]), u, t - t[0])
    return np.asarray(y, float)


def _cut(t: np.ndarray, *xs: np.ndarray, warmup: float) -> list[np.ndarray]:
    keep = np.asarray(t) >= np.asarray(t)[0] + warmup
    return [np.asarray(x)[keep] for x in xs]


def road_scores(t: np.ndarray, est: np.ndarray, truth: np.ndarray, std: np.ndarray | None = None,
                warmup: float = WARMUP, reference: bool = True, start: float | None = None) -> dict[str, float]:
    """Road scores of an estimate ``est`` against the true road ``truth`` (m, the elevation) sampled
    at times t (s, uniform) from the start of the run.

    Keys: err_std_raw_pct, err_std_hp_pct (100 std(err)/std(truth)), gain_hp
    (std(HP est)/std(HP truth), the in-band gain), rmse_raw_mm, rmse_hp_mm, rmse_abs_mm (against
    the absolute elevation) and, with ``std`` (the reported 1-sigma, m), coverage_2sigma:
    fraction of raw errors within +-2 std. Raw scores and coverage are against
    ``reference_road(t, truth)`` (what the estimate estimates, see the module doc), or with
    ``reference`` False against ``truth`` itself (estimators that report an absolute level);
    ``start``: as ``reference_road``'s.
    """
    t = np.asarray(t, float)
    h = float(np.median(np.diff(t)))
    est, absolute = np.asarray(est, float), np.asarray(truth, float)
    truth = reference_road(t, absolute, start=start) if reference else absolute
    hp_est, hp_truth = highpass(est, h), highpass(absolute, h)
    e, r, he, hr, a = _cut(t, est, truth, hp_est, hp_truth, absolute, warmup=warmup)
    out = {
        "rmse_abs_mm": float(1e3 * np.sqrt(np.mean((e - a) ** 2))),
        "err_std_raw_pct": float(100 * np.std(e - r) / np.std(r)),
        "err_std_hp_pct": float(100 * np.std(he - hr) / np.std(hr)),
        "gain_hp": float(np.std(he) / np.std(hr)),
        "rmse_raw_mm": float(1e3 * np.sqrt(np.mean((e - r) ** 2))),
        "rmse_hp_mm": float(1e3 * np.sqrt(np.mean((he - hr) ** 2))),
    }
    if std is not None:
        (s,) = _cut(t, np.asarray(std, float), warmup=warmup)
        out["coverage_2sigma"] = float(np.mean(np.abs(e - r) <= 2 * s))
    return out


def reference_profile(distance: np.ndarray, height: np.ndarray, cutoff: float = PROFILE_CUTOFF) -> np.ndarray:
    """The profile in a distance band, as inertial profilers report it (m): the true elevation
    ``height`` (m) at ``distance`` (m, non-decreasing) high-passed in distance at the wavelength
    ``cutoff`` (m; plant.profile_band: second order, from rest at the first point, so the start
    level and a constant grade give 0). It does not depend on the speed, and a stop changes
    nothing."""
    return highpass_profile(distance, height, cutoff)


def profile_scores(t: np.ndarray, distance: np.ndarray, profile: np.ndarray, truth: np.ndarray,
                   std: np.ndarray | None = None, cutoff: float = PROFILE_CUTOFF,
                   warmup: float = WARMUP) -> dict[str, float]:
    """Scores of ``profile`` (m, e.g. road_profile_est) against ``reference_profile`` of the true
    elevation ``truth`` (m) at ``distance`` (m), after ``warmup`` s of the times ``t`` (s). Keys:
    profile_rmse_mm, profile_rms_mm (of the reference), profile_err_pct (100 rmse / rms) and,
    with ``std`` (the reported 1-sigma, m), profile_coverage: the share of errors within +-2 std."""
    ref = reference_profile(distance, truth, cutoff)
    e, r = _cut(t, np.asarray(profile, float) - ref, ref, warmup=warmup)
    out = {"profile_rmse_mm": float(1e3 * np.sqrt(np.mean(e ** 2))),
           "profile_rms_mm": float(1e3 * np.sqrt(np.mean(r ** 2))),
           "profile_err_pct": float(100 * np.sqrt(np.mean(e ** 2) / np.mean(r ** 2)))}
    if std is not None:
        (s,) = _cut(t, np.asarray(std, float), warmup=warmup)
        out["profile_coverage"] = float(np.mean(np.abs(e) <= 2 * s))
    return out


def band_scores(t: np.ndarray, distance: np.ndarray, est: np.ndarray, truth: np.ndarray,
                cutoff: float = PROFILE_CUTOFF, warmup: float = WARMUP) -> dict[str, float]:
    """The error of any road estimate ``est`` (m) in the distance band of ``reference_profile``:
    ``profile_scores`` of the estimate passed through the same high-pass, so that a level, a
    grade or a drift longer than ``cutoff`` m leaves no error. Keys: band_rmse_mm, band_err_pct."""
    s = profile_scores(t, distance, reference_profile(distance, est, cutoff), truth, cutoff=cutoff, warmup=warmup)
    return {"band_rmse_mm": s["profile_rmse_mm"], "band_err_pct": s["profile_err_pct"]}


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
