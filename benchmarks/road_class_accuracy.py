"""Accuracy of the response-feature road classifier on independent test roads, as confusion matrices.

    .venv/bin/python benchmarks/road_class_accuracy.py [--runs N] [--duration S] [--seed S] [--windows]
    .venv/bin/python benchmarks/road_class_accuracy.py --pool 1,2,3,4,5,6,95,96,97,98,99

Our quarter car: the shipped model (estimators/data/response_class_iso.json), in the loop as
``ResponseClassifier`` runs it (``response_class.classify``: a decision every 2 s block on the
pooled window of the last blocks, with its hysteresis), on ``--runs`` runs (classes A-E in turn,
``--duration`` s each after 1 s of settling, speed uniform 10-30 m/s) on road seeds the training
never saw (201, 202) with a test seed of their own. Scored: every decision once the window is
full. Cases:

1. roughness at the class value, vehicles drawn over the whole spread (c_s +-30 %, k_s +-15 %,
   k_t +-10 %, m_u +-15 %, m_s 230-590 kg);
2. the same roads and vehicles, roughness log-uniform over the class band (factor 2 either side):
   the whole band, within a factor sqrt(2) of the class value, and outside a margin of
   ``EDGE_MARGIN`` octave inside the band edges; the ceiling of a classifier that knows the actual
   road over the same window (``oracle_classes``); class changes per run on these constant roads;
3. roughness over the class band, the nominal vehicle only;
4. roughness at the class value, the extreme vehicles only (every parameter at one end of its
   range: the 32 corners, in turn);
5. a change of road: roughness at the class value, the road one class rougher or smoother from
   the moment the window is full (``latency_table``): how long until the new class is in force.

``--windows``: for cases 2 and 3, the oracle and a model trained as the shipped one
(``response_class_train``, its seeds) for windows of 1, 2, 4 and 6 blocks of 2 s, without
hysteresis, and the measured signals alone (the three raw features) for comparison: what limits
the accuracy, the road's own scatter over a window or the vehicle.

Paper 004's scenario: the block-by-block accuracy of ``harness.studies.vb.paper_classifier`` on
its E / C / A scenario (other seed), every block and without the first block after a switch.

``--pool``: case 2 alone on each of the given test seeds, and pooled.

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
from suspension_estimation.estimators.response_class import block_features, classify, load_model, predict  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

TEST_ROAD_SEEDS = (201, 202)
EDGE_MARGIN = 0.25  # octave of Gd(n0) inside each band edge left out of the "outside the margin" figure
ORACLE_BAND = (0.5, 25.0)  # Hz of the road velocity the ceiling looks at


def pooled(sq: np.ndarray, k: int) -> np.ndarray:
    """Means over the last k blocks (fewer at the start) of per-block values sq (runs, blocks)."""
    c = np.concatenate([np.zeros((len(sq), 1)), np.cumsum(sq, axis=1)], axis=1)
    end = np.arange(1, sq.shape[1] + 1)
    start = np.maximum(end - k, 0)
    return (c[:, end] - c[:, start]) / (end - start)


def oracle_classes(runs, samples: int, k: int = 1) -> np.ndarray:
    """(runs, blocks) class at the end of each block from the actual road (``runs.zr``) over the
    last k blocks of ``samples``: ln of the mean square of the road velocity band-passed to
    ``ORACLE_BAND``, over the speed (white road velocity of PSD ~ Gd(n0) V), shifted by the median
    offset to ln Gd(n0) over the runs, rounded to the nearest class on the ISO grid (a factor 4 a
    class)."""
    from scipy.signal import butter, lfilter

    vr = np.diff(runs.zr, axis=1, prepend=runs.zr[:, :1]) / T.H
    b, a = butter(2, ORACLE_BAND, btype="band", fs=1.0 / T.H)
    y = lfilter(b, a, vr, axis=1)
    nb = y.shape[1] // samples
    ms = pooled(np.mean(y[:, :nb * samples].reshape(len(y), nb, samples) ** 2, axis=2), k)
    g = np.log(ms / runs.speed[:, None])
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


def _offset(runs) -> np.ndarray:
    """|log2(Gd(n0) / class value)| of every run (octaves; the band edges are at 1)."""
    return np.abs(np.log2(runs.gd / [iso8608.class_psd_n0(c) for c in runs.classes]))


def window_table(tests: dict, training) -> str:
    """Markdown table: accuracy per window length of the oracle, a model of the shipped features
    and training, and one of the three measured signals alone, on the test runs of ``tests``."""
    lines = ["| window | " + " | ".join(f"{t}: oracle | {t}: 18 features | {t}: 3 signals" for t in tests) + " |",
             "|---" * (1 + 3 * len(tests)) + "|"]
    raw = tuple((i, None, None) for i in range(3))
    samples = int(round(T.WINDOW / T.H))
    for k in (1, 2, 4, 6):
        row = [f"{k * T.WINDOW:g} s"]
        models = []
        for feats in (T.FEATURES, raw):
            s = T.spec(features=feats, blocks=k)
            f, _, ln_gd = T.features_of(training, s)
            models.append(T.train_ordinal(f, ln_gd, s, hysteresis=0.0))
        for runs in tests.values():
            truth = runs.classes[:, None]
            row.append(f"{np.mean(oracle_classes(runs, samples, k)[:, k - 1:] == truth):.1%}")
            for m in models:
                row.append(f"{np.mean(classify(m, runs.Y, runs.speed[:, None], T.H)[:, k - 1:] == truth):.1%}")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def after_change(i: int) -> int:
    """Class after the change of run i (classes A-E in turn): one class rougher on the first five
    runs of every ten, one smoother on the others (A always rougher, E always smoother)."""
    c = T.CLASSES[i % len(T.CLASSES)]
    up = (i // len(T.CLASSES)) % 2 == 0
    return c + 1 if (up and c < T.CLASSES[-1]) or c == T.CLASSES[0] else c - 1


def latency_table(model: dict, n_runs: int, duration: float, seed: int) -> str:
    """Case 5: roughness at the class value, vehicles over the spread, the road one class rougher
    or smoother from half the run on (``after_change``). Latency: from the change to the end of
    the first block from which the class in force is the new one to the end of the run."""
    k = int(model["blocks"])
    t_change = k * float(model["window"])
    if duration < t_change + 2 * float(model["window"]):
        return f"### 5. a change of road: needs --duration >= {t_change + 2 * float(model['window']):g} s"
    runs = T.simulate(n_runs, duration, seed + 1000, road_seeds=TEST_ROAD_SEEDS, spread=False,
                      change=(t_change, after_change))
    cls = classify(model, runs.Y, runs.speed[:, None], T.H)
    ends = float(model["window"]) * np.arange(1, cls.shape[1] + 1)
    new = np.array([after_change(i) for i in range(n_runs)])
    late = ends > t_change + 1e-9
    ok = cls == new[:, None]
    held = np.flip(np.cumprod(np.flip(ok & late, axis=1), axis=1), axis=1).astype(bool)  # new class to the end
    found = held.any(axis=1)
    lat = np.where(found, ends[np.argmax(held, axis=1)] - t_change, np.inf)
    lines = [f"### 5. a change of road after {t_change:g} s (class values, vehicles over the spread, one class "
             f"up or down, {n_runs} runs, seed {seed + 1000}): the class is right {np.mean(found):.1%} of runs by "
             f"the end ({duration - t_change:g} s after)\n",
             "| change | runs | median latency s | 90 % of runs within s | longest s | not found by the end |",
             "|---|---|---|---|---|---|"]
    for up in (True, False):
        m = (new > runs.classes) == up
        lm = lat[m]
        q = np.sort(lm)[int(np.ceil(0.9 * len(lm))) - 1]  # 90 % of runs within q (inf: not found)
        lines.append(f"| one class {'rougher' if up else 'smoother'} | {m.sum()} | {np.median(lm):g} | "
                     f"{q:g} | {np.max(lm):g} | {np.mean(~np.isfinite(lm)):.1%} |")
    before = ok[:, ~late]
    lines.append(f"\nBefore the change, wrong decisions naming the class to come: {np.mean(before):.1%}")
    return "\n".join(lines)


def pooled_band_table(model: dict, seeds: list[int], n_runs: int, duration: float) -> str:
    """Case 2 (roughness over the class band, vehicles over the spread) on every test seed of
    ``seeds``: the accuracy and the ceiling per seed, and the confusion matrix of all of them."""
    k = int(model["blocks"])
    samples = int(round(model["window"] / T.H))
    truth_all, pred_all, acc = [], [], []
    lines = ["| test seed | accuracy | ceiling (road known) |", "|---|---|---|"]
    for seed in seeds:
        runs = T.simulate(n_runs, duration, seed, road_seeds=TEST_ROAD_SEEDS, spread=True)
        cls = classify(model, runs.Y, runs.speed[:, None], T.H)[:, k - 1:]
        truth = np.repeat(runs.classes, cls.shape[1])
        oracle = oracle_classes(runs, samples, k)[:, k - 1:].ravel()
        acc.append(100 * np.mean(cls.ravel() == truth))
        lines.append(f"| {seed} | {acc[-1]:.1f}% | {np.mean(oracle == truth):.1%} |")
        truth_all.append(truth)
        pred_all.append(cls.ravel())
    t, p = np.concatenate(truth_all), np.concatenate(pred_all)
    head = (f"### Case 2 over {len(seeds)} test seeds ({n_runs} runs of {duration:g} s each): {np.mean(p == t):.1%} "
            f"of {len(t)} decisions (per seed {min(acc):.1f}-{max(acc):.1f} %)\n")
    return head + "\n".join(lines) + "\n\n" + confusion(t, p, list(model["classes"]))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=400, help="test runs per case (default 400)")
    ap.add_argument("--duration", type=float, default=24.0, help="s per run after settling (default 24)")
    ap.add_argument("--seed", type=int, default=99, help="seed of the test draws (default 99)")
    ap.add_argument("--windows", action="store_true", help="also train and compare windows of 2-12 s (~5 min)")
    ap.add_argument("--pool", default="", metavar="S1,S2,...",
                    help="only case 2, on each of these test seeds and pooled (about 10 s a seed)")
    a = ap.parse_args(argv)
    model = load_model()
    k = int(model["blocks"])
    least = k * model["window"]
    if a.runs < 5 or not least <= a.duration <= 25:
        print(f"road_class_accuracy: need --runs >= 5 and {least:g} <= --duration <= 25 s", file=sys.stderr)
        return 2
    if a.pool:
        try:
            seeds = [int(x) for x in a.pool.split(",")]
        except ValueError:
            print(f"road_class_accuracy: --pool needs comma-separated integers, not {a.pool!r}", file=sys.stderr)
            return 2
        print(pooled_band_table(model, seeds, a.runs, a.duration))
        return 0
    classes = list(model["classes"])
    samples = int(round(model["window"] / T.H))
    print(f"## Our quarter car: shipped model, a decision every {model['window']:g} s on the last "
          f"{least:g} s, hysteresis {model['hysteresis']:g} in ln Gd(n0); {a.runs} runs of {a.duration:g} s "
          f"per case, road seeds {TEST_ROAD_SEEDS}, test seed {a.seed}\n")
    corners = _corners()
    cases = {
        "1. class values, vehicles over the spread": dict(spread=False),
        "2. roughness over the class band, vehicles over the spread": dict(spread=True),
        "3. roughness over the class band, nominal vehicle": dict(spread=True, vehicles=lambda i: DEFAULT_VEHICLE),
        "4. class values, the 32 extreme vehicles": dict(spread=False, vehicles=lambda i: corners[i % 32]),
    }
    band_runs = {}
    for title, kw in cases.items():
        runs = T.simulate(a.runs, a.duration, a.seed, road_seeds=TEST_ROAD_SEEDS, **kw)
        cls = classify(model, runs.Y, runs.speed[:, None], T.H)[:, k - 1:]
        pred = cls.ravel()
        truth = np.repeat(runs.classes, cls.shape[1])
        v = np.repeat(runs.speed, cls.shape[1])
        by_speed = " / ".join(f"{np.mean(pred[m] == truth[m]):.1%}" for m in
                              (v < 50 / 3, (v >= 50 / 3) & (v < 70 / 3), v >= 70 / 3))
        print(f"### {title}: {np.mean(pred == truth):.1%} of {len(truth)} decisions "
              f"(10-16.7 / 16.7-23.3 / 23.3-30 m/s: {by_speed})\n")
        if kw["spread"]:
            band_runs["spread" if "vehicles" not in kw else "nominal"] = runs
            off = np.repeat(_offset(runs), cls.shape[1])
            print(f"Within a factor sqrt(2) of the class value: {np.mean(pred[off < 0.5] == truth[off < 0.5]):.1%} "
                  f"of {np.sum(off < 0.5)} decisions; farther out: {np.mean(pred[off >= 0.5] == truth[off >= 0.5]):.1%} "
                  f"of {np.sum(off >= 0.5)}\n")
            inner = off < 1.0 - EDGE_MARGIN
            print(f"Excluding a margin of {EDGE_MARGIN:g} octave (a factor {2 ** EDGE_MARGIN:.3f}) inside each band "
                  f"edge: {np.mean(pred[inner] == truth[inner]):.1%} of {np.sum(inner)} decisions\n")
            oracle = oracle_classes(runs, samples, k)[:, k - 1:].ravel()
            print(f"Ceiling: a classifier that knows the actual road under the tyre over the same {least:g} s (its "
                  f"mean square road velocity in {ORACLE_BAND[0]:g}-{ORACLE_BAND[1]:g} Hz, calibrated on these roads, "
                  f"nearest class on the ISO grid) gets {np.mean(oracle == truth):.1%} of the whole band, "
                  f"{np.mean(oracle[inner] == truth[inner]):.1%} outside the margin\n")
            flips = np.sum(np.diff(cls, axis=1) != 0, axis=1)
            print(f"Class changes on these constant roads after the window is full: {flips.mean():.2f} a run "
                  f"({cls.shape[1]} decisions), {np.mean(flips > 0):.1%} of runs change at all\n")
        print(confusion(truth, pred, classes) + "\n")
    print(latency_table(model, a.runs, a.duration, a.seed) + "\n")
    if a.windows:
        training = T.simulate(300, 24.0, T.TRAIN_SEED)
        print("### Window length, without hysteresis: oracle, the 18 features, the 3 measured signals alone "
              "(each model trained as the shipped one for its window)\n")
        print(window_table({"spread": band_runs["spread"], "nominal": band_runs["nominal"]}, training) + "\n")

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
