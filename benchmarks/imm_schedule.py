"""Does the road-class schedule of the IMM's Q help? ``.venv/bin/python benchmarks/imm_schedule.py
[--seeds N] [--segment S] [--codes 2,4]``, on the plain-Python cores (no FMI).

Plant ``plant.quarter_car.QuarterCar`` (the default vehicle, its default sensors), 20 m/s, 1 ms,
sprung mass 425 kg (between the fixed bank's models) then 325 kg half-way; the road runs through
ISO A, B, C, D, ``--segment`` s each (``plant.road.SyntheticRoad``, each segment shifted to start
where the previous ended). ``SuspensionEstimator`` with ``road_estimator`` 0 and ``mass_estimator``
2 or 4, the sub-models' road intensity from:

- "F (default)": ISO class max(identified, q_class_min = 6): F on every road up to F;
- "identified": the class the online classifier (eqs. 33-37, road_class.py) identifies, from
  ``default_class`` C until its first window (q_class_min = 1);
- "true class": the road's class, told per segment (q_class_min = 1): the best the schedule can do.

Per segment: mean |mass error| over its last 40 %, the HP road error (100 std(HP error) /
std(HP truth), HP as the harness's, from 2 s after the segment start; road_height_est, the
profile, against ``harness.metrics.reference_profile`` of the whole road) and the share of
samples at the right online class. Prints a markdown table, means over seeds.
"""
from __future__ import annotations

import os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.estimators.suspension import SuspensionEstimator  # noqa: E402
from suspension_estimation.harness.metrics import highpass, reference_profile  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

H = 1e-3
SPEED = 20.0
CLASSES = (1, 2, 3, 4)
SCHEDULES = {"F (default)": {}, "identified": {"q_class_min": 1}, "true class": {"q_class_min": 1}}


def run(seed: int, segment: float, code: int) -> dict:
    n_seg = int(round(segment / H))
    roads = [SyntheticRoad(iso8608.class_psd_n0(c), seed=10 * seed + i) for i, c in enumerate(CLASSES)]
    n = n_seg * len(CLASSES)
    mass = np.where(np.arange(n) < n // 2, 425.0, 325.0)
    heights = np.empty(n)
    z0 = 0.0
    for i, r in enumerate(roads):
        s = SPEED * (np.arange(n_seg) + 1) * H
        z = np.array([r.height(x) for x in s])
        heights[i * n_seg:(i + 1) * n_seg] = z - r.height(0.0) + z0
        z0 = heights[(i + 1) * n_seg - 1]
    plant = QuarterCar(DEFAULT_VEHICLE.with_(m_s=425.0), SensorNoise(), noise_seed=1000 + seed)
    plant.settle(0.0)
    meas = np.empty((n, 3))
    for k in range(n):
        plant.step(heights[k], H, m_s=float(mass[k]))
        meas[k] = plant.measured
    hp_truth = highpass(reference_profile(SPEED * (np.arange(n) + 1) * H, heights), H)  # what road_height_est estimates
    out = {}
    for name, extra in SCHEDULES.items():
        est = SuspensionEstimator(road_estimator=0, mass_estimator=code, **extra)
        m, q, cls = np.empty(n), np.empty(n), np.empty(n)
        for k in range(n):
            if name == "true class":
                est.composed.cfg.road_class = CLASSES[k // n_seg]  # the class told per segment
            o = est.step(*meas[k], SPEED, H)
            m[k], q[k], cls[k] = o["sprung_mass_est"], o["road_height_est"], o["road_class_est"]
        hp = highpass(q, H)
        segs = []
        for i, c in enumerate(CLASSES):
            a, b = i * n_seg, (i + 1) * n_seg
            tail = slice(b - int(0.4 * n_seg), b)
            scored = slice(a + int(2.0 / H), b)
            e = hp[scored] - hp_truth[scored]
            after = slice(a + int(102.4 / SPEED / H), b)
            segs.append((float(np.mean(np.abs(m[tail] - mass[tail]) / mass[tail]) * 100),
                         float(100 * np.std(e) / np.std(hp_truth[scored])), float(np.mean(cls[after] == c))))
        out[name] = segs
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--segment", type=float, default=20.0, help="s per ISO class (default 20)")
    ap.add_argument("--codes", default="2,4", help="mass_estimator codes (default 2,4)")
    args = ap.parse_args()
    print(f"seeds 1..{args.seeds}, {args.segment:g} s per class at {SPEED:g} m/s, 425 kg then 325 kg; means over seeds\n")
    print("| mass_estimator | sub-models' Q from | ISO | steady mass error % | HP road error % | class right % |")
    print("|---|---|---|---|---|---|")
    for code in (int(c) for c in args.codes.split(",")):
        res = [run(s, args.segment, code) for s in range(1, args.seeds + 1)]
        for name in SCHEDULES:
            for i, c in enumerate(CLASSES):
                v = np.array([r[name][i] for r in res])
                print(f"| {code} | {name} | {iso8608.CLASSES[c - 1]} | {v[:, 0].mean():.2f} | {v[:, 1].mean():.2f} | "
                      f"{100 * v[:, 2].mean():.1f} |")


if __name__ == "__main__":
    main()
