"""Paper 002's closed loop over the weight schedule's 100 working conditions, on the cores: the
scheduled LQR fed by the half car's observer, against the same LQR fed by the true states
(docs/paper-reproductions.md quotes it).

    .venv/bin/python benchmarks/half_car_loop_grid.py [--duration 20] [--step 0.01] [--estimator 4] [--seed 1]
        [--force-error-q 100] [--plant-error k_f=0.85,k_r=0.85] [--speeds 10,30] [--classes B,D]
        [--masses 504,672,840]

Conditions: controllers.schedule_train's grid, speed 10-30 m/s x ISO A-D x sprung mass 0.75-1.25 of
HalfCar's default side (504-840 kg), or the subset of it that ``--speeds``, ``--classes`` and
``--masses`` (kg) pick. Plant: plant.half_car.HalfCar at that mass (passive dampers, sensor
noise), on an ISO 8608 road of the class, the rear tyre a wheelbase behind, from rest; with
``--plant-error`` its other HalfCarParams scaled (the plant's only: the observer and the
controller are told DEFAULT_HALF_CAR, and the condition's mass in the true-state loop).
Loops at ``--step`` (the FMUs' Gauss-Seidel order: plant, observer, controller; the force of a
step is the controller's of the step before): the scheduled LQR (controllers.controller, mode 2,
force limit 3 kN) on the true relative states told the true speed, class and mass, and on
HalfCarObserver's estimates (``--estimator`` and ``--force-error-q``, N^2/s, 0 = the paper's
10-state model; its defaults otherwise: IMMAKF5, the real car's sensors), told its own class and
mass estimates. Per condition after the first quarter: the body acceleration RMS at the centre of
gravity of both loops and their ratio, the peak deflection of both loops, whether every value
stayed finite, and the observer's final mass estimate; then the largest ratio and deflection over
the grid and the range of the final mass estimates. Exit code 0 iff everything stayed finite and every peak
deflection is below eq. 17's 0.15 m.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import fields
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
        seed: int, force_error_q: float = ObserverSettings.force_error_q) -> dict:
    """One loop on a plant ``p`` (the observer and the controller are told DEFAULT_HALF_CAR):
    ``estimator`` None = the true states. Returns the CG body acceleration RMS (m/s2) and the
    peak |deflection| (m) after the first quarter, whether everything stayed finite, and the
    mass the controller was told last (kg: the observer's final estimate, or p.m_s)."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    L = p.wheelbase
    car = HalfCar(p, SensorNoise(), noise_seed=1000 + seed)
    car.settle(road.height(0.0), road.height(-L))
    ctl = SuspensionController(DEFAULT_HALF_CAR, LQR_SCHEDULED, FORCE_LIMIT)
    obs = (HalfCarObserver(DEFAULT_HALF_CAR, ObserverSettings(estimator=estimator, force_error_q=force_error_q))
           if estimator is not None else None)
    n = int(round(duration / h))
    acc, defl = np.empty(n), np.empty(n)
    force, mass_told = (0.0, 0.0), p.m_s
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
            "finite": bool(np.all(np.isfinite(acc)) and np.all(np.isfinite(defl))), "mass_est": mass_told}


def parse_plant_error(text: str) -> dict[str, float]:
    """``NAME=SCALE[,NAME=SCALE...]`` -> {field: scale}; ValueError with a one-line message."""
    names = [f.name for f in fields(HalfCarParams) if f.name != "m_s"]
    out = {}
    for item in filter(None, text.split(",")):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise ValueError(f"--plant-error: {item!r} is not NAME=SCALE with NAME one of {', '.join(names)} "
                             "(m_s is the condition's: --masses)")
        try:
            scale = float(value)
        except ValueError:
            scale = float("nan")
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"--plant-error: the scale of {name} must be a positive number, not {value!r}")
        out[name] = scale
    return out


def parse_subset(text: str | None, grid: tuple, label: str, convert, names: tuple | None = None) -> tuple:
    """A comma-separated subset of ``grid`` (``convert`` maps an item to a grid value, ``names``
    are the grid's values as the user writes them), or the grid."""
    if text is None:
        return grid
    try:
        values = [convert(item.strip()) for item in text.split(",") if item.strip()]
    except (ValueError, OverflowError):
        values = [None]
    if not values or any(v not in grid for v in values):
        raise ValueError(f"--{label} {text!r}: pick from {', '.join(names or [f'{v:g}' for v in grid])}")
    return tuple(v for v in grid if v in values)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="s per condition")
    ap.add_argument("--step", type=float, default=0.01, help="s")
    ap.add_argument("--estimator", type=int, default=4, help="HalfCarObserver's code (0 KF ... 4 IMMAKF5)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--force-error-q", type=float, default=ObserverSettings.force_error_q,
                    help="N^2/s, the observer's force-error intensity (0 = the paper's model)")
    ap.add_argument("--plant-error", default="", help="NAME=SCALE[,...]: the plant's HalfCarParams scaled")
    ap.add_argument("--speeds", help="m/s, comma-separated, from the grid's (default all)")
    ap.add_argument("--classes", help="ISO classes A-D, comma-separated (default all)")
    ap.add_argument("--masses", help="kg, comma-separated, from the grid's (default all)")
    a = ap.parse_args(argv)
    if not (a.duration > 0 and 0 < a.step <= 0.015 and a.estimator in range(5)
            and np.isfinite(a.force_error_q) and a.force_error_q >= 0):
        print("error: --duration must be > 0, --step in (0, 0.015] s, --estimator 0-4 and --force-error-q >= 0",
              file=sys.stderr)
        return 1
    masses = tuple(round(frac * DEFAULT_HALF_CAR.m_s) for frac in MASS_FRACTIONS)
    try:
        errors = parse_plant_error(a.plant_error)
        speeds = parse_subset(a.speeds, SPEEDS, "speeds", float)
        classes = parse_subset(a.classes, CLASSES, "classes",
                               lambda c: "ABCD".index(c.upper()) + 1 if len(c) == 1 else 0, tuple("ABCD"))
        masses = parse_subset(a.masses, masses, "masses", lambda m: round(float(m)))
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    plant = DEFAULT_HALF_CAR.with_(**{name: scale * getattr(DEFAULT_HALF_CAR, name) for name, scale in errors.items()})
    if problems := plant.problems():
        print(f"error: --plant-error gives a plant out of range: {'; '.join(problems)}", file=sys.stderr)
        return 1
    told = ", ".join(f"{name} x{scale:g}" for name, scale in errors.items()) or "none"
    print(f"estimator {a.estimator}, force_error_q {a.force_error_q:g} N^2/s, plant error {told}, "
          f"{a.duration:g} s at {a.step:g} s, seed {a.seed}\n")
    print("| m/s | ISO | kg | acc RMS true states | acc RMS estimated | ratio | peak deflection mm true states "
          "| peak deflection mm estimated | finite | mass est kg |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    worst_ratio, worst_defl, all_finite, mass_ests = 0.0, [0.0, 0.0], True, []
    for speed in speeds:
        for cls in classes:
            for m_s in masses:
                p = plant.with_(m_s=float(m_s))
                true = run(p, cls, speed, a.duration, a.step, None, a.seed)
                est = run(p, cls, speed, a.duration, a.step, a.estimator, a.seed, a.force_error_q)
                ratio = est["acc_rms"] / true["acc_rms"]
                finite = true["finite"] and est["finite"]
                worst_ratio = max(worst_ratio, ratio)
                worst_defl = [max(worst, r["defl_peak"]) for worst, r in zip(worst_defl, (true, est))]
                all_finite &= finite
                mass_ests.append(est["mass_est"])
                print(f"| {speed:g} | {'ABCD'[cls - 1]} | {p.m_s:.0f} | {true['acc_rms']:.4f} | {est['acc_rms']:.4f} | "
                      f"{ratio:.3f} | {1e3 * true['defl_peak']:.1f} | {1e3 * est['defl_peak']:.1f} | {finite} | "
                      f"{est['mass_est']:.0f} |", flush=True)
    print(f"\nlargest ratio {worst_ratio:.3f}, largest deflection {1e3 * max(worst_defl):.1f} mm (true states "
          f"{1e3 * worst_defl[0]:.1f}, estimated {1e3 * worst_defl[1]:.1f}; limit {1e3 * DEFLECTION_LIMIT:g}), "
          f"finite everywhere: {all_finite}, final mass estimates {min(mass_ests):.0f}-{max(mass_ests):.0f} kg")
    return 0 if all_finite and max(worst_defl) < DEFLECTION_LIMIT else 1


if __name__ == "__main__":
    sys.exit(main())
