"""PNG plots of a record (matplotlib, Agg backend), for a report on a run.

Time series have the full run on the left and a short window on the right (shaded on the left),
where 1 kHz signals are dense enough to see. Where curves would lie on top of each other
(measured, true and estimated deflection; measured and true accelerations) the differences get
their own panels. The warm-up that the scores leave out is shaded grey. With the estimator: the
road estimate against the truth with its ±2σ band and its error, the sprung-mass estimate with
y-limits set by the true mass (the start-up transient is in its own window), and the spatial PSD
of the estimated and the true road against the ISO 8608 classes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

ZOOM_S = 1.0  # s, length of the zoom window
ACC_ZOOM_S = 0.25  # s, that of the accelerations (a 10-15 Hz wheel hop sampled at 1 kHz)
MASS_START_S = 2.0  # s, window on the start or the first mass change of the sprung-mass estimate
PSD_DX = 0.05  # m, spacing of the road resampled over distance for its PSD
PSD_MIN_LENGTH = 20.0  # m of road after the warm-up, at least, for a PSD
_GREY = dict(color="0.85", zorder=0)


def _figure(title: str, rows: int, zoom: bool = True, heights: list[float] | None = None):
    """A figure of ``rows`` rows (relative ``heights``): a wide full-run panel and, with ``zoom``,
    a narrow window panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    heights = heights or [1.0] * rows
    grid = {"height_ratios": heights, **({"width_ratios": [3, 1]} if zoom else {})}
    fig, axes = plt.subplots(rows, 2 if zoom else 1, figsize=(12, 2.4 * sum(heights) + 0.8), squeeze=False,
                             sharex="col", gridspec_kw=grid)
    fig.suptitle(title)
    return fig, axes


def _save(fig, path: Path, xlabel: str = "time (s)") -> Path:
    import matplotlib.pyplot as plt

    for ax in fig.axes:
        ax.grid(True, alpha=0.3)
        if ax.get_subplotspec().is_last_row():
            ax.set_xlabel(xlabel)
    # legends above the full-run panels, where they cover no trace
    for ax in fig.axes:
        if ax.get_subplotspec().is_first_col() and ax.get_legend_handles_labels()[0]:
            ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=5, fontsize="small", frameon=False,
                      borderaxespad=0.1)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _window(t: np.ndarray, warmup: float, length: float = ZOOM_S) -> tuple[float, float]:
    """A window of ``length`` s just after the warm-up (or at the end of a short run)."""
    start = min(t[0] + warmup, t[-1] - length)
    return max(start, t[0]), min(max(start, t[0]) + length, t[-1])


def _zoom(ax_full, ax_zoom, t: np.ndarray, window: tuple[float, float], *ys: np.ndarray) -> None:
    """Limit ``ax_zoom`` to ``window`` with y-limits from what the ``ys`` do there; shade the
    window on ``ax_full``."""
    lo, hi = window
    ax_full.axvspan(lo, hi, color="gold", alpha=0.25, zorder=0)
    ax_zoom.set_xlim(lo, hi)
    inside = (t >= lo) & (t <= hi)
    vals = np.concatenate([np.asarray(y)[inside] for y in ys]) if ys else np.array([])
    vals = vals[np.isfinite(vals)]
    if vals.size:
        a, b = float(vals.min()), float(vals.max())
        pad = 0.08 * (b - a) or 1e-9 + 0.05 * abs(a)
        ax_zoom.set_ylim(a - pad, b + pad)
    ax_zoom.set_title(f"{lo:.4g}-{hi:.4g} s", fontsize="small")


def _warmup(t: np.ndarray, warmup: float, *axes) -> None:
    for ax in axes:
        ax.axvspan(t[0], t[0] + warmup, **_GREY, label="warm-up (not scored)" if ax is axes[0] else None)


def plot_result(result: np.ndarray, out: Path, name: str, warmup: float | None = None) -> list[Path]:
    """Write ``<name>_road.png``, ``_accelerations.png``, ``_deflection.png`` and, with estimator
    columns, ``_road_estimate.png``, ``_sprung_mass.png`` and ``_road_psd.png`` into ``out``.

    ``warmup`` (s) is shaded as not scored; default ``metrics.warmup_for(time)``, as in the run's
    summary. Returns the files written.
    """
    from .metrics import warmup_for

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cols = set(result.dtype.names)
    t = result["time"]
    warmup = warmup_for(t) if warmup is None else warmup
    win = _window(t, warmup)
    files = []

    def has(*names):
        return all(n in cols for n in names)

    def col(n, scale=1.0):
        return scale * np.asarray(result[n], float)

    est_prefix = "SuspensionEstimator."

    if has("ISORoad.road_height"):
        fig, ax = _figure(f"{name}: road under the tyre", 1)
        z = col("ISORoad.road_height", 1e3)
        for a in ax[0]:
            a.plot(t, z, lw=0.7, label="road_height")
        _zoom(*ax[0], t, win, z)
        ax[0, 0].set_ylabel("height (mm)")
        files.append(_save(fig, out / f"{name}_road.png"))

    if has("QuarterCar.acc_sprung", "QuarterCar.acc_unsprung"):
        pairs = [("sprung", "QuarterCar.acc_sprung"), ("unsprung", "QuarterCar.acc_unsprung")]
        with_true = has("QuarterCar.acc_sprung_true", "QuarterCar.acc_unsprung_true")
        # with the truth: under each signal, measured - true (the sensor noise), which is too small
        # to see beside the signal
        fig, ax = _figure(f"{name}: accelerations, measured and true", 4 if with_true else 2,
                          heights=[1.5, 0.7, 1.5, 0.7] if with_true else None)
        win_acc = _window(t, warmup, ACC_ZOOM_S)
        for i, (label, n) in enumerate(pairs):
            row = ax[2 * i] if with_true else ax[i]
            meas = col(n)
            row[0].plot(t, meas, lw=0.5, color="C0", label="measured")
            row[1].plot(t, meas, ".", ms=2.5, color="C0")
            ys = [meas]
            if with_true:
                true = col(n + "_true")
                row[0].plot(t, true, lw=0.4, color="C3", alpha=0.8, label="true")
                row[1].plot(t, true, lw=0.9, color="C3")
                ys.append(true)
                diff = ax[2 * i + 1]
                for a in diff:
                    a.plot(t, meas - true, lw=0.4, color="0.3", label="measured - true" if a is diff[0] else None)
                _zoom(*diff, t, win_acc, meas - true)
                diff[0].set_ylabel("noise (m/s²)")
            _zoom(*row, t, win_acc, *ys)
            row[0].set_ylabel(f"{label} (m/s²)")
        files.append(_save(fig, out / f"{name}_accelerations.png"))

    if has("QuarterCar.susp_deflection"):
        meas = col("QuarterCar.susp_deflection", 1e3)
        true = col("QuarterCar.z_s", 1e3) - col("QuarterCar.z_u", 1e3) if has("QuarterCar.z_s", "QuarterCar.z_u") \
            else None
        est = col(est_prefix + "susp_deflection_est", 1e3) if has(est_prefix + "susp_deflection_est") else None
        rows = 1 + (true is not None)
        fig, ax = _figure(f"{name}: suspension deflection z_s - z_u", rows)
        ref = true if true is not None else meas
        ax[0, 0].plot(t, ref, lw=0.6, color="C3" if true is not None else "C0",
                      label="true" if true is not None else "measured")
        ax[0, 1].plot(t, ref, lw=0.9, color=ax[0, 0].lines[-1].get_color())
        _zoom(*ax[0], t, win, ref)
        ax[0, 0].set_ylabel("deflection (mm)")
        if true is not None:
            errs = [("measured - true", meas - true, "C0", 0.45)]
            if est is not None:
                errs.append(("estimate - true", est - true, "C2", 1.0))
            for label, e, c, alpha in errs:
                ax[1, 0].plot(t, 1e3 * e, lw=0.6, color=c, alpha=alpha, label=label)
                ax[1, 1].plot(t, 1e3 * e, lw=0.9, color=c, alpha=alpha)
            _zoom(*ax[1], t, win, *(1e3 * e for _, e, _, _ in errs))
            ax[1, 0].set_ylabel("error (µm)")
            if est is not None:
                _warmup(t, warmup, ax[1, 0])
        files.append(_save(fig, out / f"{name}_deflection.png"))

    if has(est_prefix + "road_height_est", "ISORoad.road_height"):
        est, true = col(est_prefix + "road_height_est", 1e3), col("ISORoad.road_height", 1e3)
        std = col(est_prefix + "road_height_std", 1e3) if has(est_prefix + "road_height_std") else None
        fig, ax = _figure(f"{name}: road estimate vs true road", 2)
        _warmup(t, warmup, ax[0, 0], ax[1, 0])
        for a in ax[0]:
            a.plot(t, true, lw=0.8, color="C3", label="true")
            a.plot(t, est, lw=0.8, color="C0", label="estimate")
            if std is not None:
                a.fill_between(t, est - 2 * std, est + 2 * std, color="C0", alpha=0.2, lw=0, label="estimate ±2σ")
        for a in ax[1]:
            a.plot(t, est - true, lw=0.6, color="C0", label="estimate - true")
            if std is not None:
                a.fill_between(t, -2 * std, 2 * std, color="C0", alpha=0.15, lw=0, label="±2σ reported")
        _zoom(*ax[0], t, win, est, true)
        _zoom(*ax[1], t, win, est - true, *((2 * std, -2 * std) if std is not None else ()))
        # the full error panel scaled by what is scored, not by the start
        after = t >= t[0] + warmup
        if after.any():
            e = np.abs((est - true)[after])
            lim = 1.15 * max(float(e.max()), 2 * float(std[after].max()) if std is not None else 0.0)
            ax[1, 0].set_ylim(-lim, lim)
        ax[0, 0].set_ylabel("height (mm)")
        ax[1, 0].set_ylabel("error (mm)")
        files.append(_save(fig, out / f"{name}_road_estimate.png"))

    if has(est_prefix + "sprung_mass_est", "QuarterCar.sprung_mass"):
        m_est, m_true = col(est_prefix + "sprung_mass_est"), col("QuarterCar.sprung_mass")
        fig, ax = _figure(f"{name}: sprung mass estimate vs true", 2)
        _warmup(t, warmup, ax[0, 0], ax[1, 0])
        err = 100 * (m_est - m_true) / m_true
        for a in ax[0]:
            a.plot(t, m_true, lw=1.2, color="C3", label="true")
            a.plot(t, m_est, lw=0.8, color="C0", label="estimate")
        for a in ax[1]:
            a.plot(t, err, lw=0.6, color="C0", label="estimate - true")
            for s in (-5, 5):
                a.axhline(s, color="0.4", lw=0.7, ls="--", label="±5 %" if (s > 0 and a is ax[1, 0]) else None)
        # full run: limits from the true mass (±15 %) and ±10 % of error; the start in its own window
        lo, hi = float(m_true.min()), float(m_true.max())
        ax[0, 0].set_ylim(0.85 * lo, 1.15 * hi)
        ax[1, 0].set_ylim(-10, 10)
        # the window: the first change of the true mass if there is one, else the start-up
        changes = np.flatnonzero(np.diff(m_true) != 0)
        t0 = t[changes[0]] - 0.25 * MASS_START_S if changes.size else t[0]
        start = (max(t[0], t0), min(max(t[0], t0) + MASS_START_S, t[-1]))
        _zoom(*ax[0], t, start, m_est, m_true)
        _zoom(*ax[1], t, start, err)
        what = "first change of mass" if changes.size else "start-up"
        ax[0, 1].set_title(f"{what}, {start[0]:.4g}-{start[1]:.4g} s", fontsize="small")
        ax[0, 0].set_ylabel("sprung mass (kg)")
        ax[1, 0].set_ylabel("error (%)")
        files.append(_save(fig, out / f"{name}_sprung_mass.png"))

    if has(est_prefix + "road_height_est", "ISORoad.road_height", "ISORoad.distance"):
        path = _road_psd(result, out / f"{name}_road_psd.png", name, warmup)
        if path is not None:
            files.append(path)
    if has("SuspensionEstimator.iri_est", "ISORoad.iri", "ISORoad.distance"):
        from .metrics import iri_segments

        rows = iri_segments(result["ISORoad.distance"], result["ISORoad.iri"], result["SuspensionEstimator.iri_est"])
        if rows:
            files.append(plot_iri(rows, out / f"{name}_iri.png", name))
    return files


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


def _road_psd(result: np.ndarray, path: Path, name: str, warmup: float) -> Path | None:
    from plant import iso8608

    t = result["time"]
    keep = t >= t[0] + warmup
    d = np.asarray(result["ISORoad.distance"], float)[keep]
    if d.size < 2 or d[-1] - d[0] < PSD_MIN_LENGTH:
        return None
    n, p_true = spatial_psd(d, result["ISORoad.road_height"][keep])
    _, p_est = spatial_psd(d, result["SuspensionEstimator.road_height_est"][keep])
    # up to a little past where the true road has content (its generated band, a profile's resolution)
    floor = iso8608.psd(n, iso8608.class_psd_n0(1) * 0.5) / 100
    n_hi = min(float(n[-1]), 1.5 * float(n[p_true >= floor].max())) if (p_true >= floor).any() else float(n[-1])
    shown = n <= n_hi
    n, p_true, p_est = n[shown], p_true[shown], p_est[shown]
    fig, ax = _figure(f"{name}: road PSD after the warm-up, estimate vs true ({d[-1] - d[0]:.0f} m)", 1, zoom=False,
                      heights=[2.2])
    fig.set_size_inches(8, 6)
    a = ax[0, 0]
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
    return _save(fig, path, xlabel="spatial frequency n (cycle/m)")


def plot_iri(rows: list[tuple[float, float, float, float]], path: Path, name: str) -> Path:
    """Bars of the true and estimated IRI per segment (rows of ``metrics.iri_segments``)."""
    d = np.array([r[0] for r in rows])
    x = np.arange(len(rows))
    fig, ax = _figure(f"{name}: IRI per segment, true vs estimated", 2, zoom=False)
    a1, a2 = ax[0, 0], ax[1, 0]
    a1.bar(x - 0.2, [r[1] for r in rows], 0.4, label="true (ISORoad.iri)")
    a1.bar(x + 0.2, [r[2] for r in rows], 0.4, label="estimated (iri_est)")
    a1.set_ylabel("IRI (m/km)")
    a2.bar(x, [r[3] for r in rows], 0.6, color="C3", label="error")
    a2.axhline(3, color="k", lw=0.6, ls="--")
    a2.axhline(-3, color="k", lw=0.6, ls="--")
    a2.set_ylabel("error (%)")
    a2.set_xticks(x, [f"{v:.0f}" for v in d])
    return _save(fig, path, "segment reported at distance (m)")
