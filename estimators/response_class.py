"""Road class from the measured RESPONSE of the car: a streaming linear one-vs-one classifier.

Paper 004 schedules the nominal Q and R of its VB-AKF by the ISO 8608 road class; its script takes
the class from the simulation (an oracle). This classifier takes it from the measurements alone:
over blocks of ``window`` s it forms, for every measured signal y_i, the feature

    f_i = ln( mean over the block of y_i^2 / V^p )                   (V speed m/s, p = speed_power)

For an ISO road of waviness 2 the road velocity is white with a PSD proportional to Gd(n0) V, so
the mean square of every linear response grows like Gd(n0) V (p = 1 removes the speed; one ISO
class is a factor 4 of Gd(n0), ln 4 = 1.39 in f). The features are standardised,
g = (f - mean) / scale, and a linear one-vs-one SVM votes: for the pair (i, j) with weights w and
intercept b, w . g + b > 0 votes for class i, otherwise for j; the most votes win (ties: the
lower class), as scikit-learn's ``SVC(kernel="linear")`` predicts.

The trained model is plain data (a JSON file, ``load_model``); this module evaluates it with a
constant cost per sample (one multiply-add per signal; one vote of the pairs per block). It
knows nothing of how the model was trained: ``estimators.response_class_train`` does that.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

MODEL_DIR = Path(__file__).resolve().parent / "data"
ISO_MODEL = "response_class_iso.json"  # our quarter car (a_s, a_u, deflection), ISO A-E, 10-30 m/s
MODEL_KEYS = ("classes", "signals", "window", "speed_power", "mean", "scale", "pairs", "coef",
              "intercept")


def check_model(model: dict) -> dict:
    """Raise ValueError naming the first missing or inconsistent entry of a model dict."""
    missing = [k for k in MODEL_KEYS if k not in model]
    if missing:
        raise ValueError(f"road-class model lacks {', '.join(missing)}")
    m, c = len(model["signals"]), len(model["classes"])
    if len(model["mean"]) != m or len(model["scale"]) != m or any(s <= 0 for s in model["scale"]):
        raise ValueError(f"road-class model: mean and scale need {m} entries, scale > 0")
    n_pairs = c * (c - 1) // 2
    if (len(model["pairs"]) != n_pairs or len(model["coef"]) != n_pairs
            or len(model["intercept"]) != n_pairs or any(len(w) != m for w in model["coef"])):
        raise ValueError(f"road-class model: {n_pairs} pairs of {m} weights expected")
    if not model["window"] > 0:
        raise ValueError(f"road-class model: window = {model['window']!r} s must be > 0")
    return model


def load_model(path: str | Path = ISO_MODEL) -> dict:
    """The model dict from a JSON file (a bare name is looked up in the package's data folder)."""
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = MODEL_DIR / p
    return check_model(json.loads(p.read_text(encoding="utf-8")))


def predict(model: dict, f: np.ndarray) -> np.ndarray:
    """Classes (labels of ``model["classes"]``) of feature rows f (..., signals) (module doc)."""
    g = (np.asarray(f, float) - np.asarray(model["mean"])) / np.asarray(model["scale"])
    d = g @ np.asarray(model["coef"]).T + np.asarray(model["intercept"])  # (..., pairs)
    c = len(model["classes"])
    votes = np.zeros(g.shape[:-1] + (c,), int)
    for p, (i, j) in enumerate(model["pairs"]):
        win = d[..., p] > 0
        votes[..., i] += win
        votes[..., j] += ~win
    return np.asarray(model["classes"])[np.argmax(votes, axis=-1)]


def block_features(Y: np.ndarray, speed: np.ndarray | float, samples: int,
                   speed_power: float = 1.0) -> np.ndarray:
    """Features of consecutive whole blocks of ``samples`` samples of Y (..., K, signals), speed
    (m/s) per sample or constant: (..., K // samples, signals). Equals what ``ResponseClassifier``
    computes sample by sample (mean speed over the block)."""
    Y = np.asarray(Y, float)
    K = Y.shape[-2]
    nb = K // samples
    Yb = Y[..., :nb * samples, :].reshape(Y.shape[:-2] + (nb, samples, Y.shape[-1]))
    V = np.broadcast_to(np.asarray(speed, float), Y.shape[:-1])[..., :nb * samples]
    Vb = V.reshape(V.shape[:-1] + (nb, samples)).mean(axis=-1)
    return np.log(np.mean(Yb ** 2, axis=-2)) - speed_power * np.log(Vb)[..., None]


class ResponseClassifier:
    """Streaming road class from the measurements (module doc).

    ``update(y, speed, dt)`` adds one sample (y one value per ``model["signals"]``, in their
    units; speed m/s; dt s) and returns the class in force: ``initial`` until the first block is
    complete, then the class of the last complete block. A block holds the samples whose time
    adds up to ``model["window"]`` s; a block with a mean speed below ``min_speed`` keeps the
    previous class (the response of a car at rest says nothing of the road)."""

    def __init__(self, model: dict | str | Path = ISO_MODEL, initial: int = 0, min_speed: float = 1.0):
        self.model = check_model(model) if isinstance(model, dict) else load_model(model)
        self.window = float(self.model["window"])
        self.min_speed = float(min_speed)
        self.road_class = initial
        self.blocks = 0  # complete blocks classified
        self._m = len(self.model["signals"])
        self._reset_block()

    def _reset_block(self) -> None:
        self._sq = [0.0] * self._m
        self._n = 0
        self._t = 0.0
        self._v = 0.0

    def update(self, y, speed: float, dt: float) -> int:
        if len(y) != self._m:
            raise ValueError(f"y has {len(y)} values, the model's signals are {self.model['signals']}")
        for i in range(self._m):
            self._sq[i] += float(y[i]) ** 2
        self._n += 1
        self._v += abs(float(speed))
        self._t += float(dt)
        if self._t >= self.window * (1.0 - 1e-9):
            v = self._v / self._n
            if v >= self.min_speed and all(s > 0.0 for s in self._sq):
                p = self.model["speed_power"]
                f = [math.log(s / self._n) - p * math.log(v) for s in self._sq]
                self.road_class = predict(self.model, np.array(f)).item()
                self.blocks += 1
            self._reset_block()
        return self.road_class
