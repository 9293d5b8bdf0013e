"""harness/plots.py on a short co-simulation through the built FMUs: every plot is written and
shows something (not a blank or single-colour image)."""
from __future__ import annotations

import numpy as np
import pytest

from harness.runner import run_scenario
from harness.scenario import load_scenario

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


def test_every_plot_is_written_and_not_blank(dist, tmp_path):
    from matplotlib.image import imread

    from harness.plots import plot_result

    if not (dist / "SuspensionEstimator.fmu").is_file():
        pytest.skip("SuspensionEstimator.fmu is not part of this build")
    f = tmp_path / "p.toml"
    f.write_text(SCENARIO)
    run = run_scenario(load_scenario(f), dist=dist)
    files = plot_result(run.result, tmp_path / "out", "p")
    names = {p.name for p in files}
    assert names == {f"p_{k}.png" for k in ("road", "accelerations", "deflection", "road_estimate", "sprung_mass",
                                            "road_psd", "iri")}
    for png in files:
        img = imread(png)[..., :3]
        ink = np.any(img < 0.9, axis=-1)  # anything darker than near-white: axes, text, traces
        colours = {tuple(c) for c in (img[::4, ::4] * 255).astype(np.uint8).reshape(-1, 3)}
        assert ink.mean() > 0.03, f"{png.name} is almost blank ({100 * ink.mean():.1f} % ink)"
        assert len(colours) > 50, f"{png.name} has {len(colours)} colours"
        # the traces: matplotlib's first colours, blue (estimate, measured) or red (true)
        trace = [np.all(np.abs(img - np.array(c) / 255) < 0.12, axis=-1).mean() for c in ((31, 119, 180), (214, 39, 40))]
        assert max(trace) > 3e-4, f"{png.name} shows no trace ({trace})"
