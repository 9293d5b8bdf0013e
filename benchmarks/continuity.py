"""Steps of the road estimate and class flips on roads that change class or sit on a boundary.

    .venv/bin/python benchmarks/continuity.py [--speeds 40,72] [--legacy]

Runs the plain-Python plant and the default estimator (no FMI: ``--legacy`` swaps internals,
which the FMU cannot) on two roads: ISO A joined to ISO C at 250 m with a 1.1 m sag curve over
100-400 m (550 m), and an ISO road whose Gd(n0) sits on the B/C boundary (600 m). Prints per
road and speed the online class changes (distance: class) and the largest step of the road
estimate (road_height_est, the profile) beyond the true profile's own change
(harness.metrics.reference_profile of the road), |d est - d true| per 1 ms step, after the first
50 m (the start transient) and within 2 m of a class change. ``--legacy`` emulates the behaviour
before class hysteresis (hysteresis 0).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import suspension_estimation.estimators.road_class as road_class  # noqa: E402
from suspension_estimation.estimators.suspension import SuspensionEstimator  # noqa: E402
from suspension_estimation.harness.metrics import reference_profile  # noqa: E402
from suspension_estimation.harness.testroads import add_sag, joined_iso  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import MeasuredRoad, SyntheticRoad  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

H = 1e-3


def drive(road, speed: float, length: float) -> np.ndarray:
    """Columns: distance m, true profile m (metrics.reference_profile), estimate m, online class."""
    car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(), noise_seed=1)
    car.settle(road.height(0.0))
    est = SuspensionEstimator()
    n = int(length / speed / H)
    out = np.empty((n, 4))
    for k in range(n):
        s = speed * (k + 1) * H
        r = road.height(s)
        car.step(r, H)
        o = est.step(*car.measured, speed, H)
        out[k] = (s, r, o["road_height_est"], o["road_class_est"])
    out[:, 1] = reference_profile(out[:, 0], out[:, 1])  # what road_height_est estimates
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", default="40,72", help="km/h")
    ap.add_argument("--legacy", action="store_true", help="no class hysteresis")
    args = ap.parse_args(argv)
    if args.legacy:
        road_class.RoadClassifier.__init__.__defaults__ = (*road_class.RoadClassifier.__init__.__defaults__[:-1], 0.0)
    s, h = joined_iso([1, 3], [250.0, 300.0])
    roads = {"A->C + 1.1 m sag": (MeasuredRoad(s, add_sag(s, h, 100.0, 300.0, 1.1)), 540.0),
             "B/C boundary": (SyntheticRoad(2 * iso8608.class_psd_n0(2), seed=4), 600.0)}
    print("| road | km/h | class changes (m: class) | max step after 50 m, mm | max step within 2 m of a change, mm |")
    print("|---|---|---|---|---|")
    for name, (road, length) in roads.items():
        for kmh in (float(x) for x in args.speeds.split(",")):
            out = drive(road, kmh / 3.6, length)
            step = np.abs(np.diff(out[:, 2]) - np.diff(out[:, 1]))
            d = out[1:, 0]
            changes = np.flatnonzero(np.diff(out[:, 3]) != 0) + 1
            near = np.zeros(len(step), bool)
            for i in changes:
                near |= np.abs(d - out[i, 0]) < 2.0
            text = ", ".join(f"{out[i, 0]:.0f}: {iso8608.class_name(int(out[i, 3]))}" for i in changes)
            print(f"| {name} | {kmh:g} | {text} | {1e3 * step[d > 50].max():.3f} | "
                  f"{1e3 * step[near].max() if near.any() else float('nan'):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
