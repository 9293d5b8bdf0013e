"""The LQR weights over speed, road class and sprung mass: the shipped table and its interpolation.

The table (``SCHEDULE``, package data, written by ``schedule_train``) holds the NSGA-II optimum
(q1, q2, q3) of paper 002's eq. 17 at each of its 100 working conditions: speeds 10-30 m/s, ISO
classes A-D, five sprung masses. Between the conditions the weights are interpolated, linearly in
log10 q over speed and sprung mass within the row of the road class (the class is an integer),
and held at the edges: a speed below 10 or above 30 m/s takes the nearest speed's weights, a mass
outside the grid the nearest mass's, classes E-H take D's, and class 0 (not identified yet, as an
estimator reports before it has seen enough road) takes ``UNKNOWN_CLASS``'s.

Why interpolation and not the paper's fuzzy controller: the paper publishes its fuzzy rules only
as trends (Fig. 3: q1 falls and q2 rises with V, d and |x_H''|), not the membership functions or
the rule table, so they cannot be reproduced; a fuzzy system with centroid defuzzification over
a grid of optima is itself a smooth interpolator of those optima, and piecewise-linear
interpolation returns the optima exactly at the 100 conditions without inventing rules between
them. The paper's fuzzy controller also takes |x_H''| in place of the sprung mass, which it deems
hard to measure; here the mass is an input (an estimator's ``sprung_mass_est``, or the truth).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "data"
SCHEDULE = "lqr_schedule.json"
COLUMNS = ("speed", "road_class", "sprung_mass", "q1", "q2", "q3", "acc_rms", "deflection_peak",
           "passive_acc_rms", "passive_deflection_peak", "stability_margin")
UNKNOWN_CLASS = 3  # ISO C: the paper's nominal condition (its KF's: 20 m/s, ISO C, 400 kg)


def check_table(table: dict) -> dict:
    """``table`` if it is a complete schedule: the columns, one row per grid point in grid order
    (speed, then class, then mass), positive finite weights; else ValueError."""
    for key in ("grid", "columns", "rows"):
        if key not in table:
            raise ValueError(f"the schedule lacks {key!r}")
    if list(table["columns"]) != list(COLUMNS):
        raise ValueError(f"the schedule's columns are {table['columns']}, not {list(COLUMNS)}")
    g = table["grid"]
    want = [(v, c, m) for v in g["speed"] for c in g["road_class"] for m in g["sprung_mass"]]
    got = [tuple(r[:3]) for r in table["rows"]]
    if got != [(float(v), float(c), float(m)) for v, c, m in want]:
        raise ValueError("the schedule's rows are not the grid's points in order (speed, class, mass)")
    q = np.array([r[3:6] for r in table["rows"]], dtype=float)
    if not (np.all(np.isfinite(q)) and np.all(q > 0)):
        raise ValueError("the schedule holds weights that are not positive finite numbers")
    for name in ("speed", "sprung_mass"):
        if len(g[name]) > 1 and not np.all(np.diff(g[name]) > 0):
            raise ValueError(f"the schedule's {name} grid is not increasing")
    return table


@dataclass(frozen=True)
class Schedule:
    """log10 of q1, q2, q3 on the grid, shape (speeds, classes, masses)."""

    speeds: np.ndarray
    classes: tuple[int, ...]
    masses: np.ndarray
    log_q: np.ndarray  # (speeds, classes, masses, 3)

    @classmethod
    def from_table(cls, table: dict) -> "Schedule":
        g = check_table(table)["grid"]
        shape = (len(g["speed"]), len(g["road_class"]), len(g["sprung_mass"]), 3)
        q = np.array([r[3:6] for r in table["rows"]], dtype=float).reshape(shape)
        return cls(np.array(g["speed"], float), tuple(int(c) for c in g["road_class"]),
                   np.array(g["sprung_mass"], float), np.log10(q))

    def weights(self, speed: float, road_class: int, sprung_mass: float) -> tuple[float, float, float]:
        """(q1, q2, q3) at ``speed`` (m/s), ISO class 0..8 (0: not known) and ``sprung_mass`` (kg)."""
        c = UNKNOWN_CLASS if road_class == 0 else road_class
        ic = self.classes.index(min(max(c, self.classes[0]), self.classes[-1]))
        iv, tv = _bracket(self.speeds, speed)
        im, tm = _bracket(self.masses, sprung_mass)
        plane = self.log_q[:, ic]
        row = (1 - tv) * plane[iv] + tv * plane[min(iv + 1, len(self.speeds) - 1)]
        log_q = (1 - tm) * row[im] + tm * row[min(im + 1, len(self.masses) - 1)]
        return tuple(float(10.0 ** v) for v in log_q)


def _bracket(grid: np.ndarray, x: float) -> tuple[int, float]:
    """(i, t): x lies a fraction t of the way from grid[i] to grid[i + 1]; held at the ends."""
    if len(grid) == 1 or x <= grid[0]:
        return 0, 0.0
    if x >= grid[-1]:
        return len(grid) - 1, 0.0
    i = int(np.searchsorted(grid, x, side="right")) - 1
    return i, float((x - grid[i]) / (grid[i + 1] - grid[i]))


def load_schedule(path: str | Path = SCHEDULE) -> Schedule:
    """The schedule from a JSON file (a bare name is looked up in the package's data folder)."""
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = DATA_DIR / p
    return Schedule.from_table(json.loads(p.read_text(encoding="utf-8")))
