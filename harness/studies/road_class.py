"""The online ISO 8608 class of the default estimator (``class``): classes A..E at 10, 20 and
30 m/s, one SuspensionEstimator with the default configuration (road_class 0), 410 kg."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..metrics import road_scores
from .runner import (CLASS_LETTERS, NOMINAL_MASS, RunSpec, Study, build_system, mean_std, noise_params,
                     plant_params, simulate, vehicle_params, verdict)

CLASS_STUDY_CLASSES = (1, 2, 3, 4, 5)
CLASS_STUDY_SPEEDS = (10.0, 20.0, 30.0)  # m/s
TARGET_CLASS = 0.95  # share of samples at the true class, from the first identified class on


def run(spec: RunSpec) -> dict:
    """The online ISO class of the default estimator on one class at one speed."""
    dist = Path(spec.dist)
    params = plant_params(spec)
    params.update({f"SuspensionEstimator.{k}": x for k, x in {**vehicle_params(spec), **noise_params(spec)}.items()})
    record = ["ISORoad.road_height", "ISORoad.distance", "SuspensionEstimator.road_class_est", "SuspensionEstimator.road_height_est"]
    r, timing = simulate(build_system(dist, ["SuspensionEstimator"]), params,
                         {"vehicle_speed": spec.speed, "QuarterCar.sprung_mass": NOMINAL_MASS}, record, spec,
                         spec.duration)
    t, cls = r["time"], r["SuspensionEstimator.road_class_est"]
    seen = np.nonzero(cls > 0)[0]
    scores = road_scores(t, r["SuspensionEstimator.road_height_est"], r["ISORoad.road_height"], warmup=spec.warmup,
                         distance=r["ISORoad.distance"])
    return {"timing": timing, "class_first_s": float(t[seen[0]]) if len(seen) else math.inf,
            "class_right": float(np.mean(cls[seen[0]:] == spec.road_class)) if len(seen) else math.nan,
            "class_counts": {int(k): int(v) for k, v in zip(*np.unique(cls[seen[0]:], return_counts=True))}
            if len(seen) else {}, "err_std_hp_pct": scores["err_std_hp_pct"]}


class RoadClass(Study):
    name = "class"
    runs = {"class": run}

    def specs(self, suite) -> list[RunSpec]:
        d = str(Path(suite.dist).resolve())
        return [RunSpec("class", c, s, suite.duration, suite.warmup, suite.step, d, speed=u)
                for c in CLASS_STUDY_CLASSES for u in CLASS_STUDY_SPEEDS for s in range(1, suite.class_seeds + 1)]

    def markdown(self, suite) -> list[str]:
        lines = [f"## (d) Online ISO 8608 class, default estimator, classes A–E at 10–30 m/s, seeds "
                 f"1..{suite.class_seeds}", "", f"{suite.duration:g} s runs at {1e3 * suite.step:g} ms, "
                 f"{NOMINAL_MASS:g} kg, road_class 0. *right* = share of samples, from the first identified class "
                 "on, at the true class.", "",
                 "| ISO | speed (m/s) | first class after (s) | right after the first window % | worst seed % | "
                 "classes seen | seeds |", "|---|---|---|---|---|---|---|"]
        for c in CLASS_STUDY_CLASSES:
            for u in CLASS_STUDY_SPEEDS:
                rs = [r for r in suite.ok("class", road_class=c) if r["spec"]["speed"] == u]
                right = np.array([r["class_right"] for r in rs], float)
                first = np.array([r["class_first_s"] for r in rs], float)
                seen = sorted({CLASS_LETTERS[int(k) - 1] for r in rs for k in r["class_counts"]})
                least = f"{100 * np.min(right):.1f}" if len(right) else "–"
                lines.append(f"| {CLASS_LETTERS[c - 1]} | {u:g} | {mean_std(first, '.1f')} | "
                             f"{mean_std(100 * right, '.1f')} | {least} | {', '.join(seen) or '–'} | {len(rs)} |")
        return lines

    def targets(self, suite) -> list[tuple[str, str, str]]:
        rs = suite.ok("class")
        if not rs:
            return []
        right = np.array([r["class_right"] for r in rs], float)
        bad = [r["name"] for r in rs if not r["class_right"] >= TARGET_CLASS]
        return [(f"online ISO class right ≥ {100 * TARGET_CLASS:g} % after its first window, ISO A–E at "
                 f"10–30 m/s (every run)", verdict(not bad),
                 f"{len(rs)} runs, mean {100 * np.nanmean(right):.1f} %, worst {100 * np.nanmin(right):.1f} %"
                 + (f"; below: {', '.join(bad)}" if bad else ""))]


CLASS = RoadClass()
