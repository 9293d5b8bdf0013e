"""The road error that a wrong k_t, m_u or k_s puts into ANY estimator that uses them.

    .venv/bin/python benchmarks/identifiability_floor.py [--classes 2,3,4] [--speeds 40,80] [--seeds 1-3]

The road is the wheel's position plus the tyre deflection, z_r = z_u + F_t/k_t with the tyre force
F_t = m_s a_s + m_u a_u (the force balance of the corner, any spring and damper). The wheel
equation is the only one that carries the unknown road, so the measured signals (a_s, a_u, d)
fix k_t and m_u only through what is assumed about the road: they are not identifiable from the
sensors. And the body equation fixes k_s/m_s, not m_s: with k_s off by x %, the identified mass
and hence the m_s a_s term are off by x %. An estimator told k_t, m_u or m_s off by a fraction e
therefore carries, to first order, the error e times one term of the tyre deflection.

This script runs the exact linear plant (the contract's default vehicle) on ISO roads, 1 ms,
40 s, and prints, as % of the std of the high-passed true road (harness.metrics, 0.5 Hz, after
10 s), the std of the high-passed error terms e (z_r - z_u) for k_t +-10 %, e m_u a_u / k_t for
m_u +-15 % and e m_s a_s / k_t for m_s (k_s) +-15 %, and the quadrature sum with a given
exact-vehicle error (default 2.5 %, the default estimator's on the exact vehicle): the HP error
floor of each robustness case. The measured errors of that study are within a few tenths of
these floors (docs/robustness.md).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.harness.metrics import highpass  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE as V  # noqa: E402

H, T, WARMUP = 1e-3, 40.0, 10.0
TERMS = (("k_t", 0.10), ("m_u", 0.15), ("k_s (m_s)", 0.15))


def floors(cls: int, speed: float, seed: int) -> list[float]:
    """HP error std % of the true HP road for each of TERMS, one run."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    car = QuarterCar(V, SensorNoise(), noise_seed=1000 + seed)
    car.settle(road.height(0.0))
    n = int(round(T / H))
    zr, zu, a_s, a_u = (np.empty(n) for _ in range(4))
    for k in range(n):
        car.step(road.height(speed * (k + 1) * H), H)
        zr[k], zu[k] = car.road, car.x[2]
        a_s[k], a_u[k] = car.measured[0], car.measured[1]
    cut = int(round(WARMUP / H))

    def pct(s: np.ndarray) -> float:
        return float(100 * np.std(highpass(s, H)[cut:]) / np.std(highpass(zr, H)[cut:]))

    terms = (zr - zu, V.m_u * a_u / V.k_t, V.m_s * a_s / V.k_t)
    return [pct(e * s) for (_, e), s in zip(TERMS, terms)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--classes", default="2,3,4", help="ISO classes, 1 = A")
    ap.add_argument("--speeds", default="40,80", help="km/h")
    ap.add_argument("--seeds", default="1-3", help="first-last")
    ap.add_argument("--exact", type=float, default=2.5, help="HP error %% on the exact vehicle")
    a = ap.parse_args()
    lo, hi = (int(s) for s in a.seeds.split("-"))
    print("| class | km/h | " + " | ".join(f"{n} +-{100 * e:.0f} %: term, floor" for n, e in TERMS) + " |")
    print("|---|---|" + "---|" * len(TERMS))
    for cls in (int(c) for c in a.classes.split(",")):
        for kmh in (float(s) for s in a.speeds.split(",")):
            f = np.mean([floors(cls, kmh / 3.6, s) for s in range(lo, hi + 1)], axis=0)
            cells = [f"{x:.2f}, {np.hypot(x, a.exact):.2f}" for x in f]
            print(f"| {'ABCDEFGH'[cls - 1]} | {kmh:.0f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
