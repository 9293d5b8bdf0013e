"""The imm study (harness/studies/imm.py) on a shortened Fig. 6 scenario through the built FMUs:
its road profile is continuous and of the right ISO classes, its runs score every estimator per
segment, and its table and targets name them."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from suspension_estimation.harness.studies import imm, load
from suspension_estimation.harness.studies.runner import RunSpec
from suspension_estimation.plant import iso8608
from suspension_estimation.estimators.road_class import grade_index_from_profile


def test_profile_segments_are_continuous_and_of_their_class(tmp_path):
    p = tmp_path / "road.csv"
    imm.write_profile(p, seed=1, segment=20.0)
    s, z = np.loadtxt(p, delimiter=",").T
    assert np.all(np.diff(s) > 0)
    ends = np.cumsum([v * 20.0 for v in imm.SPEEDS])
    assert abs(s[-1] - ends[-1] - 1.0) < 1e-9
    dz = np.abs(np.diff(z))
    for e in ends[:-1]:  # no jump at a segment boundary beyond the road's own steps
        i = np.searchsorted(s, e)
        assert dz[i - 1] < 5 * np.percentile(dz, 99.9)
    start = 0.0
    for c, e in zip(imm.CLASSES, ends):
        seg = z[(s >= start) & (s < e)]
        d = grade_index_from_profile(seg, imm.PROFILE_DX, segment=2048, n_lo=0.05, n_hi=2.0)
        assert iso8608.class_from_grade_index(d) == c, (c, d)
        start = e


def test_a_short_run_scores_every_estimator(dist):
    spec = RunSpec("imm_off", 3, 1, 8.0, 0.0, 1e-3, str(dist))
    r = load("imm").runs["imm_off"](spec)
    est = r["estimators"]
    assert set(est) == {"IMM (2)", "moving IMM (4)", "default: robust KF + RLS", imm.TRUE_KF}
    for segs in est.values():
        assert len(segs) == 4 and all(np.isfinite(s["hp_pct"]) and s["hp_pct"] > 0 for s in segs)
    assert all(s["steady_pct"] == 0.0 for s in est[imm.TRUE_KF])  # told the true mass
    # 2 s segments: the moving bank is within 5 % by the end of each (targets: the full study)
    assert all(s["steady_pct"] < 5.0 for s in est["moving IMM (4)"][1:]), est["moving IMM (4)"]
    suite = SimpleNamespace(seeds=1, step=1e-3, ok=lambda kind: [r] if kind == "imm_off" else [])
    md = "\n".join(imm.IMM.markdown(suite))
    assert "off grid: 425 kg → 325 kg → 425 kg → 525 kg" in md and md.count("| moving IMM (4) |") == 4
    assert {t[0].split(",")[0] for t in imm.IMM.targets(suite)} == {"IMM (2)", "moving IMM (4)",
                                                                     "default: robust KF + RLS"}
