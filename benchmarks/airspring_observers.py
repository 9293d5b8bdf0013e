"""Paper 003's observers on the nonlinear plant core: road error, in-band gain, mass, cost.

    .venv/bin/python benchmarks/airspring_observers.py [--seconds 30] [--classes 2,3,4] [--seed 1]

The default nonlinear car (air spring, asymmetric damper; 410 kg) with the default sensor noise on
ISO roads at 40 km/h, 1 ms steps. Filters (estimators/airspring_observers.py): the EKF and the UKF
told the plant's force laws; the EKF told only the linearisation at the static point (a linear
KF); the EKF with the mass 20 % high and no mass estimation; the dual observer starting 20 % high;
and today's default SuspensionEstimator, told the contract's linear defaults (the static point).
Road scores as harness.metrics.road_scores (HP error in % of the HP true profile, in-band gain)
after a 10 s warm-up: the default's road_height_est (the profile) as it is, the observers' road
state made a profile as the estimator makes its own (metrics.reference_profile: the high-pass in
distance; they have no common-mode reference to take off); the mass at the end of the run; the
filter's time per step on this machine.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the test's ride and noise


def run(cls: int, seconds: float, seed: int) -> list[tuple]:
    from suspension_estimation.estimators import EstimatorConfig, SuspensionEstimator
    from suspension_estimation.estimators.airspring_observers import EKF, UKF, DualObserver, NonlinearModel
    from suspension_estimation.harness.metrics import reference_profile, road_scores
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE as V
    from test_airspring_observers import SPEED as speed, R, ride

    h, gd = 0.001, iso8608.class_psd_n0(cls)
    t, meas, z = ride(h, seconds, seed, gd)
    n = len(t)
    d = speed * t  # m travelled at each sample
    nl = NonlinearModel(V, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, speed, gd)
    linear = NonlinearModel(V, None, None, speed, gd)
    filters = {
        "EKF, plant's laws": EKF(nl, h, R, V.m_s),
        "UKF, plant's laws": UKF(nl, h, R, V.m_s),
        "linear KF, static point": EKF(linear, h, R, V.m_s),
        "EKF, mass +20 %": EKF(nl, h, R, 1.2 * V.m_s),
        "dual observer, start +20 %": DualObserver(nl, h, R, 1.2 * V.m_s),
    }
    default = SuspensionEstimator(EstimatorConfig())  # told the contract's linear defaults
    filters["today's default estimator"] = default
    rows = []
    for name, f in filters.items():
        t0 = time.perf_counter()
        if f is default:
            est = np.empty(n)
            for k, m in enumerate(meas):
                out = f.step(*m, speed, h)  # the same dict each step: read it now
                est[k], mass = out["road_height_est"], out["sprung_mass_est"]
        else:
            est = np.array([f.step(m)[4] for m in meas])
            mass = f.mass if isinstance(f, DualObserver) else f.m_s
        us = (time.perf_counter() - t0) / n * 1e6
        if f is not default:
            est = reference_profile(d, est)  # the road state made a profile, as the estimator makes its own
        s = road_scores(t, est, z, warmup=10.0, distance=d)
        rows.append((name, iso8608.class_name(cls), s["err_std_hp_pct"], s["gain_hp"], mass, us))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--classes", default="2,3,4", help="ISO classes, 1..8 = A..H")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    try:
        classes = [int(c) for c in args.classes.split(",")]
    except ValueError:
        print(f"--classes {args.classes!r}: expected comma-separated integers 1..8", file=sys.stderr)
        return 2
    print("| filter | ISO | HP error % | in-band gain | mass at the end (kg) | us/step |")
    print("|---|---|---|---|---|---|")
    for cls in classes:
        for name, c, hp, gain, mass, us in run(cls, args.seconds, args.seed):
            print(f"| {name} | {c} | {hp:.1f} | {gain:.3f} | {mass:.1f} | {us:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
