"""PNG plots of a record (matplotlib, Agg backend): road, accelerations, deflection and, with the
estimator, road estimate vs true road and sprung-mass estimate vs true."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _figure(title: str, rows: int = 1):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(rows, 1, figsize=(10, 2.8 * rows + 0.6), sharex=True, squeeze=False)
    fig.suptitle(title)
    return fig, axes[:, 0]


def _save(fig, path: Path, xlabel: str = "time (s)") -> Path:
    import matplotlib.pyplot as plt

    fig.axes[-1].set_xlabel(xlabel)
    for ax in fig.axes:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_result(result: np.ndarray, out: Path, name: str) -> list[Path]:
    """Write ``<name>_road.png``, ``_accelerations.png``, ``_deflection.png`` and, with estimator
    columns, ``_road_estimate.png`` and ``_sprung_mass.png`` into ``out``. Returns the files."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cols = set(result.dtype.names)
    t = result["time"]
    files = []

    def has(*names):
        return all(n in cols for n in names)

    if has("ISORoad.road_height"):
        fig, (ax,) = _figure(f"{name}: road under the tyre")
        ax.plot(t, 1e3 * result["ISORoad.road_height"], lw=0.7, label="road_height")
        ax.set_ylabel("height (mm)")
        files.append(_save(fig, out / f"{name}_road.png"))
    if has("QuarterCar.acc_sprung", "QuarterCar.acc_unsprung"):
        fig, (a1, a2) = _figure(f"{name}: accelerations", 2)
        a1.plot(t, result["QuarterCar.acc_sprung"], lw=0.5, label="measured")
        a2.plot(t, result["QuarterCar.acc_unsprung"], lw=0.5, label="measured")
        if has("QuarterCar.acc_sprung_true", "QuarterCar.acc_unsprung_true"):
            a1.plot(t, result["QuarterCar.acc_sprung_true"], lw=0.7, label="true")
            a2.plot(t, result["QuarterCar.acc_unsprung_true"], lw=0.7, label="true")
        a1.set_ylabel("sprung (m/s²)")
        a2.set_ylabel("unsprung (m/s²)")
        files.append(_save(fig, out / f"{name}_accelerations.png"))
    if has("QuarterCar.susp_deflection"):
        fig, (ax,) = _figure(f"{name}: suspension deflection")
        ax.plot(t, 1e3 * result["QuarterCar.susp_deflection"], lw=0.5, label="measured")
        if has("QuarterCar.z_s", "QuarterCar.z_u"):
            ax.plot(t, 1e3 * (result["QuarterCar.z_s"] - result["QuarterCar.z_u"]), lw=0.7, label="true")
        if has("SuspensionEstimator.susp_deflection_est"):
            ax.plot(t, 1e3 * result["SuspensionEstimator.susp_deflection_est"], lw=0.7, ls="--", label="estimate")
        ax.set_ylabel("z_s - z_u (mm)")
        files.append(_save(fig, out / f"{name}_deflection.png"))
    if has("SuspensionEstimator.road_height_est", "ISORoad.road_height"):
        fig, (a1, a2) = _figure(f"{name}: road estimate vs true road", 2)
        est, true = result["SuspensionEstimator.road_height_est"], result["ISORoad.road_height"]
        a1.plot(t, 1e3 * true, lw=0.8, label="true")
        a1.plot(t, 1e3 * est, lw=0.8, ls="--", label="estimate")
        if has("SuspensionEstimator.road_height_std"):
            s = result["SuspensionEstimator.road_height_std"]
            a1.fill_between(t, 1e3 * (est - 2 * s), 1e3 * (est + 2 * s), alpha=0.2, label="±2σ")
        a1.set_ylabel("height (mm)")
        a2.plot(t, 1e3 * (est - true), lw=0.6, label="estimate - true")
        a2.set_ylabel("error (mm)")
        files.append(_save(fig, out / f"{name}_road_estimate.png"))
    if has("SuspensionEstimator.sprung_mass_est", "QuarterCar.sprung_mass"):
        fig, (ax,) = _figure(f"{name}: sprung mass estimate vs true")
        ax.plot(t, result["QuarterCar.sprung_mass"], lw=1.0, label="true")
        ax.plot(t, result["SuspensionEstimator.sprung_mass_est"], lw=0.8, ls="--", label="estimate")
        ax.set_ylabel("sprung mass (kg)")
        files.append(_save(fig, out / f"{name}_sprung_mass.png"))
    if has("SuspensionEstimator.iri_est", "ISORoad.iri", "ISORoad.distance"):
        from .metrics import iri_segments

        rows = iri_segments(result["ISORoad.distance"], result["ISORoad.iri"], result["SuspensionEstimator.iri_est"])
        if rows:
            files.append(plot_iri(rows, out / f"{name}_iri.png", name))
    return files


def plot_iri(rows: list[tuple[float, float, float, float]], path: Path, name: str) -> Path:
    """Bars of the true and estimated IRI per segment (rows of ``metrics.iri_segments``)."""
    d = np.array([r[0] for r in rows])
    x = np.arange(len(rows))
    fig, (a1, a2) = _figure(f"{name}: IRI per segment, true vs estimated", 2)
    a1.bar(x - 0.2, [r[1] for r in rows], 0.4, label="true (ISORoad.iri)")
    a1.bar(x + 0.2, [r[2] for r in rows], 0.4, label="estimated (iri_est)")
    a1.set_ylabel("IRI (m/km)")
    a2.bar(x, [r[3] for r in rows], 0.6, color="C3", label="error")
    a2.axhline(3, color="k", lw=0.6, ls="--")
    a2.axhline(-3, color="k", lw=0.6, ls="--")
    a2.set_ylabel("error (%)")
    a2.set_xticks(x, [f"{v:.0f}" for v in d])
    return _save(fig, path, "segment reported at distance (m)")
