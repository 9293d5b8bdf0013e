"""The LQR weight schedule: NSGA-II over paper 002's 100 working conditions (its eq. 17).

    python -m suspension_estimation.controllers.schedule_train [--out FILE]

writes ``schedule.SCHEDULE`` (package data); ``build.py`` runs the same function when the file is
not ``is_current`` (its sources or pymoo changed, or it was edited), and the same seed gives the
same file byte for byte (numbers rounded to 10 significant digits, as the road classifier's).

Conditions: speed 10, 15, 20, 25, 30 m/s x ISO 8608 classes A-D (Gd(n0) the class values) x five
sprung masses. The paper's masses, 300-500 kg in steps of 50 around its 400 kg, are 0.75-1.25 of
its nominal car; ours is ``DEFAULT_HALF_CAR`` (672 kg), so the masses are the same fractions of
672 kg (504-840 kg; the pitch inertia kept, as the plant keeps it when the mass changes).

Per condition, as eq. 17: the decision variables q1 (= q4, deflection) and q2 (= q5, body
acceleration), q3 = q6 = 1e-4 (tyre deflection); population 30 (pymoo's NSGA2, the same seed for
every condition), 30 generations where the paper runs 100 (the choice below stops moving after
20-40; docs/controller.md has the measurement); objectives

    f1 = RMS of the body acceleration at the CG, x_H'' (m/s2)
    f2 = 0.5 (peak |d_f| + peak |d_r|) (m)
    subject to peak |d_f| < 0.15 m, peak |d_r| < 0.15 m,

evaluated analytically, not by simulation: the road velocity under each tyre is white noise of the
ISO road's intensity (``lqr.road_intensity``, waviness 2), front and rear independent (the
paper's omega_f, omega_r), the closed loop's stationary covariance comes from the Lyapunov
equation (``lqr.DesignModel.covariance``), and the "max |deflection|" of eq. 17 is taken as the
Gaussian peak ``PEAK`` = 3 sigma (exceeded 0.27 % of the time). The search runs on log10 q1 in
[0, 9] and log10 q2 in [-2, log10 2000]: the paper's upper bounds; the weights span decades, and
log10 needs positive lower bounds (q2 > 0 besides for R^-1, ``lqr`` module doc).

The chosen point is the feasible non-dominated point closest to the origin, as the paper chooses,
with each objective divided by the passive car's at the same condition (zero actuator force, the
dampers c_f, c_r acting): both objectives become unit-free ratios to passive, and the origin stays
the origin. It is taken from every evaluation of the run (an archive), not only the final
population: K depends on the ratios of the weights only, and with q3 fixed and small nearly only
on q1/q2, so every evaluation lies on one curve from 0.01 to 50 times the passive acceleration,
along which the final 30 are spread by their crowding distance with one or two near the knee.
For the same reason q1 and q2 of the table wander over decades from one condition to the next
while q1/q2 stays within about 0.1 decade at one mass.

A consequence worth knowing: the system is linear, so every standard deviation scales with
sqrt(Gd(n0) V), and so do both objectives, for any weights. Scaling both objectives by one factor
changes neither the Pareto set nor the point closest to the origin (in raw or passive-normalised
units), so speed and road class can move the chosen weights only through the 0.15 m constraint;
the sprung mass, which changes the dynamics, moves them. The covariance is therefore computed once
per mass and weights at unit intensity (``Responses``) and scaled per condition.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from pathlib import Path

import numpy as np

from .lqr import DesignModel, road_intensity
from .schedule import DATA_DIR, SCHEDULE, COLUMNS, check_table
from ..plant import iso8608
from ..plant.half_car import DEFAULT_HALF_CAR, HalfCarParams

SPEEDS = (10.0, 15.0, 20.0, 25.0, 30.0)  # m/s
CLASSES = (1, 2, 3, 4)  # ISO A-D
MASS_FRACTIONS = (0.75, 0.875, 1.0, 1.125, 1.25)  # the paper's 300-500 kg over its 400 kg
Q3 = 1e-4  # q3 = q6, eq. 17
LOG_Q1 = (0.0, 9.0)
LOG_Q2 = (-2.0, math.log10(2000.0))
PEAK = 3.0  # "max |deflection|" = PEAK standard deviations
DEFLECTION_LIMIT = 0.15  # m, eq. 17
POPULATION = 30
GENERATIONS = 30  # the paper runs 100: docs/controller.md says why fewer
SEED = 1
# what the schedule is computed from, beside pymoo (pinned): a change retrains it (is_current)
SOURCES = ("controllers/lqr.py", "controllers/schedule.py", "controllers/schedule_train.py", "plant/half_car.py",
           "plant/iso8608.py")
FAILED = 1e6  # objectives and constraints of weights that have no gain


def _r(x: float) -> float:
    return float(f"{x:.10g}")


class Responses:
    """Standard deviations at unit road intensity of one car, cached by (mass, q1, q2): the body
    acceleration at the CG (m/s2), the front and rear deflections (m)."""

    def __init__(self, car: HalfCarParams = DEFAULT_HALF_CAR):
        self.car = car
        self._models: dict[float, DesignModel] = {}
        self._cache: dict[tuple[float, float, float], tuple[float, float, float] | None] = {}
        self.evaluations = 0  # Riccati and Lyapunov solutions computed

    def model(self, m_s: float) -> DesignModel:
        if m_s not in self._models:
            self._models[m_s] = DesignModel.of(self.car.with_(m_s=m_s))
        return self._models[m_s]

    def of_gain(self, m_s: float, K: np.ndarray) -> tuple[float, float, float]:
        """(sigma x_H'', sigma d_f, sigma d_r) at unit intensity under u = -K xi."""
        model = self.model(m_s)
        S = model.covariance(K)
        acc = model.A[0] - model.B[0] @ K  # x_H'' = row 0 of xi' without the road (G has none there)
        return math.sqrt(acc @ S @ acc), math.sqrt(S[4, 4]), math.sqrt(S[5, 5])

    def of_weights(self, m_s: float, q1: float, q2: float) -> tuple[float, float, float] | None:
        """``of_gain`` of the LQR gain of (q1, q2, Q3), None where eq. 14 has no stabilising
        solution (scipy's solver gives up on the extreme comfort end, q1/q2 below ~0.1)."""
        key = (m_s, q1, q2)
        if key not in self._cache:
            self.evaluations += 1
            try:
                self._cache[key] = self.of_gain(m_s, self.model(m_s).gain(q1, q2, Q3))
            except ValueError:
                self._cache[key] = None
        return self._cache[key]


def objectives(unit: tuple[float, float, float] | None, intensity: float) -> tuple[float, float, float, float]:
    """(f1, f2, g_f, g_r) of eq. 17 from unit-intensity standard deviations: g <= 0 is feasible.
    Weights without a gain (None) are infeasible by far."""
    if unit is None:
        return FAILED, FAILED, FAILED, FAILED
    s = math.sqrt(intensity)
    acc, df, dr = unit[0] * s, PEAK * unit[1] * s, PEAK * unit[2] * s
    return _r(acc), _r(0.5 * (df + dr)), _r(df - DEFLECTION_LIMIT), _r(dr - DEFLECTION_LIMIT)


def optimise(responses: Responses, speed: float, road_class: int, m_s: float,
             population: int = POPULATION, generations: int = GENERATIONS, seed: int = SEED) -> list[float]:
    """One row of the schedule (``schedule.COLUMNS``) for one condition."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize

    intensity = road_intensity(iso8608.class_psd_n0(road_class), speed)

    class Eq17(Problem):
        def __init__(self):
            super().__init__(n_var=2, n_obj=2, n_ieq_constr=2, xl=np.array([LOG_Q1[0], LOG_Q2[0]]),
                             xu=np.array([LOG_Q1[1], LOG_Q2[1]]))

        def _evaluate(self, X, out, *args, **kwargs):
            rows = [objectives(responses.of_weights(m_s, 10.0 ** a, 10.0 ** b), intensity) for a, b in X]
            out["F"] = np.array([r[:2] for r in rows])
            out["G"] = np.array([r[2:] for r in rows])
            archive.extend((a, b, *r) for (a, b), r in zip(X.tolist(), rows))

    archive: list[tuple[float, ...]] = []  # every evaluation of the run: log10 q1, log10 q2, f1, f2, g_f, g_r
    minimize(Eq17(), NSGA2(pop_size=population), ("n_gen", generations), seed=seed, verbose=False)
    front = _front([a for a in archive if a[4] <= 0.0 and a[5] <= 0.0])
    if not front:
        raise RuntimeError(f"no feasible weights at {speed} m/s, class {road_class}, {m_s} kg")
    passive = objectives(responses.of_gain(m_s, np.zeros((2, 8))), intensity)
    best = min(front, key=lambda a: (math.hypot(a[2] / passive[0], a[3] / passive[1]), a))
    q1, q2 = _r(10.0 ** best[0]), _r(10.0 ** best[1])
    model = responses.model(m_s)
    margin = model.margin(model.gain(q1, q2, Q3))
    return [speed, float(road_class), _r(m_s), q1, q2, Q3, best[2], best[3], passive[0], passive[1], _r(margin)]


def _front(points: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
    """The points (.., f1, f2 at [2], [3]) that no other point dominates (minimising both)."""
    out, best_f2 = [], math.inf
    for a in sorted(set(points), key=lambda a: (a[2], a[3])):
        if a[3] < best_f2:
            out.append(a)
            best_f2 = a[3]
    return out


def train_schedule(car: HalfCarParams = DEFAULT_HALF_CAR, speeds=SPEEDS, classes=CLASSES,
                   mass_fractions=MASS_FRACTIONS, population: int = POPULATION,
                   generations: int = GENERATIONS, seed: int = SEED) -> dict:
    """The schedule table (``schedule`` module doc) of ``car`` over the conditions given."""
    responses = Responses(car)
    masses = [_r(f * car.m_s) for f in mass_fractions]
    rows = [optimise(responses, v, c, m, population, generations, seed)
            for v in speeds for c in classes for m in masses]
    return check_table({
        "about": "LQR weights of paper 002 (eqs. 10-17) per working condition: NSGA-II (pymoo), the point "
                 "of the feasible front closest to the origin with both objectives over the passive car's "
                 "(controllers/schedule_train.py)",
        "car": {k: _r(v) for k, v in vars(car).items()},
        "grid": {"speed": list(speeds), "road_class": list(classes), "sprung_mass": masses},
        "nsga2": {"population": population, "generations": generations, "seed": seed,
                  "log10_q1": list(LOG_Q1), "log10_q2": [LOG_Q2[0], _r(LOG_Q2[1])], "peak_sigmas": PEAK,
                  "deflection_limit": DEFLECTION_LIMIT},
        "columns": list(COLUMNS),
        "rows": rows,
        "rows_sha256": rows_hash(rows),
        "sources_sha256": sources_hash(),
    })


def sources_hash() -> str:
    """SHA-256 of pymoo's version and of the ``SOURCES`` files (line ends normalised)."""
    from importlib.metadata import version

    top = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(f"pymoo {version('pymoo')}".encode())
    for name in SOURCES:
        h.update(b"\0" + name.encode() + b"\0" + (top / name).read_bytes().replace(b"\r\n", b"\n"))
    return h.hexdigest()


def rows_hash(rows: list) -> str:
    return hashlib.sha256(json.dumps(rows).encode()).hexdigest()


def is_current(path: Path = DATA_DIR / SCHEDULE) -> bool:
    """Whether the schedule file is a complete table trained from the present sources, its rows
    as trained (not edited)."""
    try:
        table = check_table(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, TypeError, KeyError):
        return False
    return table.get("sources_sha256") == sources_hash() and table.get("rows_sha256") == rows_hash(table["rows"])


def dumps(table: dict) -> str:
    """The file's text: sorted keys, the header one value a line, one row a line."""
    head = json.dumps({**table, "rows": []}, indent=1, sort_keys=True)
    rows = ",\n".join("  " + json.dumps(r) for r in table["rows"])
    return head.replace('"rows": []', '"rows": [\n' + rows + "\n ]") + "\n"


def write_schedule(path: Path = DATA_DIR / SCHEDULE) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps(train_schedule()), encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DATA_DIR / SCHEDULE)
    a = ap.parse_args(argv)
    try:
        print(f"wrote {write_schedule(a.out)}")
    except OSError as e:
        print(f"schedule_train: cannot write {a.out}: {e.strerror}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
