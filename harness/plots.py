"""PNG plots of a record (matplotlib), for a report on a run.

The road is plotted against travelled distance (``ISORoad.distance``, m), the vehicle's signals
(accelerations, deflection, sprung mass) against time. Each trace has the full run on the left
and a short window on the right (shaded on the left). Measured signals are drawn underneath,
translucent, with the true ones thin on top; sensor noise and estimation errors are shown as
histograms with their standard deviation written. Error axes are symmetric about 0 and scaled to
the data (or, when a few outliers would flatten the rest, to a robust limit, with the number of
samples beyond it written in the panel). The figures carry the scores the run's summary prints
(harness/metrics.py): the road estimate's high-passed error, its ±2σ coverage, the IRI per
segment and the sprung-mass error over the part of the run it is scored on.

``figures`` builds the ``matplotlib.figure.Figure`` objects (no pyplot state), ``plot_result``
writes them as PNG files.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..plant.profile_band import PROFILE_CUTOFF

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

ZOOM_S = 1.0  # s, length of the time window (deflection)
ACC_ZOOM_S = 0.25  # s, that of the accelerations (a 10-15 Hz wheel hop sampled at 1 kHz)
ZOOM_M = 10.0  # m, length of the distance window (road)
MASS_BAND = 0.02  # the mass estimate has converged once it stays within this fraction of its final value
MASS_MIN_ZOOM_S = 0.5  # s, shortest window on the mass convergence
MASS_SCORED_FRACTION = 0.25  # the run's summary (runner.summary) scores the mass over the last quarter
PSD_DX = 0.05  # m, spacing of the road resampled over distance for its PSD
PSD_MIN_LENGTH = 20.0  # m of road after the warm-up, at least, for a PSD
IRI_TOLERANCE = 3.0  # %, the dashed lines of the IRI error panel
DPI = 110
_EST = "SuspensionEstimator."
_TRUE = dict(color="C3", lw=0.45, zorder=3)  # true signals: thin, red, on top
_MEAS = dict(color="C0", lw=1.6, alpha=0.5)  # measured and estimated signals: underneath, translucent
_GREY = dict(color="0.88", zorder=0)


def _figure(title: str, width: float = 12.0, height: float = 5.0) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    fig.suptitle(title, fontsize="medium")
    return fig


def _panels(fig: Figure, rows: int, hist: bool = False, heights: list[float] | None = None
            ) -> tuple[list[Axes], list[Axes], list[Axes]]:
    """Per row: a full-run panel, a window panel (each column sharing x) and, with ``hist``, a
    histogram panel of its own x."""
    widths = [3.0, 1.0] + ([1.1] if hist else [])
    gs = fig.add_gridspec(rows, len(widths), width_ratios=widths, height_ratios=heights or [1.0] * rows)
    full, zoom, hists = [], [], []
    for r in range(rows):
        full.append(fig.add_subplot(gs[r, 0], sharex=full[0] if full else None))
        zoom.append(fig.add_subplot(gs[r, 1], sharex=zoom[0] if zoom else None))
        if hist:
            hists.append(fig.add_subplot(gs[r, 2]))
    for ax in full[:-1] + zoom[:-1]:
        ax.tick_params(labelbottom=False)
    return full, zoom, hists


def _finish(fig: Figure) -> Figure:
    """Grids; the legends of the full-run panels above them, where they cover no trace."""
    for ax in fig.axes:
        ax.grid(True, alpha=0.3)
    for ax in fig.axes:
        n = len(ax.get_legend_handles_labels()[0])
        if ax.get_subplotspec().is_first_col() and n:
            ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=n if n <= 4 else (n + 1) // 2,
                      fontsize="small", frameon=False, borderaxespad=0.1)
    return fig


def _window(x: np.ndarray, start: float, length: float) -> tuple[float, float]:
    """A window of ``length`` (units of x) from ``start``, moved back to end with the record if
    it would run past it."""
    lo = max(float(x[0]), min(start, float(x[-1]) - length))
    return lo, min(lo + length, float(x[-1]))


def _span(lo: float, hi: float, unit: str) -> str:
    """``lo-hi unit`` with as many decimals as the length of the span asks for."""
    d = max(0, 1 - int(np.floor(np.log10(hi - lo)))) if hi > lo else 3
    return f"{lo:.{d}f}-{hi:.{d}f} {unit}"


def _zoom(ax_full: Axes, ax_zoom: Axes, x: np.ndarray, window: tuple[float, float], *ys: np.ndarray,
          unit: str = "s") -> None:
    """Limit ``ax_zoom`` to ``window`` with y-limits from what the ``ys`` do there; shade the
    window on ``ax_full``."""
    lo, hi = window
    ax_full.axvspan(lo, hi, color="gold", alpha=0.25, lw=0, zorder=0)
    ax_zoom.set_xlim(lo, hi)
    inside = (x >= lo) & (x <= hi)
    vals = np.concatenate([np.asarray(y)[inside] for y in ys]) if ys else np.array([])
    vals = vals[np.isfinite(vals)]
    if vals.size:
        a, b = float(vals.min()), float(vals.max())
        pad = 0.08 * (b - a) or 1e-9 + 0.05 * abs(a)
        ax_zoom.set_ylim(a - pad, b + pad)
    ax_zoom.set_title(_span(lo, hi, unit), fontsize="small")


def _symmetric_ylim(ax: Axes, err: np.ndarray, *also: np.ndarray, unit: str, q: float = 99.0,
                    ratio: float = 3.0, floor: float = 0.0) -> float:
    """Set y-limits ±L about 0 that hold ``err`` and ``also`` (e.g. a ±2σ band), at least
    ±``floor``. When the largest |value| is over ``ratio`` times the ``q``-th percentile (a few
    outliers would flatten the rest), L is twice that percentile instead and the panel says
    how many samples of ``err`` lie beyond it. Returns L."""
    v = np.abs(np.concatenate([np.ravel(a) for a in (err, *also)]))
    v = v[np.isfinite(v)]
    if not v.size:
        return 0.0
    big, robust = float(v.max()), float(np.percentile(v, q))
    lim = 1.08 * big if big <= ratio * robust else 2.0 * robust
    lim = max(lim, floor) or 1.0
    ax.set_ylim(-lim, lim)
    e = np.abs(np.asarray(err, float))
    out = int(np.count_nonzero(e > lim))
    if out:
        ax.text(0.995, 0.03, f"{out} samples beyond ±{lim:.3g} {unit} (max |error| {float(np.nanmax(e)):.3g} {unit})",
                transform=ax.transAxes, ha="right", va="bottom", fontsize="small",
                bbox=dict(facecolor="white", edgecolor="0.7", alpha=0.85, pad=2))
    return lim


def _histogram(ax: Axes, label: str, unit: str, *series: tuple[str, np.ndarray, str]) -> None:
    """Histograms (share of samples in %) of ``series`` (legend, values, colour), their std and
    mean in the legend."""
    vals = [np.asarray(v, float)[np.isfinite(v)] for _, v, _ in series]
    lo = min(float(np.percentile(v, 0.05)) for v in vals)
    hi = max(float(np.percentile(v, 99.95)) for v in vals)
    bins = np.linspace(lo, hi, 61) if hi > lo else 60
    for (name, _, colour), v in zip(series, vals):
        ax.hist(v, bins=bins, weights=np.full(v.size, 100.0 / v.size), histtype="stepfilled", color=colour,
                alpha=0.35, edgecolor=colour, lw=1.0,
                label=f"{name}\nσ {np.std(v):.3g} {unit}, mean {np.mean(v):+.2g} {unit}")
    ax.set_xlabel(f"{label} ({unit})")
    ax.set_ylabel("samples (%)")
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, 1.0), fontsize="x-small", frameon=False, handlelength=1.0)
    ax.set_ylim(top=ax.get_ylim()[1] * (1.15 + 0.25 * len(series)))  # room for the legend


def _shade(ax: Axes, lo: float, hi: float, label: str | None) -> None:
    ax.axvspan(lo, hi, **_GREY, lw=0, label=label)


def _road_axis(result: np.ndarray) -> tuple[np.ndarray, str, str]:
    """The road's x: travelled distance (m), or the time (s) in a record without it."""
    if "ISORoad.distance" in result.dtype.names:
        return np.asarray(result["ISORoad.distance"], float), "distance (m)", "m"
    return np.asarray(result["time"], float), "time (s)", "s"


def road_figure(result: np.ndarray, name: str, warmup: float) -> Figure:
    """The road height (mm) under the tyre against travelled distance (m)."""
    x, xlabel, unit = _road_axis(result)
    t = result["time"]
    z = 1e3 * np.asarray(result["ISORoad.road_height"], float)
    fig = _figure(f"{name}: road under the tyre ({x[-1] - x[0]:.0f} m)", height=3.4)
    (full,), (zoom,), _ = _panels(fig, 1)
    for a in (full, zoom):
        a.plot(x, z, color="C3", lw=0.7, label="ISORoad.road_height" if a is full else None)
    x_w = float(np.interp(t[0] + warmup, t, x))
    _zoom(full, zoom, x, _window(x, x_w, ZOOM_M if unit == "m" else ZOOM_S), z, unit=unit)
    full.set_ylabel("height (mm)")
    full.set_xlabel(xlabel)
    zoom.set_xlabel(xlabel)
    return _finish(fig)


def acceleration_figure(result: np.ndarray, name: str, warmup: float) -> Figure:
    """Measured and (if recorded) true sprung and unsprung accelerations (m/s²) against time (s),
    with histograms of measured - true (the sensor noise)."""
    t = np.asarray(result["time"], float)
    with_true = all(f"QuarterCar.acc_{k}_true" in result.dtype.names for k in ("sprung", "unsprung"))
    fig = _figure(f"{name}: accelerations, measured and true", height=5.6)
    full, zoom, hists = _panels(fig, 2, hist=with_true)
    win = _window(t, t[0] + warmup, ACC_ZOOM_S)
    for i, k in enumerate(("sprung", "unsprung")):
        meas = np.asarray(result[f"QuarterCar.acc_{k}"], float)
        full[i].plot(t, meas, **_MEAS, label="measured")
        zoom[i].plot(t, meas, ".", color="C0", ms=3.0, alpha=0.6)
        ys = [meas]
        if with_true:
            true = np.asarray(result[f"QuarterCar.acc_{k}_true"], float)
            full[i].plot(t, true, **_TRUE, label="true")
            zoom[i].plot(t, true, **{**_TRUE, "lw": 0.9})
            ys.append(true)
            _histogram(hists[i], f"{k}: measured - true", "m/s²", ("sensor noise", meas - true, "0.35"))
        _zoom(full[i], zoom[i], t, win, *ys)
        full[i].set_ylabel(f"{k} acceleration (m/s²)", fontsize="small")
    for a in (full[-1], zoom[-1]):
        a.set_xlabel("time (s)")
    return _finish(fig)


def _rolling_rms(t: np.ndarray, x: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """RMS of x over consecutive blocks of ``length`` s, at the blocks' centres."""
    h = float(np.median(np.diff(t)))
    n = max(1, int(round(length / h)))
    m = len(x) // n
    if m < 2:
        return t[:1], np.sqrt(np.mean(np.square(x)))[None]
    blocks = np.asarray(x[: m * n], float).reshape(m, n)
    return t[: m * n].reshape(m, n).mean(axis=1), np.sqrt(np.mean(blocks ** 2, axis=1))


def deflection_figure(result: np.ndarray, name: str, warmup: float) -> Figure:
    """Suspension deflection z_s - z_u (mm) against time (s): measured, true and estimated, the
    RMS of their errors over 0.5 s blocks (µm) and their histograms."""
    cols = result.dtype.names
    t = np.asarray(result["time"], float)
    meas = 1e3 * np.asarray(result["QuarterCar.susp_deflection"], float)
    true = 1e3 * (np.asarray(result["QuarterCar.z_s"], float) - np.asarray(result["QuarterCar.z_u"], float)) \
        if {"QuarterCar.z_s", "QuarterCar.z_u"} <= set(cols) else None
    est = 1e3 * np.asarray(result[_EST + "susp_deflection_est"], float) if _EST + "susp_deflection_est" in cols \
        else None
    win = _window(t, t[0] + warmup, ZOOM_S)
    fig = _figure(f"{name}: suspension deflection z_s - z_u", height=5.0 if true is not None else 3.2)
    if true is None:
        (full,), (zoom,), _ = _panels(fig, 1)
        for a in (full, zoom):
            a.plot(t, meas, color="C0", lw=0.7, label="measured" if a is full else None)
        _zoom(full, zoom, t, win, meas)
        full.set_ylabel("deflection (mm)")
        full.set_xlabel("time (s)")
        zoom.set_xlabel("time (s)")
        return _finish(fig)
    gs = fig.add_gridspec(2, 3, width_ratios=[3.0, 1.0, 1.1])
    full = [fig.add_subplot(gs[0, 0])]
    full.append(fig.add_subplot(gs[1, 0], sharex=full[0]))
    zoom = [fig.add_subplot(gs[0, 1])]
    zoom.append(fig.add_subplot(gs[1, 1], sharex=zoom[0]))
    hist = fig.add_subplot(gs[:, 2])
    for a in full[:1] + zoom[:1]:
        a.tick_params(labelbottom=False)
    full[0].plot(t, meas, **_MEAS, label="measured")
    full[0].plot(t, true, **_TRUE, label="true")
    zoom[0].plot(t, meas, ".", color="C0", ms=3.0, alpha=0.6)
    zoom[0].plot(t, true, **{**_TRUE, "lw": 0.9})
    errs = [("measured - true", meas - true, "C0")]
    if est is not None:
        full[0].plot(t, est, color="C2", lw=0.5, label="estimate")
        zoom[0].plot(t, est, color="C2", lw=0.9)
        errs.append(("estimate - true", est - true, "C2"))
        _shade(full[1], t[0], t[0] + warmup, "warm-up (not scored)")
    _zoom(full[0], zoom[0], t, win, meas, true)
    for label, e, c in errs:
        tc, rms = _rolling_rms(t, 1e3 * e, 0.5)
        full[1].plot(tc, rms, color=c, lw=1.0, marker=".", ms=3, label=label)
        if "measured" in label:  # samples of noise: dots, not a line that fills the panel
            zoom[1].plot(t, 1e3 * e, ".", color=c, ms=2.0, alpha=0.5)
        else:
            zoom[1].plot(t, 1e3 * e, color=c, lw=1.0)
    full[1].set_ylim(bottom=0)
    _zoom(full[1], zoom[1], t, win, *(1e3 * e for _, e, _ in errs))
    # the sensor noise over the run, the estimate's error after the warm-up (its start-up left out)
    after = t >= t[0] + warmup
    series = [(f"{label} (after the warm-up)" if label.startswith("estimate") else label,
               1e3 * (e[after] if label.startswith("estimate") else e), c) for label, e, c in errs]
    _histogram(hist, "error", "µm", *series)
    full[0].set_ylabel("deflection (mm)")
    full[1].set_ylabel("RMS over 0.5 s (µm)")
    zoom[1].set_ylabel("error (µm)", fontsize="small")
    for a in (full[1], zoom[1]):
        a.set_xlabel("time (s)")
    return _finish(fig)


def _score_road(result: np.ndarray, warmup: float, cutoff: float = PROFILE_CUTOFF) -> dict[str, float]:
    """``metrics.road_scores`` called as ``runner.summary`` calls it."""
    from .metrics import road_scores

    if "ISORoad.distance" not in result.dtype.names:
        raise ValueError("no ISORoad.distance recorded")
    std = result[_EST + "road_height_std"] if _EST + "road_height_std" in result.dtype.names else None
    return road_scores(result["time"], result[_EST + "road_height_est"], result["ISORoad.road_height"], std,
                       warmup=warmup, distance=result["ISORoad.distance"], cutoff=cutoff)


def _score_text(scores: dict[str, float], warmup: float, start: str) -> str:
    """The headline road scores as written on the figures (the numbers as ``runner.summary``
    rounds them, coverage to 0.1 %)."""
    from .metrics import HP_CUTOFF

    text = (f"scored after the {warmup:g} s warm-up ({start}): HP error std {scores['err_std_hp_pct']:.1f} % "
            f"({HP_CUTOFF:g} Hz high-pass), raw {scores['err_std_raw_pct']:.1f} %, HP gain {scores['gain_hp']:.3f}")
    if "coverage_2sigma" in scores:
        text += f"; within ±2σ {100 * scores['coverage_2sigma']:.1f} %"
    return text


def road_estimate_figure(result: np.ndarray, name: str, warmup: float, cutoff: float = PROFILE_CUTOFF) -> Figure:
    """The road estimate (mm) against the true road and its errors against travelled distance (m),
    with the scores of ``metrics.road_scores``: the raw error against what the estimate tracks
    (``metrics.reference_profile``) with the reported ±2σ band, and the error after the high-pass
    at ``metrics.HP_CUTOFF`` (the headline score); ``cutoff`` (m): the estimator's profile_cutoff."""
    from .metrics import HP_CUTOFF, highpass, reference_profile

    x, xlabel, unit = _road_axis(result)
    t = np.asarray(result["time"], float)
    true_m = np.asarray(result["ISORoad.road_height"], float)
    est, true = 1e3 * np.asarray(result[_EST + "road_height_est"], float), 1e3 * true_m
    std = 1e3 * np.asarray(result[_EST + "road_height_std"], float) if _EST + "road_height_std" in result.dtype.names \
        else None
    x_w = float(np.interp(t[0] + warmup, t, x))
    try:
        scores = _score_road(result, warmup, cutoff)
        ref_m = reference_profile(np.asarray(result["ISORoad.distance"], float), true_m, cutoff)
        ref = 1e3 * ref_m
        h = float(np.median(np.diff(t)))
        hp_err = 1e3 * (highpass(result[_EST + "road_height_est"], h) - highpass(ref_m, h))
        headline = _score_text(scores, warmup, f"from {x_w:.0f} {unit}")
    except ValueError as e:  # too short to score (the high-pass needs a few seconds): plot without
        ref, hp_err, headline = None, None, f"no score ({e})"
    rows = 2 if hp_err is None else 3
    fig = _figure(f"{name}: road estimate vs true road\n{headline}", height=2.2 * rows + 1.2)
    full, zoom, _ = _panels(fig, rows, heights=[1.3] + [1.0] * (rows - 1))
    for a in full:
        _shade(a, x[0], x_w, "warm-up (not scored)" if a is full[0] else None)
    win = _window(x, x_w, ZOOM_M if unit == "m" else ZOOM_S)
    for a in (full[0], zoom[0]):
        first = a is full[0]
        if std is not None:
            a.fill_between(x, est - 2 * std, est + 2 * std, color="C0", alpha=0.15, lw=0,
                           label="estimate ±2σ" if first else None)
        a.plot(x, est, color="C0", lw=1.0, label="estimate" if first else None)
        a.plot(x, true, **_TRUE, label="true road" if first else None)
        if ref is not None:
            a.plot(x, ref, color="k", lw=0.6, ls=(0, (3, 2)), zorder=4,
                   label="true profile (metrics.reference_profile)" if first else None)
    _zoom(full[0], zoom[0], x, win, est, true, *(() if ref is None else (ref,)), unit=unit)
    full[0].set_ylabel("height (mm)")

    raw = est - (ref if ref is not None else true)
    what = "estimate - true profile" if ref is not None else "estimate - true"
    for a in (full[1], zoom[1]):
        first = a is full[1]
        if std is not None:
            a.fill_between(x, -2 * std, 2 * std, color="C0", alpha=0.15, lw=0,
                           label="±2σ reported" if first else None)
        a.plot(x, raw, color="C0", lw=0.7, label=what if first else None)
        a.axhline(0, color="0.4", lw=0.5)
    band = (2 * std,) if std is not None else ()
    _symmetric_ylim(full[1], raw, *band, unit="mm")
    _zoom(full[1], zoom[1], x, win, raw, *band, *(-b for b in band), unit=unit)
    full[1].set_ylabel("raw error (mm)")
    if hp_err is not None:
        for a in (full[2], zoom[2]):
            a.plot(x, hp_err, color="C0", lw=0.6, label=f"HP estimate - HP true ({HP_CUTOFF:g} Hz high-pass)"
                   if a is full[2] else None)
            a.axhline(0, color="0.4", lw=0.5)
        _symmetric_ylim(full[2], hp_err, unit="mm")
        _zoom(full[2], zoom[2], x, win, hp_err, unit=unit)
        full[2].set_ylabel("HP error (mm)")
    for a in (full[-1], zoom[-1]):
        a.set_xlabel(xlabel)
    return _finish(fig)


def mass_convergence(t: np.ndarray, m_est: np.ndarray, m_true: np.ndarray, band: float = MASS_BAND
                     ) -> tuple[float, float, float, float]:
    """The sprung-mass estimate's convergence after the start or, if the true mass changes, after
    its first change: (t_a, t_b, final, t_in) in s, kg: from t_a (the start or the change) to t_b
    (the next change or the end) the estimate ends at ``final`` (kg, the median of the last tenth)
    and stays within ``band`` of it from t_in on (inf if it does not)."""
    t, m_est, m_true = (np.asarray(a, float) for a in (t, m_est, m_true))
    changes = np.flatnonzero(np.diff(m_true) != 0)
    if changes.size:
        gaps = np.flatnonzero(np.diff(changes) > 1)  # a ramp changes at consecutive samples
        first_end = changes[gaps[0]] if gaps.size else changes[-1]
        a = int(changes[0])
        b = int(changes[gaps[0] + 1]) if gaps.size else len(t) - 1
        seg = slice(int(first_end) + 1, b + 1)
    else:
        a, b = 0, len(t) - 1
        seg = slice(0, b + 1)
    ts, ms = t[seg], m_est[seg]
    final = float(np.median(ms[-max(1, len(ms) // 10):]))  # the end, less its noise
    out = np.abs(ms - final) > band * abs(final)
    if not out.any():
        t_in = float(ts[0])
    elif out[-1]:
        t_in = float("inf")
    else:
        t_in = float(ts[np.flatnonzero(out)[-1] + 1])
    return float(t[a]), float(t[b]), final, t_in


def sprung_mass_figure(result: np.ndarray, name: str) -> Figure:
    """The sprung-mass estimate (kg) against the true mass and its error (%) against time (s),
    the window on its convergence (``mass_convergence``) and the score ``runner.summary`` prints:
    the mean |error| over the last quarter of the run (the rest shaded as not scored)."""
    from .metrics import mass_error_pct

    t = np.asarray(result["time"], float)
    m_est = np.asarray(result[_EST + "sprung_mass_est"], float)
    m_true = np.asarray(result["QuarterCar.sprung_mass"], float)
    err = mass_error_pct(m_est, m_true)
    t_score = t[0] + (1 - MASS_SCORED_FRACTION) * (t[-1] - t[0])
    tail = t >= t_score
    score = float(np.mean(np.abs(err[tail])))
    t_a, t_b, final, t_in = mass_convergence(t, m_est, m_true)
    changed = t_a > t[0]
    what = "after the first change of mass" if changed else "from the start"
    settled = (f"within {100 * MASS_BAND:g} % of its final {final:.1f} kg {t_in - t_a:.2f} s {what}"
               if np.isfinite(t_in) else f"not within {100 * MASS_BAND:g} % of its final {final:.1f} kg {what}")
    fig = _figure(f"{name}: sprung mass estimate vs true\nmean |error| over the last quarter "
                  f"({t_score:.4g}-{t[-1]:.4g} s): {score:.2f} %; {settled}", height=5.4)
    full, zoom, _ = _panels(fig, 2)
    for a in full:
        _shade(a, t[0], t_score, "not in the mass score (summary: last quarter)" if a is full[0] else None)
    for a in (full[0], zoom[0]):
        a.plot(t, m_est, color="C0", lw=1.0, label="estimate" if a is full[0] else None)
        a.plot(t, m_true, **{**_TRUE, "lw": 1.0}, label="true" if a is full[0] else None)
    for a in (full[1], zoom[1]):
        a.plot(t, err, color="C0", lw=0.7, label="estimate - true" if a is full[1] else None)
        for s in (-1, 1):
            a.axhline(100 * s * MASS_BAND, color="0.4", lw=0.7, ls="--",
                      label=f"±{100 * MASS_BAND:g} %" if (s > 0 and a is full[1]) else None)
    lo, hi = float(min(m_true.min(), np.percentile(m_est, 0.5))), float(max(m_true.max(), np.percentile(m_est, 99.5)))
    full[0].set_ylim(lo - 0.1 * (hi - lo) - 0.05 * lo, hi + 0.1 * (hi - lo) + 0.05 * hi)
    _symmetric_ylim(full[1], err, unit="%", floor=150 * MASS_BAND)
    # the window: from the start or just before the change, to a few times the convergence time
    span = t_b - t_a
    if np.isfinite(t_in):
        span = min(span, max(MASS_MIN_ZOOM_S, 4.0 * (t_in - t_a)))
    win = (max(t[0], t_a - 0.15 * span) if changed else t_a, t_a + span)
    _zoom(full[0], zoom[0], t, win, m_est, m_true)
    _zoom(full[1], zoom[1], t, win, err, np.full_like(err, -100 * MASS_BAND), np.full_like(err, 100 * MASS_BAND))
    if np.isfinite(t_in):
        for a in zoom:
            a.axvline(t_in, color="0.3", lw=0.8, ls=":")
        zoom[0].annotate(f"within {100 * MASS_BAND:g} %", (t_in, 0.05), xycoords=("data", "axes fraction"),
                         xytext=(3, 0), textcoords="offset points", fontsize="x-small", color="0.3")
    zoom[0].set_title(f"{what}, {_span(*win, 's')}", fontsize="small")
    full[0].set_ylabel("sprung mass (kg)")
    full[1].set_ylabel("error (%)")
    for a in (full[1], zoom[1]):
        a.set_xlabel("time (s)")
    return _finish(fig)


def spatial_psd(distance: np.ndarray, height: np.ndarray, dx: float = PSD_DX) -> tuple[np.ndarray, np.ndarray]:
    """One-sided displacement PSD (m³) against spatial frequency n (cycle/m) of ``height`` (m)
    recorded at travelled ``distance`` (m): resampled every ``dx`` m, Welch with Hann windows of
    a quarter of the length (at most 4096 samples), linear detrend, as ISO 8608 asks for Gd(n)."""
    from scipy.signal import welch

    s, idx = np.unique(np.asarray(distance, float), return_index=True)  # standstill repeats a distance
    grid = np.arange(s[0], s[-1], dx)
    z = np.interp(grid, s, np.asarray(height, float)[idx])
    nper = min(4096, max(16, len(z) // 4))
    n, p = welch(z, fs=1.0 / dx, nperseg=nper, detrend="linear")
    return n[1:], p[1:]


def road_psd_figure(result: np.ndarray, name: str, warmup: float) -> Figure | None:
    """The spatial PSD Gd(n) (m³) of the estimated and the true road after the warm-up against
    spatial frequency (cycle/m), with the ISO 8608 class bounds; None for less than
    ``PSD_MIN_LENGTH`` m of road."""
    from suspension_estimation.plant import iso8608

    t = result["time"]
    keep = t >= t[0] + warmup
    d = np.asarray(result["ISORoad.distance"], float)[keep]
    if d.size < 2 or d[-1] - d[0] < PSD_MIN_LENGTH:
        return None
    n, p_true = spatial_psd(d, result["ISORoad.road_height"][keep])
    _, p_est = spatial_psd(d, result[_EST + "road_height_est"][keep])
    # up to a little past where the true road has content (its generated band, a profile's resolution)
    floor = iso8608.psd(n, iso8608.class_psd_n0(1) * 0.5) / 100
    n_hi = min(float(n[-1]), 1.5 * float(n[p_true >= floor].max())) if (p_true >= floor).any() else float(n[-1])
    shown = n <= n_hi
    n, p_true, p_est = n[shown], p_true[shown], p_est[shown]
    fig = _figure(f"{name}: road PSD after the warm-up, estimate vs true ({d[0]:.0f}-{d[-1]:.0f} m)", 8, 5.6)
    a = fig.add_subplot()
    # curves that coincide over most of the band: the true one broad and translucent underneath
    a.loglog(n, p_true, lw=2.2, color="C3", alpha=0.6, label="true road")
    a.loglog(n, p_est, lw=1.0, color="C0", label="estimate")
    # ISO 8608 classes: each spans a factor 4 around its Gd(n0); the bounds are drawn, the letters between
    for c in range(1, 10):
        bound = iso8608.class_psd_n0(min(c, 8)) * (0.5 if c <= 8 else 2.0)
        a.loglog(n, iso8608.psd(n, bound), lw=0.6, ls="--", color="0.55", zorder=0,
                 label="ISO 8608 class bounds" if c == 1 else None)
    top = max(float(p_true.max()), float(p_est.max())) * 3
    # the true road drops far below class A past its band: not scaled by that
    bottom = min(float(p_est.min()), float(iso8608.psd(n[-1], iso8608.class_psd_n0(1) * 0.5))) / 10
    for c in range(1, 9):
        y = float(iso8608.psd(n[-1], iso8608.class_psd_n0(c)))
        if bottom < y < top:
            a.text(n[-1], y, f" {iso8608.class_name(c)}", fontsize="small", color="0.35", va="center", ha="left")
    a.set_xlim(n[0], n[-1] * 1.25)
    a.set_ylim(bottom, top)
    a.set_ylabel("Gd(n) (m³)")
    a.set_xlabel("spatial frequency n (cycle/m)")
    return _finish(fig)


def iri_figure(rows: list[tuple[float, float, float, float]], name: str, start: float = 0.0) -> Figure:
    """Bars of the true and the estimated IRI (m/km) per segment (rows of ``metrics.iri_segments``)
    over travelled distance (m), the segments from ``start`` (m, the distance the first began at)
    to where each was reported, values on the bars; below, the error (%)."""
    ends = np.array([r[0] for r in rows])
    starts = np.concatenate([[start], ends[:-1]])
    width, mid = ends - starts, 0.5 * (starts + ends)
    true, est, err = (np.array([r[i] for r in rows]) for i in (1, 2, 3))
    fig = _figure(f"{name}: IRI per segment, true vs estimated", height=4.8)
    gs = fig.add_gridspec(2, 1, height_ratios=[1.4, 1.0])
    a1 = fig.add_subplot(gs[0])
    a2 = fig.add_subplot(gs[1], sharex=a1)
    a1.tick_params(labelbottom=False)
    b1 = a1.bar(mid - 0.21 * width, true, 0.4 * width, color="C3", label="true (ISORoad.iri)")
    b2 = a1.bar(mid + 0.21 * width, est, 0.4 * width, color="C0", label="estimated (iri_est)")
    for b in (b1, b2):
        a1.bar_label(b, fmt="%.2f", fontsize="small", padding=2)
    a1.set_ylim(0, 1.18 * max(float(true.max()), float(est.max())))
    a1.set_ylabel("IRI (m/km)")
    b3 = a2.bar(mid, err, 0.5 * width, color="0.45", label="estimated / true - 1")
    a2.bar_label(b3, fmt="%+.1f %%", fontsize="small", padding=2)
    for s in (-1, 1):
        a2.axhline(s * IRI_TOLERANCE, color="k", lw=0.6, ls="--", label=f"±{IRI_TOLERANCE:g} %" if s > 0 else None)
    a2.axhline(0, color="0.4", lw=0.5)
    lim = 1.3 * max(IRI_TOLERANCE, float(np.abs(err).max()))
    a2.set_ylim(-lim, lim)
    a2.set_ylabel("error (%)")
    edges = np.concatenate([starts[:1], ends])
    a2.set_xticks(edges, [f"{v:.0f}" for v in edges])
    a2.set_xlim(starts[0], ends[-1])
    a2.set_xlabel("distance (m), segment boundaries")
    return _finish(fig)


def figures(result: np.ndarray, name: str, warmup: float | None = None,
            cutoff: float = PROFILE_CUTOFF) -> dict[str, Figure]:
    """The figures of a record (structured array of ``runner.run_scenario``) by file suffix:
    ``road``, ``accelerations``, ``deflection`` and, with estimator columns, ``road_estimate``,
    ``sprung_mass``, ``road_psd`` (20 m of road after the warm-up, at least) and ``iri``.

    ``warmup`` (s) is shaded as not scored; default ``metrics.warmup_for(time)``, as in the run's
    summary; ``cutoff`` (m): the estimator's profile_cutoff, the truth's band.
    """
    from .metrics import iri_segments, warmup_for

    cols = set(result.dtype.names)
    t = result["time"]
    warmup = warmup_for(t) if warmup is None else warmup
    out: dict[str, Figure] = {}

    def has(*names: str) -> bool:
        return all(n in cols for n in names)

    if has("ISORoad.road_height"):
        out["road"] = road_figure(result, name, warmup)
    if has("QuarterCar.acc_sprung", "QuarterCar.acc_unsprung"):
        out["accelerations"] = acceleration_figure(result, name, warmup)
    if has("QuarterCar.susp_deflection"):
        out["deflection"] = deflection_figure(result, name, warmup)
    if has(_EST + "road_height_est", "ISORoad.road_height"):
        out["road_estimate"] = road_estimate_figure(result, name, warmup, cutoff)
    if has(_EST + "sprung_mass_est", "QuarterCar.sprung_mass"):
        out["sprung_mass"] = sprung_mass_figure(result, name)
    if has(_EST + "road_height_est", "ISORoad.road_height", "ISORoad.distance"):
        fig = road_psd_figure(result, name, warmup)
        if fig is not None:
            out["road_psd"] = fig
    if has(_EST + "iri_est", "ISORoad.iri", "ISORoad.distance"):
        rows = iri_segments(result["ISORoad.distance"], result["ISORoad.iri"], result[_EST + "iri_est"])
        if rows:
            out["iri"] = iri_figure(rows, name, start=float(result["ISORoad.distance"][0]))
    return out


def plot_result(result: np.ndarray, out: Path, name: str, warmup: float | None = None,
                cutoff: float = PROFILE_CUTOFF) -> list[Path]:
    """Write the ``figures`` of a record as ``<out>/<name>_<suffix>.png``; returns the files written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for suffix, fig in figures(result, name, warmup, cutoff).items():
        path = out / f"{name}_{suffix}.png"
        fig.savefig(path, dpi=DPI)
        files.append(path)
    return files


def plot_iri(rows: list[tuple[float, float, float, float]], path: Path, name: str, start: float = 0.0) -> Path:
    """Write ``iri_figure`` to ``path``."""
    iri_figure(rows, name, start).savefig(path, dpi=DPI)
    return Path(path)
