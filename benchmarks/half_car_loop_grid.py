"""Paper 002's closed loop over the weight schedule's 100 working conditions, on the cores: the
scheduled LQR fed by the half car's observer, against the same LQR fed by the true states
(docs/paper-reproductions.md quotes it).

    .venv/bin/python benchmarks/half_car_loop_grid.py [--duration 20] [--step 0.01] [--estimator 4] [--seed 1]

Conditions: controllers.schedule_train's grid, speed 10-30 m/s x ISO A-D x sprung mass 0.75-1.25 of
HalfCar's default side (504-840 kg). Plant: plant.half_car.HalfCar at that mass (passive dampers,
sensor noise), on an ISO 8608 road of the class, the rear tyre a wheelbase behind, from rest.
Loops at ``--step`` (the FMUs' Gauss-Seidel order: plant, observer, controller; the force of a
step is the controller's of the step before): the scheduled LQR (controllers.controller, mode 2,
force limit 3 kN) on the true relative states told the true speed, class and mass, and on
HalfCarObserver's estimates (``--estimator``, its defaults otherwise: IMMAKF5, the real car's
sensors), told its own class and mass estimates. Per condition after the first quarter: the body
acceleration RMS at the centre of gravity of both loops and their ratio, the peak deflection and
whether every value stayed finite; then the largest ratio and deflection over the grid.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.controllers.controller import LQR_SCHEDULED, SuspensionController  # noqa: E402
from suspension_estimation.controllers.lqr import STATES  # noqa: E402
from suspension_estimation.controllers.schedule_train import CLASSES, MASS_FRACTIONS, SPEEDS  # noqa: E402
from suspension_estimation.estimators.half_car_imm import HalfCarObserver, ObserverSettings  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.half_car import DEFAULT_HALF_CAR, HalfCar, HalfCarParams  # noqa: E402
from suspension_estimation.plant.quarter_car import SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402

FORCE_LIMIT = 3000.0  # N, SuspensionController.fmu's default
DEFLECTION_LIMIT = 0.15  # m, eq. 17


def true_states(car: HalfCar) -> np.ndarray:
    """The plant's relative states in ``lqr.STATES``' order."""
    x = car.x
    return np.array([x[4], x[5], x[6], x[7], *car.deflection_true, *car.tire_deflection_true])


def run(p: HalfCarParams, cls: int, speed: float, duration: float, h: float, estimator: int | None,
        seed: int) -> dict:
    """One loop: ``estimator`` None = the true states. Returns the CG body acceleration RMS (m/s2)
    and the peak |deflection| (m) after the first quarter, and whether everything stayed finite."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    L = p.wheelbase
    car = HalfCar(p, SensorNoise(), noise_seed=1000 + seed)
    car.settle(road.height(0.0), road.height(-L))
    ctl = SuspensionController(DEFAULT_HALF_CAR, LQR_SCHEDULED, FORCE_LIMIT)
    obs = HalfCarObserver(DEFAULT_HALF_CAR, ObserverSettings(estimator=estimator)) if estimator is not None else None
    n = int(round(duration / h))
    acc, defl = np.empty(n), np.empty(n)
    force = (0.0, 0.0)
    for k in range(n):
        s = speed * (k + 1) * h
        car.step(road.height(s), road.height(s - L), h, p.m_s, *force)
        if obs is None:
            state, cls_told, mass_told = true_states(car), cls, p.m_s
        else:
            out = obs.step(car.measured, force, speed, h)
            state = np.array([out[f"{name}_est"] for name in STATES])
            cls_told, mass_told = int(out["road_class_est"]), float(out["sprung_mass_est"])
        force = ctl.command(state, speed, cls_told, mass_told).force
        a_f, a_r = car.acc_true[:2]
        acc[k] = (p.l_r * a_f + p.l_f * a_r) / L
        defl[k] = max(abs(d) for d in car.deflection_true)
    late = slice(n // 4, n)
    return {"acc_rms": float(np.sqrt(np.mean(acc[late] ** 2))), "defl_peak": float(np.max(defl[late])),
            "finite": bool(np.all(np.isfinite(acc)) and np.all(np.isfinite(defl)))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="s per condition")
    ap.add_argument("--step", type=float, default=0.01, help="s")
    ap.add_argument("--estimator", type=int, default=4, help="HalfCarObserver's code (0 KF ... 4 IMMAKF5)")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    if not (a.duration > 0 and 0 < a.step <= 0.015 and a.estimator in range(5)):
        print("error: --duration must be > 0, --step in (0, 0.015] s and --estimator 0-4", file=sys.stderr)
        return 1
    print(f"estimator {a.estimator}, {a.duration:g} s at {a.step:g} s, seed {a.seed}\n")
    print("| m/s | ISO | kg | acc RMS true states | acc RMS estimated | ratio | peak deflection mm | finite |")
    print("|---|---|---|---|---|---|---|---|")
    worst_ratio, worst_defl, all_finite = 0.0, 0.0, True
    for speed in SPEEDS:
        for cls in CLASSES:
            for frac in MASS_FRACTIONS:
                p = DEFAULT_HALF_CAR.with_(m_s=frac * DEFAULT_HALF_CAR.m_s)
                true = run(p, cls, speed, a.duration, a.step, None, a.seed)
                est = run(p, cls, speed, a.duration, a.step, a.estimator, a.seed)
                ratio = est["acc_rms"] / true["acc_rms"]
                defl = max(true["defl_peak"], est["defl_peak"])
                finite = true["finite"] and est["finite"]
                worst_ratio, worst_defl = max(worst_ratio, ratio), max(worst_defl, defl)
                all_finite &= finite
                print(f"| {speed:g} | {'ABCD'[cls - 1]} | {p.m_s:.0f} | {true['acc_rms']:.4f} | {est['acc_rms']:.4f} | "
                      f"{ratio:.3f} | {1e3 * defl:.1f} | {finite} |", flush=True)
    print(f"\nlargest ratio {worst_ratio:.3f}, largest deflection {1e3 * worst_defl:.1f} mm "
          f"(limit {1e3 * DEFLECTION_LIMIT:g}), finite everywhere: {all_finite}")
    return 0 if all_finite and worst_defl < DEFLECTION_LIMIT else 1


if __name__ == "__main__":
    sys.exit(main())
