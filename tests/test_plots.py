"""harness/plots.py: the figures of a synthetic record (fast, no FMUs) say what they should: units on
the axes, the road against distance, the scores of harness/metrics.py written on them, error axes
that hold the data, IRI values on the bars, the mass window on its convergence; and on a short
co-simulation through the built FMUs every plot is written, shows something and carries the
numbers the run's summary prints."""
from __future__ import annotations

import re

import numpy as np
import pytest

from suspension_estimation.harness import metrics, plots

SCENARIO = """\
duration = 4.0
step = 0.001
[road]
road_class = "C"
seed = 3
iri_segment = 10.0
[estimator]
iri_segment = 10.0
[speed]
value = 15.0
[sprung_mass]
time = [0.0, 3.0]
value = [410.0, 480.0]
"""
EST = "SuspensionEstimator."
UNIT = re.compile(r"\(.+\)")


def record(duration: float = 12.0, h: float = 2e-3, outlier: bool = False) -> np.ndarray:
    """A record with the columns of a run with the estimator: a road of a few sines over distance
    at 10 m/s, an estimate of what it estimates (its profile, ``metrics.reference_profile``) with
    1 mm of noise and its reported std, noisy
    accelerations and deflection, a mass estimate converging in about 0.1 s, IRI every 40 m."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, duration + h / 2, h)
    n = t.size
    d = 10.0 * t
    z = 0.01 * np.sin(2 * np.pi * d / 23.0) + 0.004 * np.sin(2 * np.pi * d / 3.1) + 0.002 * np.sin(2 * np.pi * d / 0.9)
    est = metrics.reference_profile(d, z) + 1e-3 * rng.standard_normal(n)
    if outlier:
        est[n // 2: n // 2 + 3] += 0.5  # three samples 0.5 m off
    a_s, a_u = np.sin(2 * np.pi * 1.3 * t), 8 * np.sin(2 * np.pi * 11 * t)
    defl = 0.01 * np.sin(2 * np.pi * 1.3 * t + 0.4)
    iri_true = np.select([d >= 120, d >= 80, d >= 40], [8.15, 8.32, 8.37], 0.0)
    cols = {
        "time": t, "ISORoad.road_height": z, "ISORoad.distance": d, "ISORoad.iri": iri_true,
        "QuarterCar.sprung_mass": np.full(n, 410.0),
        "QuarterCar.acc_sprung": a_s + 0.02 * rng.standard_normal(n), "QuarterCar.acc_sprung_true": a_s,
        "QuarterCar.acc_unsprung": a_u + 0.2 * rng.standard_normal(n), "QuarterCar.acc_unsprung_true": a_u,
        "QuarterCar.susp_deflection": defl + 1e-4 * rng.standard_normal(n),
        "QuarterCar.z_s": defl, "QuarterCar.z_u": np.zeros(n),
        EST + "road_height_est": est, EST + "road_height_std": np.full(n, 1e-3),
        EST + "sprung_mass_est": 410.0 - 40.0 * np.exp(-t / 0.025) + 0.3 * rng.standard_normal(n),
        EST + "susp_deflection_est": defl + 5e-5 * rng.standard_normal(n),
        EST + "iri_est": 0.99 * iri_true,
    }
    out = np.empty(n, dtype=[(k, float) for k in cols])
    for k, v in cols.items():
        out[k] = v
    return out


@pytest.fixture(scope="module")
def rec() -> np.ndarray:
    return record()


@pytest.fixture(scope="module")
def figs(rec):
    return plots.figures(rec, "s")


def texts(fig) -> str:
    from matplotlib.text import Text

    return "\n".join(t.get_text() for t in fig.findobj(Text))


def panel(fig, ylabel: str):
    """The full-run axes of ``fig`` labelled ``ylabel``."""
    (ax,) = [a for a in fig.axes if a.get_ylabel() == ylabel]
    return ax


def test_every_figure_is_made_and_every_axis_has_its_unit(figs):
    assert set(figs) == {"road", "accelerations", "deflection", "road_estimate", "sprung_mass", "road_psd", "iri"}
    for key, fig in figs.items():
        for ax in fig.axes:
            spec = ax.get_subplotspec()
            labels = [ax.get_xlabel(), ax.get_ylabel()]
            assert all(UNIT.search(s) for s in labels if s), (key, labels)
            if spec.is_last_row():
                assert ax.get_xlabel(), f"{key}: an axis of the bottom row has no x label"
            if spec.is_first_col():
                assert ax.get_ylabel(), f"{key}: an axis of the first column has no y label"


def test_the_road_is_plotted_against_distance_the_vehicle_against_time(figs):
    for key in ("road", "road_estimate", "iri"):
        bottom = [a.get_xlabel() for a in figs[key].axes if a.get_subplotspec().is_last_row()]
        assert bottom and all(label.startswith("distance (m)") for label in bottom), (key, bottom)
    assert figs["road_psd"].axes[0].get_xlabel() == "spatial frequency n (cycle/m)"
    for key in ("accelerations", "sprung_mass"):
        assert "time (s)" in [a.get_xlabel() for a in figs[key].axes]


def test_the_road_scores_on_the_figure_are_those_of_road_scores(rec, figs):
    s = metrics.road_scores(rec["time"], rec[EST + "road_height_est"], rec["ISORoad.road_height"],
                            rec[EST + "road_height_std"], warmup=metrics.warmup_for(rec["time"]),
                            distance=rec["ISORoad.distance"])
    text = texts(figs["road_estimate"])
    hp = re.search(r"HP error std ([\d.]+) %", text)
    cov = re.search(r"within ±2σ ([\d.]+) %", text)
    assert hp and cov, text
    assert hp.group(1) == f"{s['err_std_hp_pct']:.1f}"
    assert cov.group(1) == f"{100 * s['coverage_2sigma']:.1f}"
    assert 80 < 100 * s["coverage_2sigma"] < 100  # the record is made so that the number means something


def test_the_error_axes_hold_the_data_symmetric_about_zero(rec, figs):
    """The raw error against the true profile (``metrics.reference_profile``) and the HP error,
    HP(estimate) - HP(true profile) as ``metrics.road_scores`` scores it."""
    fig = figs["road_estimate"]
    h = float(np.median(np.diff(rec["time"])))
    est = rec[EST + "road_height_est"]
    ref = metrics.reference_profile(rec["ISORoad.distance"], rec["ISORoad.road_height"])
    raw, hp = 1e3 * (est - ref), 1e3 * (metrics.highpass(est, h) - metrics.highpass(ref, h))
    for ylabel, expected in (("raw error (mm)", raw), ("HP error (mm)", hp)):
        ax = panel(fig, ylabel)
        (line,) = [ln for ln in ax.lines if len(ln.get_ydata()) > 2]
        y = np.asarray(line.get_ydata())
        np.testing.assert_allclose(y, expected, atol=1e-9)
        lo, hi = ax.get_ylim()
        assert lo == pytest.approx(-hi)
        assert lo <= y.min() and y.max() <= hi, (ylabel, (lo, hi), (y.min(), y.max()))
        assert "samples beyond" not in texts(fig)


def test_a_few_outliers_get_a_robust_limit_and_a_count(rec):
    fig = plots.road_estimate_figure(record(outlier=True), "s", warmup=6.0)
    ax = panel(fig, "raw error (mm)")
    lo, hi = ax.get_ylim()
    assert hi < 100  # not scaled by the 500 mm outliers
    raw = max((ln.get_ydata() for ln in ax.lines), key=len)
    note = re.search(r"(\d+) samples beyond ±([\d.]+) mm \(max \|error\| ([\d.]+) mm\)", texts(fig))
    assert note and int(note.group(1)) == np.count_nonzero(np.abs(raw) > hi) >= 3
    assert float(note.group(2)) == pytest.approx(hi, rel=1e-2) and float(note.group(3)) > 490


def test_iri_bars_carry_their_values_by_segment_in_metres(rec, figs):
    rows = metrics.iri_segments(rec["ISORoad.distance"], rec["ISORoad.iri"], rec[EST + "iri_est"])
    assert len(rows) == 3
    fig = figs["iri"]
    bar_texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    for _, true, est, err in rows:
        assert f"{true:.2f}" in bar_texts and f"{est:.2f}" in bar_texts and f"{err:+.1f} %" in bar_texts
    ticks = [t.get_text() for t in fig.axes[-1].get_xticklabels()]
    assert ticks == ["0", "40", "80", "120"]


def test_the_mass_window_is_on_its_convergence_and_the_shade_on_what_is_not_scored(rec, figs):
    t = rec["time"]
    t_a, t_b, final, t_in = plots.mass_convergence(t, rec[EST + "sprung_mass_est"], rec["QuarterCar.sprung_mass"])
    assert t_a == 0.0 and t_b == t[-1] and abs(final - 410.0) < 0.5 and 0.03 < t_in < 0.2
    fig = figs["sprung_mass"]
    (zoom,) = [a for a in fig.axes if a.get_title().startswith("from the start")]
    lo, hi = zoom.get_xlim()
    assert lo == 0.0 and t_in < hi <= 1.0
    # the grey shade ends where the summary's mass score (the last quarter) begins
    full = panel(fig, "sprung mass (kg)")
    handles, labels = full.get_legend_handles_labels()
    shade = handles[labels.index("not in the mass score (summary: last quarter)")]
    x = shade.get_patch_transform().transform(shade.get_path().vertices)[:, 0]
    assert x.max() == pytest.approx(0.75 * t[-1])
    score = np.mean(np.abs(metrics.mass_error_pct(rec[EST + "sprung_mass_est"], 410.0)[t >= 0.75 * t[-1]]))
    assert f"mean |error| over the last quarter (9-12 s): {score:.2f} %" in texts(fig)


def test_a_record_without_the_estimator(rec):
    keep = [n for n in rec.dtype.names if not n.startswith(EST)]
    figs = plots.figures(rec[keep], "s")
    assert set(figs) == {"road", "accelerations", "deflection"}


def test_every_plot_is_written_and_carries_the_summarys_numbers(dist, tmp_path):
    """Through the FMUs: the files, not blank, and the numbers the run's summary prints."""
    from matplotlib.image import imread

    from suspension_estimation.harness.runner import run_scenario, summary
    from suspension_estimation.harness.scenario import load_scenario

    if not (dist / "SuspensionEstimator.fmu").is_file():
        pytest.skip("SuspensionEstimator.fmu is not part of this build")
    f = tmp_path / "p.toml"
    f.write_text(SCENARIO)
    run = run_scenario(load_scenario(f), dist=dist)
    files = plots.plot_result(run.result, tmp_path / "out", "p")
    names = {p.name for p in files}
    assert names == {f"p_{k}.png" for k in ("road", "accelerations", "deflection", "road_estimate", "sprung_mass",
                                            "road_psd", "iri")}
    for png in files:
        img = imread(png)[..., :3]
        ink = np.any(img < 0.9, axis=-1)  # anything darker than near-white: axes, text, traces
        assert ink.mean() > 0.03, f"{png.name} is almost blank ({100 * ink.mean():.1f} % ink)"
        # the traces: matplotlib's first colours, blue (estimate, measured) or red (true)
        trace = [np.all(np.abs(img - np.array(c) / 255) < 0.12, axis=-1).mean()
                 for c in ((31, 119, 180), (214, 39, 40))]
        assert max(trace) > 3e-4, f"{png.name} shows no trace ({trace})"
    lines = "\n".join(summary(run))
    figs = plots.figures(run.result, "p")
    hp = re.search(r"high-passed at 0.5 Hz \(error std ([\d.]+) %\)", lines).group(1)
    assert f"HP error std {hp} %" in texts(figs["road_estimate"])
    mass = re.search(r"mean \|error\| over the last quarter ([\d.]+) %", lines).group(1)
    assert re.search(rf"mean \|error\| over the last quarter \([\d.-]+ s\): {mass} %", texts(figs["sprung_mass"]))
    for seg in re.findall(r"(\d+) m ([\d.]+) / ([\d.]+) / ([+-][\d.]+) %", lines):
        assert {seg[1], seg[2], f"{seg[3]} %"} <= {t.get_text() for ax in figs["iri"].axes for t in ax.texts}
