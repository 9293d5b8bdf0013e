"""The IMM of paper 002 on and off its grid, against the moving-bank IMM and the RLS mass, on the
plain-Python cores (no FMI): ``.venv/bin/python benchmarks/imm_offgrid.py [--seeds N] [--classes B,C,D]``.

Plant ``plant.quarter_car.QuarterCar`` (the default vehicle, sensors 0.02 / 0.2 m/s^2, 0.1 mm) on an
ISO 8608 road (``plant.road.SyntheticRoad``) at 40 km/h, 1 ms, its sprung mass stepping every
``--segment`` s through a schedule (kg): "off grid" 412.5 -> 312.5 -> 487.5 -> 262.5 -> 537.5,
"on grid" 400 -> 300 -> 500 -> 250 -> 550. On the same measurements:

- "IMM 50 kg": ``estimators.imm.MassIMM`` over 250..550 kg in 50 kg steps (7 models, paper 002's
  spacing), transition probability 0.999 to stay, equal initial probabilities; the mass is the
  probability-weighted one;
- "moving IMM": ``estimators.imm.MovingMassIMM`` with its defaults (5 models, spacing 1-12.5 %,
  50-400 ms windows; ``--edge-recent``: its edge test on the last 50 ms instead of the sum since
  the bank was built), starting at 400 kg;
- "RLS": ``estimators.mass.MassEstimator`` (the default mass estimator), starting at 400 kg;
  "RLS m, c" the same with ``estimate_damping`` (paper 001's theta = [m_s, c]).

Every estimator is told the vehicle's nominal c_s = 2000 N.s/m; with ``--damping -0.2`` the
plant's is 20 % lower. The sub-models' road: spatial corner ``--n-hi`` (default 30 1/m, a pole at
2.1e3 rad/s at 40 km/h) and the intensity of ISO class ``--q-class`` (default F, as the default road
filter's q_class_min).

Per segment: steady error = mean |error| over its last 40 %, settling = time after the step
until the estimate stays within ±5 % (the harness's band for paper 001). Prints markdown per
schedule, ISO class and estimator: mean and worst over seeds and segments, and the share of segments meeting the
targets (steady <= 1 %, settling <= 0.5 s; <= 2 % steady with the damping off).
"""
from __future__ import annotations

import os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.estimators.imm import MassIMM, MovingMassIMM  # noqa: E402
from suspension_estimation.estimators.mass import MassEstimator  # noqa: E402
from suspension_estimation.estimators.model import RoadModel  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

H = 1e-3  # s
SPEED = 11.1111  # m/s
STD = (0.02, 0.2, 1e-4)  # m/s2, m/s2, m
SCHEDULES = {"off grid": (412.5, 312.5, 487.5, 262.5, 537.5), "on grid": (400.0, 300.0, 500.0, 250.0, 550.0)}
GRID = tuple(np.arange(250.0, 551.0, 50.0))  # kg
BAND = 0.05
STEADY_FRACTION = 0.4


def run(masses: tuple[float, ...], road_class: int, seed: int, segment: float, damping: float,
        n_hi: float = 30.0, q_class: int = 6, edge_recent: bool = False) -> dict:
    """Mass estimates of the estimators on one run; per-estimator arrays and µs per step."""
    gd_q, road_model = iso8608.class_psd_n0(q_class), RoadModel(n_hi=n_hi)
    est = {"IMM 50 kg": MassIMM(GRID, DEFAULT_VEHICLE, SPEED, gd_q, H, STD, P0=1e-4 * np.eye(6), road=road_model),
           "moving IMM": MovingMassIMM(400.0, DEFAULT_VEHICLE, SPEED, gd_q, H, STD, P0=1e-4 * np.eye(6),
                                       road=road_model, edge_recent=edge_recent),
           "RLS": MassEstimator(400.0, DEFAULT_VEHICLE.k_s, DEFAULT_VEHICLE.c_s),
           "RLS m, c": MassEstimator(400.0, DEFAULT_VEHICLE.k_s, DEFAULT_VEHICLE.c_s, estimate_damping=True)}
    plant = QuarterCar(DEFAULT_VEHICLE.with_(c_s=DEFAULT_VEHICLE.c_s * (1 + damping)), SensorNoise(*STD),
                       noise_seed=1000 + seed)
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    plant.settle(road.height(0.0))
    n = int(round(len(masses) * segment / H))
    true = np.repeat(np.array(masses, float), int(round(segment / H)))
    out = {k: np.zeros(n) for k in est}
    cost = dict.fromkeys(est, 0.0)
    for k in range(n):
        plant.step(road.height(SPEED * (k + 1) * H), H, m_s=float(true[k]))
        z = np.array(plant.measured)
        for name, e in est.items():
            t0 = time.perf_counter()
            if name.startswith("RLS"):
                e.update(z[0], z[2], H)
            else:
                e.step(z)
            cost[name] += time.perf_counter() - t0
            out[name][k] = e.mass
    return {"true": true, "est": out, "us": {k: 1e6 * v / n for k, v in cost.items()}}


def segments(true: np.ndarray, est: np.ndarray, segment: float) -> list[tuple[float, float]]:
    """(steady error %, settling time s) of each segment."""
    n = int(round(segment / H))
    res = []
    for i in range(len(true) // n):
        m = true[i * n]
        err = 100 * (est[i * n:(i + 1) * n] - m) / m
        steady = float(np.mean(np.abs(err[int(round((1 - STEADY_FRACTION) * n)):])))
        out = np.nonzero(np.abs(err) > 100 * BAND)[0]
        res.append((steady, (out[-1] + 1) * H if len(out) else 0.0))
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--classes", default="B,C,D")
    ap.add_argument("--segment", type=float, default=3.0, help="s per mass (default 3)")
    ap.add_argument("--damping", type=float, default=0.0, help="relative error of the plant's c_s (default 0)")
    ap.add_argument("--n-hi", type=float, default=30.0, help="sub-models' road corner, 1/m (default 30)")
    ap.add_argument("--q-class", type=int, default=6, help="sub-models' road intensity, ISO class 1..8 (default 6, F)")
    ap.add_argument("--edge-recent", action="store_true",
                    help="moving IMM: edge test on the last window only, not the sum since the bank was built")
    args = ap.parse_args()
    classes = [iso8608.CLASSES.index(c.strip().upper()) + 1 for c in args.classes.split(",")]
    rows: dict[tuple[str, int, str], list[tuple[float, float]]] = {}
    us: dict[str, list[float]] = {}
    for sched, masses in SCHEDULES.items():
        for c in classes:
            for s in range(1, args.seeds + 1):
                r = run(masses, c, s, args.segment, args.damping, args.n_hi, args.q_class, args.edge_recent)
                for name, m in r["est"].items():
                    rows.setdefault((sched, c, name), []).extend(segments(r["true"], m, args.segment))
                    us.setdefault(name, []).append(r["us"][name])
    steady_target = 1.0 if args.damping == 0 else 2.0
    print(f"classes {args.classes}, seeds 1..{args.seeds}, {args.segment:g} s segments, plant c_s "
          f"{100 * args.damping:+g} %, sub-models' road n_hi {args.n_hi:g} 1/m and class "
          f"{iso8608.CLASSES[args.q_class - 1]}; steady = mean |error| over the last 40 % of a segment, settling to ±5 %\n")
    print("| schedule | ISO | estimator | steady % mean | steady % worst | settling s mean | settling s worst | "
          f"segments with steady ≤ {steady_target:g} % and settling ≤ 0.5 s | µs/step |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (sched, c, name), v in rows.items():
        a = np.array(v)
        ok = np.mean((a[:, 0] <= steady_target) & (a[:, 1] <= 0.5))
        print(f"| {sched} | {iso8608.CLASSES[c - 1]} | {name} | {a[:, 0].mean():.2f} | {a[:, 0].max():.2f} | {a[:, 1].mean():.2f} | "
              f"{a[:, 1].max():.2f} | {100 * ok:.0f} % of {len(a)} | {np.median(us[name]):.0f} |")


if __name__ == "__main__":
    main()
