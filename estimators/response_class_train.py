"""Training data and training of the response-feature road classifier (``estimators.response_class``).

    python -m suspension_estimation.estimators.response_class_train [--out FILE]

writes the model of our quarter car (``response_class.ISO_MODEL``, package data); ``build.py``
runs the same function, and the same seeds give the same file byte for byte (numbers rounded to
10 significant digits so that the last bits of a BLAS do not show).

Training set (``simulate``): the plant of ``plant.quarter_car`` (exact ZOH, accelerations at the
end of the step, default ``SensorNoise``) at h = 5 ms on ISO 8608 roads of classes A-E
(``plant.road.SyntheticRoad``), one vehicle, speed and roughness per run:

- speed uniform in [10, 30] m/s;
- Gd(n0) log-uniform over the class band (a factor 2 either side of the class value), so the
  classifier meets roughness anywhere in its class, not only at the class centre;
- the vehicle drawn uniformly around ``DEFAULT_VEHICLE`` within the ranges of a badly known car:
  c_s +-30 %, k_s +-15 %, k_t +-10 %, m_u +-15 %, m_s 230-590 kg (``VEHICLE_SPREAD``).

The runs take disjoint 800 m stretches of one synthetic road per road seed; a rougher road of the
same seed is the same road scaled by sqrt(Gd(n0)), as ``SyntheticRoad`` builds it (tested). The
first ``settle`` s of each run (the start from rest) are dropped.

Features (``FEATURES``): a_s, a_u and the deflection as measured and in the octave bands 1-2,
2-4, 4-8, 8-16 and 16-32 Hz (18 features), their mean square pooled over the last ``BLOCKS``
blocks of ``WINDOW`` s, over the speed, in ln. The band-pass filters start at rest at the first
sample kept; windows that begin within ``WARM`` s of it are left out. On every window
(``train_ordinal``) ln Gd(n0) is fitted by least squares and the class is the nearest on the ISO
grid, written as the one-vs-one pairs ``response_class`` evaluates. A linear SVM on the same
features (``train``, scikit-learn's ``SVC(kernel="linear")``, still what the paper study's
classifier uses) came out 1-4 points lower on held-out roads with the roughness over the whole
band: its classes are bands of one continuous quantity, which least squares on that quantity
uses and the SVM's hinge loss does not.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .response_class import ISO_MODEL, MODEL_DIR, check_model, predict, window_features
from ..plant import iso8608
from ..plant.quarter_car import SensorNoise, discretise, state_matrices
from ..plant.road import SyntheticRoad
from ..plant.vehicle import DEFAULT_VEHICLE, Vehicle

CLASSES = (1, 2, 3, 4, 5)  # ISO A-E
SIGNALS = ("acc_sprung", "acc_unsprung", "deflection")
# (low, high) factor on DEFAULT_VEHICLE, m_s in kg
VEHICLE_SPREAD = {"c_s": (0.7, 1.3), "k_s": (0.85, 1.15), "k_t": (0.9, 1.1), "m_u": (0.85, 1.15),
                  "m_s_kg": (230.0, 590.0)}
SPEEDS = (10.0, 30.0)  # m/s
H = 5e-3  # s
STRETCH = 800.0  # m of road per run
TRAIN_ROAD_SEEDS = (101, 102)
TRAIN_SEED = 7
WINDOW = 2.0  # s of a block: a decision every 2 s
BLOCKS = 6  # blocks pooled in a decision (12 s; benchmarks/road_class_accuracy.py compares 1-6)
HYSTERESIS = 0.05  # ln Gd(n0) beyond a band edge before the class in force changes
BANDS = ((1.0, 2.0), (2.0, 4.0), (4.0, 8.0), (8.0, 16.0), (16.0, 32.0))  # Hz, octaves
# every signal as measured and in every band of BANDS: (signal index, low Hz, high Hz)
FEATURES = tuple((i, None, None) for i in range(3)) + tuple((i, lo, hi) for i in range(3) for lo, hi in BANDS)
WARM = 1.0  # s after settling left out of training (the band-pass filters start at rest)


@dataclass
class Runs:
    """Measurements Y (runs, K, 3) after settling, and per run: class, Gd(n0), speed, vehicle; zr
    (runs, K) the road heights (m) under the tyre at the same samples."""

    Y: np.ndarray
    classes: np.ndarray
    gd: np.ndarray
    speed: np.ndarray
    vehicles: list[Vehicle]
    zr: np.ndarray | None = None


def draw_vehicle(rng: np.random.Generator) -> Vehicle:
    """A vehicle drawn uniformly within ``VEHICLE_SPREAD``."""
    f = {k: rng.uniform(*VEHICLE_SPREAD[k]) for k in ("c_s", "k_s", "k_t", "m_u")}
    return DEFAULT_VEHICLE.with_(m_s=rng.uniform(*VEHICLE_SPREAD["m_s_kg"]),
                                 **{k: getattr(DEFAULT_VEHICLE, k) * v for k, v in f.items()})


def draw_gd(rng: np.random.Generator, road_class: int, spread: bool = True) -> float:
    """Gd(n0) (m^3) of ``road_class``: log-uniform over its band, or its class value."""
    return iso8608.class_psd_n0(road_class) * (2.0 ** rng.uniform(-1, 1) if spread else 1.0)


def simulate(n_runs: int, duration: float, seed: int, road_seeds: tuple[int, ...] = TRAIN_ROAD_SEEDS,
             settle: float = 1.0, h: float = H, spread: bool = True, noise: SensorNoise = SensorNoise(),
             vehicles: Callable[[int], Vehicle] | None = None,
             change: tuple[float, Callable[[int], int]] | None = None) -> Runs:
    """``n_runs`` runs (classes A-E in turn) of ``duration`` s kept after ``settle`` s (module doc);
    ``vehicles(i)`` gives run i's vehicle instead of a draw.

    ``change`` = (t, after): from t s after settling, run i's road is of class ``after(i)``
    (its class value times the run's Gd(n0) over its class value): the road's increments are
    scaled from there on, so the road stays continuous. ``Runs.classes`` stays the class before.

    The plant equations of ``plant.quarter_car.QuarterCar`` (same ``state_matrices``,
    ``discretise``, outputs at the end of the step) advanced for
    all runs at once; tests/test_response_class.py checks one run against ``QuarterCar``."""
    rng = np.random.default_rng(seed)
    K0, K = int(round(settle / h)), int(round((settle + duration) / h))
    unit = {s: SyntheticRoad(iso8608.GD_N0_A, seed=s) for s in road_seeds}
    classes = np.array([CLASSES[i % len(CLASSES)] for i in range(n_runs)])
    gd = np.array([draw_gd(rng, c, spread) for c in classes])
    speed = rng.uniform(*SPEEDS, n_runs)
    vehicles = [draw_vehicle(rng) if vehicles is None else vehicles(i) for i in range(n_runs)]
    if K * h * SPEEDS[1] > STRETCH:
        raise ValueError(f"duration {duration} s is longer than a {STRETCH} m stretch at {SPEEDS[1]} m/s")
    zr = np.empty((n_runs, K))
    for i in range(n_runs):
        road = unit[road_seeds[i % len(road_seeds)]]
        s0 = STRETCH * (i // len(road_seeds))
        zr[i] = np.sqrt(gd[i] / iso8608.GD_N0_A) * np.array(
            [road.height(s0 + speed[i] * k * h) for k in range(1, K + 1)])
        if change is not None:
            kc = K0 + int(round(change[0] / h))
            c = change[1](i)
            gain = np.sqrt(iso8608.class_psd_n0(c) / iso8608.class_psd_n0(classes[i]))
            zr[i, kc:] = zr[i, kc - 1] + gain * np.cumsum(np.diff(zr[i, kc - 1:]))
    mats = [state_matrices(v) for v in vehicles]
    Ad, Bd = map(np.array, zip(*(discretise(A, B, h) for A, B in mats)))
    C = np.array([[A[1], A[3], [1.0, 0.0, -1.0, 0.0]] for A, _ in mats])  # (runs, 3, 4)
    D = np.array([[B[1], B[3], 0.0] for _, B in mats])
    x = np.zeros((n_runs, 4))
    x[:, 0] = x[:, 2] = zr[:, 0]  # settled on the road at its first height (QuarterCar.settle)
    Y = np.empty((n_runs, K, 3))
    for k in range(K):
        x = np.einsum("rij,rj->ri", Ad, x) + Bd * zr[:, k, None]
        Y[:, k] = np.einsum("rij,rj->ri", C, x) + D * zr[:, k, None]
    Y += rng.standard_normal(Y.shape) * np.array([noise.acc_sprung, noise.acc_unsprung, noise.deflection])
    return Runs(Y[:, K0:], classes, gd, speed, vehicles, zr[:, K0:])


def spec(features=FEATURES, window: float = WINDOW, blocks: int = BLOCKS, speed_power: float = 1.0) -> dict:
    """The feature part of a model dict: what ``response_class.window_features`` needs."""
    return {"signals": list(SIGNALS), "features": [list(f) for f in features], "window": window,
            "blocks": blocks, "speed_power": speed_power}


def features_of(runs: Runs, model: dict, h: float = H, warm: float = WARM) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(features (windows, features), class, ln Gd(n0)) of every whole window of ``model["blocks"]``
    blocks of every run after ``warm`` s (the filters run from the start of ``runs.Y``)."""
    f = window_features(model, runs.Y, runs.speed[:, None], h)
    f = f[:, math.ceil(warm / model["window"] - 1e-9) + int(model.get("blocks", 1)) - 1:]
    n = f.shape[1]
    return f.reshape(-1, f.shape[-1]), np.repeat(runs.classes, n), np.repeat(np.log(runs.gd), n)


def _r(a) -> list:
    return [float(f"{v:.10g}") for v in np.ravel(a)]


def train(f: np.ndarray, labels: np.ndarray, signals: tuple[str, ...] = SIGNALS, window: float = WINDOW,
          speed_power: float = 1.0, C: float = 1.0) -> dict:
    """Model dict (``estimators.response_class``) of a linear one-vs-one SVM on features f."""
    from sklearn.svm import SVC

    mean, scale = _r(f.mean(axis=0)), _r(f.std(axis=0))
    g = (f - mean) / np.array(scale)
    svm = SVC(kernel="linear", C=C, decision_function_shape="ovo").fit(g, labels)
    c = len(svm.classes_)
    pairs = [[i, j] for i in range(c) for j in range(i + 1, c)]
    model = check_model({
        "classes": [int(v) for v in svm.classes_], "signals": list(signals), "window": window,
        "speed_power": speed_power, "mean": mean, "scale": scale, "pairs": pairs,
        "coef": [_r(w) for w in svm.coef_], "intercept": _r(svm.intercept_),
        "trained_on": f"{len(labels)} blocks", "classifier": "sklearn.svm.SVC(kernel='linear', "
        f"C={C}), one-vs-one; a pair (i, j) votes i where coef . (f - mean) / scale + intercept > 0"})
    # the stored weights must predict what scikit-learn predicts
    agree = np.mean(predict(model, f) == svm.predict(g))
    if agree < 0.999:
        raise RuntimeError(f"stored model agrees with SVC.predict on {agree:.1%} of the training set")
    return model


def train_ordinal(f: np.ndarray, ln_gd: np.ndarray, feature_spec: dict, classes=CLASSES,
                  hysteresis: float = HYSTERESIS) -> dict:
    """Model dict (``estimators.response_class``) of ln Gd(n0) fitted by least squares to the
    standardised features f and rounded to the nearest class on the ISO grid, written as
    one-vs-one pairs: the pair (i, j) votes i where the estimate lies below the mid point of the
    two class values in ln Gd(n0) (coef = -beta, intercept = that mid point - beta_0), so the
    pairs' decision values and ``hysteresis`` are in ln Gd(n0)."""
    mean, scale = _r(f.mean(axis=0)), _r(f.std(axis=0))
    g = (f - mean) / np.array(scale)
    beta = np.linalg.lstsq(np.c_[g, np.ones(len(g))], ln_gd, rcond=None)[0]
    beta = np.array(_r(beta))
    centre = [np.log(iso8608.class_psd_n0(c)) for c in classes]
    c = len(classes)
    pairs = [[i, j] for i in range(c) for j in range(i + 1, c)]
    model = check_model(dict(
        feature_spec, classes=[int(v) for v in classes], mean=mean, scale=scale, pairs=pairs,
        coef=[_r(-beta[:-1]) for _ in pairs],
        intercept=_r([(centre[i] + centre[j]) / 2 - beta[-1] for i, j in pairs]),
        hysteresis=hysteresis, trained_on=f"{len(ln_gd)} windows",
        classifier="least squares of ln Gd(n0) on (f - mean) / scale (numpy.linalg.lstsq), nearest "
                   "class: a pair (i, j) votes i where coef . (f - mean) / scale + intercept > 0"))
    est = g @ beta[:-1] + beta[-1]
    near = np.clip(np.round((est - centre[0]) / np.log(4.0)), 0, c - 1).astype(int)
    agree = np.mean(predict(model, f) == np.asarray(classes)[near])
    if agree < 0.999:
        raise RuntimeError(f"stored model agrees with the rounded estimate on {agree:.1%} of the training set")
    return model


def train_iso_model(n_runs: int = 300, duration: float = 24.0, seed: int = TRAIN_SEED) -> dict:
    """The shipped model: ``n_runs`` simulated runs of ``duration`` s (module doc)."""
    s = spec()
    f, _, ln_gd = features_of(simulate(n_runs, duration, seed), s)
    return train_ordinal(f, ln_gd, s)


def dumps(model: dict) -> str:
    """The model file's text: sorted keys, one value a line, newline at the end."""
    return json.dumps(model, indent=1, sort_keys=True) + "\n"


def write_iso_model(path: Path = MODEL_DIR / ISO_MODEL) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps(train_iso_model()), encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=MODEL_DIR / ISO_MODEL)
    a = ap.parse_args(argv)
    try:
        print(f"wrote {write_iso_model(a.out)}")
    except OSError as e:
        print(f"response_class_train: cannot write {a.out}: {e.strerror}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
