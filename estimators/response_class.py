"""Road class from the measured RESPONSE of the car: a streaming linear one-vs-one classifier.

Paper 004 schedules the nominal Q and R of its VB-AKF by the ISO 8608 road class; its script takes
the class from the simulation (an oracle). This classifier takes it from the measurements alone.
Every feature is a measured signal y_i, either as measured or through a band-pass filter (a
second-order Butterworth band of ``low``-``high`` Hz, bilinear with pre-warped edges, designed
for the actual sample time), and over blocks of ``window`` s it forms

    f = ln( mean square of the feature over the last ``blocks`` blocks / V^p )   (V mean speed m/s,
                                                                                 p = speed_power)

For an ISO road of waviness 2 the road velocity is white with a PSD proportional to Gd(n0) V, so
the mean square of every linear response, in any fixed band of time frequency, grows like
Gd(n0) V (p = 1 removes the speed; one ISO class is a factor 4 of Gd(n0), ln 4 = 1.39 in f). The
mean squares of several bands of the three signals let a linear model undo most of what the
vehicle (masses, spring, damper, tyre) does to the response. The features are standardised,
g = (f - mean) / scale, and a linear one-vs-one rule votes: for the pair (i, j) with weights w and
intercept b, w . g + b > 0 votes for class i, otherwise for j; the most votes win (ties: the
lower class), as scikit-learn's ``SVC(kernel="linear")`` predicts. Every complete block gives a
new decision on the pooled window of its last ``blocks`` blocks (fewer at the start); a new class
replaces the class in force only when the pair of the two decides for it by more than
``hysteresis`` (0: always), so a road on a band edge does not flip back and forth; while the
window fills (after the start) the decision is taken as it is.

The trained model is plain data (a JSON file, ``load_model``); this module evaluates it with a
constant cost per sample (one biquad and one multiply-add per feature; one vote of the pairs per
block). It knows nothing of how the model was trained: ``estimators.response_class_train`` does
that. A model without ``features`` takes every signal as measured, with ``blocks`` 1 and
``hysteresis`` 0.
"""
from __future__ import annotations

import json
import math
from collections import deque
from pathlib import Path

import numpy as np

MODEL_DIR = Path(__file__).resolve().parent / "data"
ISO_MODEL = "response_class_iso.json"  # our quarter car (a_s, a_u, deflection), ISO A-E, 10-30 m/s
MODEL_KEYS = ("classes", "signals", "window", "speed_power", "mean", "scale", "pairs", "coef",
              "intercept")


def features_of_model(model: dict) -> list[tuple[int, float | None, float | None]]:
    """(signal index, low Hz, high Hz) of every feature; None, None: the signal as measured."""
    if "features" not in model:
        return [(i, None, None) for i in range(len(model["signals"]))]
    return [(int(i), lo, hi) for i, lo, hi in model["features"]]


def check_model(model: dict) -> dict:
    """Raise ValueError naming the first missing or inconsistent entry of a model dict."""
    missing = [k for k in MODEL_KEYS if k not in model]
    if missing:
        raise ValueError(f"road-class model lacks {', '.join(missing)}")
    c = len(model["classes"])
    feats = features_of_model(model)
    m = len(feats)
    for i, lo, hi in feats:
        if not 0 <= i < len(model["signals"]) or (lo is None) != (hi is None) or (lo is not None and not 0 < lo < hi):
            raise ValueError(f"road-class model: feature {[i, lo, hi]!r} needs a signal index and 0 < low < high Hz")
    if len(model["mean"]) != m or len(model["scale"]) != m or any(s <= 0 for s in model["scale"]):
        raise ValueError(f"road-class model: mean and scale need {m} entries, scale > 0")
    n_pairs = c * (c - 1) // 2
    if (len(model["pairs"]) != n_pairs or len(model["coef"]) != n_pairs
            or len(model["intercept"]) != n_pairs or any(len(w) != m for w in model["coef"])):
        raise ValueError(f"road-class model: {n_pairs} pairs of {m} weights expected")
    if not model["window"] > 0:
        raise ValueError(f"road-class model: window = {model['window']!r} s must be > 0")
    if not (int(model.get("blocks", 1)) >= 1 and model.get("hysteresis", 0.0) >= 0):
        raise ValueError("road-class model: blocks >= 1 and hysteresis >= 0 needed")
    return model


def load_model(path: str | Path = ISO_MODEL) -> dict:
    """The model dict from a JSON file (a bare name is looked up in the package's data folder)."""
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = MODEL_DIR / p
    return check_model(json.loads(p.read_text(encoding="utf-8")))


def bandpass(low: float | None, high: float | None, dt: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of the second-order Butterworth band-pass of ``low``-``high`` Hz at
    the sample time dt (s): y = b0 x + b1 x' + b2 x'' - a1 y' - a2 y'' (primes: samples back);
    scipy's ``butter(1, [low, high], "band", fs=1 / dt)``. None, None: y = x."""
    if low is None:
        return 1.0, 0.0, 0.0, 0.0, 0.0
    if not high < 0.5 / dt:
        raise ValueError(f"band {low:g}-{high:g} Hz needs a sample time below {0.5 / high:g} s, got {dt!r}")
    k = 2.0 / dt
    w1, w2 = k * math.tan(math.pi * low * dt), k * math.tan(math.pi * high * dt)  # pre-warped rad/s
    bw, w0sq = w2 - w1, w1 * w2
    a0 = k * k + bw * k + w0sq
    return bw * k / a0, 0.0, -bw * k / a0, 2.0 * (w0sq - k * k) / a0, (k * k - bw * k + w0sq) / a0


def filtered(model: dict, Y: np.ndarray, dt: float) -> np.ndarray:
    """The features' signals (..., K, features) of measurements Y (..., K, signals) sampled every
    dt s, every filter starting at rest: what ``ResponseClassifier`` filters sample by sample."""
    from scipy.signal import lfilter

    Y = np.asarray(Y, float)
    out = []
    for i, lo, hi in features_of_model(model):
        b0, b1, b2, a1, a2 = bandpass(lo, hi, dt)
        out.append(Y[..., i] if lo is None else lfilter([b0, b1, b2], [1.0, a1, a2], Y[..., i], axis=-1))
    return np.stack(out, axis=-1)


def predict(model: dict, f: np.ndarray) -> np.ndarray:
    """Classes (labels of ``model["classes"]``) of feature rows f (..., features) (module doc)."""
    return np.asarray(model["classes"])[np.argmax(_votes(model, f)[0], axis=-1)]


def _votes(model: dict, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    g = (np.asarray(f, float) - np.asarray(model["mean"])) / np.asarray(model["scale"])
    d = g @ np.asarray(model["coef"]).T + np.asarray(model["intercept"])  # (..., pairs)
    c = len(model["classes"])
    votes = np.zeros(g.shape[:-1] + (c,), int)
    for p, (i, j) in enumerate(model["pairs"]):
        win = d[..., p] > 0
        votes[..., i] += win
        votes[..., j] += ~win
    return votes, d


def decide(model: dict, f: np.ndarray, current: np.ndarray | int, hold: bool = True) -> np.ndarray:
    """The class in force after a decision on feature rows f (..., features) when ``current``
    (labels, 0 = none yet) was: the prediction, unless ``hold`` and the pair of ``current`` and
    the prediction decides for it by no more than ``model["hysteresis"]`` (module doc)."""
    votes, d = _votes(model, f)
    labels = np.asarray(model["classes"])
    new = labels[np.argmax(votes, axis=-1)]
    delta = float(model.get("hysteresis", 0.0)) if hold else 0.0
    cur = np.broadcast_to(np.asarray(current), new.shape)
    if delta <= 0:
        return new
    pair = {(i, j): p for p, (i, j) in enumerate(model["pairs"])}
    out, cur = np.atleast_1d(new).copy(), np.atleast_1d(cur)
    d = d.reshape(out.shape + d.shape[-1:])
    for idx in zip(*np.nonzero((out != cur) & np.isin(cur, labels))):
        i, j = int(np.searchsorted(labels, cur[idx])), int(np.searchsorted(labels, out[idx]))
        p = pair[(min(i, j), max(i, j))]
        margin = d[idx + (p,)] if j < i else -d[idx + (p,)]  # > 0: the pair votes for the new class
        if margin <= delta:
            out[idx] = cur[idx]
    return out.reshape(new.shape)


def block_features(Y: np.ndarray, speed: np.ndarray | float, samples: int,
                   speed_power: float = 1.0) -> np.ndarray:
    """Features of consecutive whole blocks of ``samples`` samples of Y (..., K, signals), speed
    (m/s) per sample or constant: (..., K // samples, signals), every signal as measured, one
    block a decision (mean speed over the block)."""
    sq, v, n = block_sums(Y, speed, samples)
    return np.log(sq / n) - speed_power * np.log(v / n)[..., None]


def block_sums(Z: np.ndarray, speed: np.ndarray | float, samples: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Per whole block of ``samples`` samples of Z (..., K, features): the sums of squares
    (..., K // samples, features), the sums of |speed| (..., K // samples), and ``samples``."""
    Z = np.asarray(Z, float)
    nb = Z.shape[-2] // samples
    Zb = Z[..., :nb * samples, :].reshape(Z.shape[:-2] + (nb, samples, Z.shape[-1]))
    V = np.abs(np.broadcast_to(np.asarray(speed, float), Z.shape[:-1])[..., :nb * samples])
    return np.sum(Zb ** 2, axis=-2), V.reshape(V.shape[:-1] + (nb, samples)).sum(axis=-1), samples


def window_features(model: dict, Y: np.ndarray, speed: np.ndarray | float, dt: float) -> np.ndarray:
    """Features (..., blocks of Y, features) on which ``ResponseClassifier`` decides at the end of
    every whole block of Y (..., K, signals) (speed m/s, dt s; all blocks driven): the pooled mean
    square of the last ``model["blocks"]`` blocks, fewer at the start."""
    samples = int(round(float(model["window"]) / dt))
    sq, v, n = block_sums(filtered(model, Y, dt), speed, samples)
    k = int(model.get("blocks", 1))
    nb = sq.shape[-2]
    c_sq = np.concatenate([np.zeros_like(sq[..., :1, :]), np.cumsum(sq, axis=-2)], axis=-2)
    c_v = np.concatenate([np.zeros_like(v[..., :1]), np.cumsum(v, axis=-1)], axis=-1)
    end = np.arange(1, nb + 1)
    start = np.maximum(end - k, 0)
    count = (end - start) * n
    w_sq = (c_sq[..., end, :] - c_sq[..., start, :]) / count[:, None]
    w_v = (c_v[..., end] - c_v[..., start]) / count
    return np.log(w_sq) - float(model["speed_power"]) * np.log(w_v)[..., None]


def classify(model: dict, Y: np.ndarray, speed: np.ndarray | float, dt: float, initial: int = 0) -> np.ndarray:
    """Class in force after every whole block of Y (..., K, signals): what ``ResponseClassifier``
    returns sample by sample at each block's last sample (all blocks driven)."""
    f = window_features(model, Y, speed, dt)
    cur = np.full(f.shape[:-2], initial)
    out = np.empty(f.shape[:-1], int)
    k = int(model.get("blocks", 1))
    for b in range(f.shape[-2]):
        cur = decide(model, f[..., b, :], cur, hold=b + 1 >= k)
        out[..., b] = cur
    return out


class ResponseClassifier:
    """Streaming road class from the measurements (module doc).

    ``update(y, speed, dt)`` adds one sample (y one value per ``model["signals"]``, in their
    units; speed m/s; dt s) and returns the class in force: ``initial`` until the first block is
    complete, then the decision of the last complete block (module doc). A block holds the
    samples whose time adds up to ``model["window"]`` s; a block with a mean speed below
    ``min_speed`` is left out of the window and keeps the class (the response of a car at rest
    says nothing of the road). The band-pass filters run on every sample; they are designed
    for the first sample's dt and again whenever dt changes."""

    def __init__(self, model: dict | str | Path = ISO_MODEL, initial: int = 0, min_speed: float = 1.0):
        self.model = check_model(model) if isinstance(model, dict) else load_model(model)
        self.window = float(self.model["window"])
        self.min_speed = float(min_speed)
        self.road_class = initial
        self.blocks = 0  # complete blocks classified
        feats = features_of_model(self.model)
        self._m = len(self.model["signals"])
        self._sig = np.array([i for i, _, _ in feats])
        self._bands = [(lo, hi) for _, lo, hi in feats]
        self._dt = None
        self._b0 = self._b1 = self._b2 = self._a1 = self._a2 = None  # band filters at step _dt
        self._s1 = np.zeros(len(feats))
        self._s2 = np.zeros(len(feats))
        self._past = deque(maxlen=int(self.model.get("blocks", 1)))  # (sums of squares, samples, sum of speed)
        self._reset_block()

    def _reset_block(self) -> None:
        self._sq = np.zeros(len(self._sig))
        self._n = 0
        self._t = 0.0
        self._v = 0.0

    def _design(self, dt: float) -> None:
        c = np.array([bandpass(lo, hi, dt) for lo, hi in self._bands])
        self._b0, self._b1, self._b2, self._a1, self._a2 = c.T
        self._dt = dt

    def update(self, y, speed: float, dt: float) -> int:
        if len(y) != self._m:
            raise ValueError(f"y has {len(y)} values, the model's signals are {self.model['signals']}")
        dt = float(dt)
        if self._dt is None or abs(dt - self._dt) > 1e-9 * self._dt:
            self._design(dt)
        x = np.asarray(y, float)[self._sig]
        z = self._b0 * x + self._s1  # direct form II transposed, as scipy's lfilter
        self._s1 = self._b1 * x - self._a1 * z + self._s2
        self._s2 = self._b2 * x - self._a2 * z
        self._sq += z * z
        self._n += 1
        self._v += abs(float(speed))
        self._t += dt
        if self._t >= self.window * (1.0 - 1e-9):
            if self._v / self._n >= self.min_speed and np.all(self._sq > 0.0):
                self._past.append((self._sq, self._n, self._v))
                sq = sum(p[0] for p in self._past)
                n = sum(p[1] for p in self._past)
                v = sum(p[2] for p in self._past) / n
                f = np.log(sq / n) - self.model["speed_power"] * math.log(v)
                full = len(self._past) == self._past.maxlen
                self.road_class = decide(self.model, f, self.road_class, hold=full).item()
                self.blocks += 1
            self._reset_block()
        return self.road_class
