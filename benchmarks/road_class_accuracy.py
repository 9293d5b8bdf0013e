"""Accuracy of the response-feature road classifier on independent test roads, as confusion matrices.

    .venv/bin/python benchmarks/road_class_accuracy.py [--runs N] [--duration S] [--seed S]

Our quarter car: the shipped model (estimators/data/response_class_iso.json) on ``--runs`` runs
(classes A-E in turn, ``--duration`` s each after 1 s of settling, speed uniform 10-30 m/s) on
road seeds the training never saw (201, 202) with a test seed of their own, in four cases:

1. roughness at the class value, vehicles drawn over the whole spread (c_s +-30 %, k_s +-15 %,
   k_t +-10 %, m_u +-15 %, m_s 230-590 kg);
2. the same roads and vehicles, roughness log-uniform over the class band (factor 2 either side):
   the whole band, within a factor sqrt(2) of the class value, and outside a margin of
   ``EDGE_MARGIN`` octave inside the band edges; the ceiling of a classifier that knows the actual
   road over each block (``oracle_classes``); info: the same model on 3x longer blocks;
3. roughness at the class value, the nominal vehicle only;
4. roughness at the class value, the extreme vehicles only (every parameter at one end of its
   range: the 32 corners, in turn).

Paper 004's scenario: the block-by-block accuracy of ``harness.studies.vb.paper_classifier`` on
its E / C / A scenario (other seed), every block and without the first block after a switch.

Rows are the true class, columns the predicted one. Exits non-zero with a one-line reason on bad
arguments.
"""
from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from suspension_estimation.estimators import response_class_train as T  # noqa: E402
from suspension_estimation.estimators.response_class import block_features, load_model, predict  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

TEST_ROAD_SEEDS = (201, 202)
EDGE_MARGIN = 0.25  # octave of Gd(n0) inside each band edge left out of the "outside the margin" figure
ORACLE_BAND = (0.5, 25.0)  # Hz of the road velocity the ceiling looks at


def oracle_classes(runs, samples: int) -> np.ndarray:
    """(runs, blocks) class of each block from the actual road (``runs.zr``): ln of the mean square
    of the road velocity band-passed to ``ORACLE_BAND`` over the block, over the speed (white
    road velocity of PSD ~ Gd(n0) V), shifted by the median offset to ln Gd(n0) over the runs,
    rounded to the nearest class on the ISO grid (a factor 4 a class)."""
    from scipy.signal import butter, lfilter

    vr = np.diff(runs.zr, axis=1, prepend=runs.zr[:, :1]) / T.H
    b, a = butter(2, ORACLE_BAND, btype="band", fs=1.0 / T.H)
    y = lfilter(b, a, vr, axis=1)
    nb = y.shape[1] // samples
    g = np.log(np.mean(y[:, :nb * samples].reshape(len(y), nb, samples) ** 2, axis=2) / runs.speed[:, None])
    g -= np.median(g - np.log(runs.gd)[:, None])
    c = np.round(np.log(np.exp(g) / iso8608.GD_N0_A) / np.log(4.0)) + 1
    return np.clip(c, 1, 5).astype(int)


def confusion(truth: np.ndarray, pred: np.ndarray, classes) -> str:
    names = [iso8608.class_name(c) for c in classes]
    lines = ["| true \\ predicted | " + " | ".join(names) + " | accuracy |", "|---" * (len(names) + 2) + "|"]
    for c, name in zip(classes, names):
        if not np.any(truth == c):
            continue
        row = [int(np.sum((truth == c) & (pred == d))) for d in classes]
        lines.append(f"| {name} | " + " | ".join(map(str, row)) + f" | {row[classes.index(c)] / max(sum(row), 1):.1%} |")
    return "\n".join(lines)


def _corners():
    lo_hi = {k: (getattr(DEFAULT_VEHICLE, k) * a, getattr(DEFAULT_VEHICLE, k) * b)
             for k, (a, b) in T.VEHICLE_SPREAD.items() if k != "m_s_kg"}
    lo_hi["m_s"] = T.VEHICLE_SPREAD["m_s_kg"]
    names = list(lo_hi)
    return [DEFAULT_VEHICLE.with_(**{n: lo_hi[n][e] for n, e in zip(names, ends)})
            for ends in itertools.product((0, 1), repeat=len(names))]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200, help="test runs per case (default 200)")
    ap.add_argument("--duration", type=float, default=8.0, help="s per run after settling (default 8)")
    ap.add_argument("--seed", type=int, default=99, help="seed of the test draws (default 99)")
    a = ap.parse_args(argv)
    if a.runs < 5 or not 0 < a.duration <= 12:
        print("road_class_accuracy: need --runs >= 5 and 0 < --duration <= 12 s", file=sys.stderr)
        return 2
    model = load_model()
    classes = list(model["classes"])
    blocks = int(round(model["window"] / T.H))
    print(f"## Our quarter car: shipped model, blocks of {model['window']:g} s, {a.runs} runs of "
          f"{a.duration:g} s per case, road seeds {TEST_ROAD_SEEDS}, test seed {a.seed}\n")
    corners = _corners()
    cases = {
        "1. class values, vehicles over the spread": dict(spread=False),
        "2. roughness over the class band, vehicles over the spread": dict(spread=True),
        "3. class values, nominal vehicle": dict(spread=False, vehicles=lambda i: DEFAULT_VEHICLE),
        "4. class values, the 32 extreme vehicles": dict(spread=False, vehicles=lambda i: corners[i % 32]),
    }
    for title, kw in cases.items():
        runs = T.simulate(a.runs, a.duration, a.seed, road_seeds=TEST_ROAD_SEEDS, **kw)
        f = block_features(runs.Y, runs.speed[:, None], blocks)
        pred = predict(model, f).ravel()
        truth = np.repeat(runs.classes, f.shape[1])
        v = np.repeat(runs.speed, f.shape[1])
        by_speed = " / ".join(f"{np.mean(pred[m] == truth[m]):.1%}" for m in
                              (v < 50 / 3, (v >= 50 / 3) & (v < 70 / 3), v >= 70 / 3))
        print(f"### {title}: {np.mean(pred == truth):.1%} of {len(truth)} blocks "
              f"(10-16.7 / 16.7-23.3 / 23.3-30 m/s: {by_speed})\n")
        if kw["spread"]:
            off = np.repeat(np.abs(np.log2(runs.gd / [iso8608.class_psd_n0(c) for c in runs.classes])),
                            f.shape[1])
            print(f"Within a factor sqrt(2) of the class value: {np.mean(pred[off < 0.5] == truth[off < 0.5]):.1%} "
                  f"of {np.sum(off < 0.5)} blocks; farther out: {np.mean(pred[off >= 0.5] == truth[off >= 0.5]):.1%} "
                  f"of {np.sum(off >= 0.5)} blocks\n")
            inner = off < 1.0 - EDGE_MARGIN
            print(f"Excluding a margin of {EDGE_MARGIN:g} octave (a factor {2 ** EDGE_MARGIN:.3f}) inside each band "
                  f"edge: {np.mean(pred[inner] == truth[inner]):.1%} of {np.sum(inner)} blocks\n")
            oracle = oracle_classes(runs, blocks).ravel()
            print(f"Ceiling: a classifier that knows the actual road under the tyre over each block (its mean square "
                  f"road velocity in {ORACLE_BAND[0]:g}-{ORACLE_BAND[1]:g} Hz, calibrated on these roads, nearest class "
                  f"on the ISO grid) gets {np.mean(oracle == truth):.1%} of the whole band, "
                  f"{np.mean(oracle[inner] == truth[inner]):.1%} outside the margin: a road near a band edge is "
                  "ambiguous over one block, whatever sees it\n")
            for k in (3,):
                fk = block_features(runs.Y, runs.speed[:, None], k * blocks)
                pk = predict(model, fk).ravel()
                tk = np.repeat(runs.classes, fk.shape[1])
                ok = np.repeat(np.abs(np.log2(runs.gd / [iso8608.class_psd_n0(c) for c in runs.classes])),
                               fk.shape[1]) < 1.0 - EDGE_MARGIN
                print(f"Info, the same model on blocks of {k * model['window']:g} s (a longer window, {k}x the latency): "
                      f"{np.mean(pk == tk):.1%} of {len(tk)} blocks, {np.mean(pk[ok] == tk[ok]):.1%} outside the margin\n")
        print(confusion(truth, pred, classes) + "\n")

    from suspension_estimation.harness.studies import vb as V

    pm = V.paper_classifier()
    F, B, H = V.paper_model()
    scn = V.paper_scenario()
    _, Y = V.simulate(scn, F, B, H, a.runs, np.random.default_rng(a.seed))
    pred = predict(pm, block_features(Y[:, 1:], 1.0, V.CLASS_BLOCK, speed_power=0.0))
    first = 1 + V.CLASS_BLOCK * np.arange(pred.shape[1])
    truth = np.array([iso8608.CLASSES.index(scn.classes[k]) + 1 for k in first])
    after_switch = np.isin(first, scn.starts[1:])
    t, p = np.broadcast_to(truth, pred.shape), pred
    print(f"## Paper 004's scenario (E / C / A): in-loop classifier, blocks of "
          f"{V.CLASS_BLOCK * V.TS:g} s, {a.runs} runs (seed {a.seed})\n")
    print(f"All blocks: {np.mean(p == t):.1%}; without the first block after a switch: "
          f"{np.mean(p[:, ~after_switch] == t[:, ~after_switch]):.1%}; the first block after a "
          f"switch: {np.mean(p[:, after_switch] == t[:, after_switch]):.1%}\n")
    print(confusion(t[:, ~after_switch].ravel(), p[:, ~after_switch].ravel(), list(pm["classes"])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
