"""Logging at 100 Hz-1 kHz on a road that is not held: the estimators on a car simulated finely
(0.5 ms, the road moving linearly between its samples: plant.quarter_car.LINEAR) and logged at a
coarser step, against the same car simulated at the logging step with the road held over it,
which is the estimator's own model of the averaged sensors (``road_hold``) and how the project's
other figures are measured. docs/real-sensors.md quotes it.

    .venv/bin/python benchmarks/logging_rates.py [--plant exact|nonlinear] [--classes C] [--speeds 40]
        [--seeds 1] [--duration 30] [--steps 1,2,5,10] [--set '{"mass_feedback": false}'] [--steady]

The logger reads the accelerations at the sample (point, acc_sampling 0) or their mean over the
sample, (v[k] - v[k-1]) / h (averaged, acc_sampling 1), and the deflection at the sample, with the
white noise of plant.quarter_car.SensorNoise drawn per logged sample. Columns after the 10 s
warm-up (harness.metrics.road_scores): HP error %, its ratio to the same sampling at 1 ms on the
same plant, the +-2 road_height_std coverage of the profile's error, the mean sprung-mass error %.
The estimator is told the exact vehicle (the linearisation for the air-spring plant) and the
sampling; everything else at its defaults or ``--set``.

``--steady``: instead, the steady-state KF of the exact model (road_estimator 0's filter, Q of
class max(class, q_class_min), no simulation: estimators.steady_state.analyse) on either plant,
for each sampling and road model (``road_hold``): the HP error %, and its parts from the road
(the filter's transfer) and from the sensor noise.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import robust_cores  # noqa: E402

from suspension_estimation.estimators import SuspensionEstimator  # noqa: E402
from suspension_estimation.estimators.model import DiscreteModel, measurement_covariance  # noqa: E402
from suspension_estimation.estimators.steady_state import analyse, steady_gain  # noqa: E402
from suspension_estimation.estimators.tuning import TUNING  # noqa: E402
from suspension_estimation.harness.metrics import road_scores  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar  # noqa: E402
from suspension_estimation.plant.quarter_car import HELD, LINEAR, QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

FINE = 5e-4  # s, the fine plant's step
WARMUP = 10.0  # s
QUIET = SensorNoise(0.0, 0.0, 0.0)


def make_car(plant: str, road_input: str, acc_sampling: int):
    if plant == "nonlinear":
        car = NonlinearQuarterCar(DEFAULT_VEHICLE, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, noise=QUIET,
                                  acc_sampling=acc_sampling, road_input=road_input)
        return car, car.linearisation()
    return QuarterCar(DEFAULT_VEHICLE, QUIET, acc_sampling=acc_sampling, road_input=road_input), DEFAULT_VEHICLE


def log(plant: str, fine: bool, cls: int, speed: float, duration: float, seed: int, h: float, acc_sampling: int):
    """(t, logged measurements n x 3, true road at each sample, the vehicle the estimator is told).
    ``fine``: simulated at FINE with the road moving linearly; else at h with the road held (the
    road at the start of the step, as the harness's co-simulation gives it)."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    car, told = make_car(plant, LINEAR if fine else HELD, acc_sampling if not fine else 0)
    car.settle(road.height(0.0))
    m = int(round(h / FINE)) if fine else 1
    n = int(round(duration / h))
    rng = np.random.default_rng(1000 + seed)
    noise = SensorNoise()
    meas, zr = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        v0 = car.x[[1, 3]].copy()
        if fine:
            for j in range(m):
                car.step(road.height(speed * (k * m + j + 1) * FINE), FINE)
            acc = (car.x[[1, 3]] - v0) / h if acc_sampling == 1 else np.array(car.acc_true)
        else:
            car.step(road.height(speed * k * h), h)
            acc = np.array(car.acc_true)
        e = rng.standard_normal(3)
        meas[k] = (acc[0] + noise.acc_sprung * e[0], acc[1] + noise.acc_unsprung * e[1],
                   car.x[0] - car.x[2] + noise.deflection * e[2])
        zr[k] = car.road
    return np.arange(1, n + 1) * h, meas, zr, told


def score(t, meas, zr, told, speed: float, h: float, acc_sampling: int, **kw) -> dict:
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s,
                              acc_sampling=acc_sampling, **kw)
    out = np.array([[o["road_height_est"], o["road_height_std"], o["sprung_mass_est"]]
                    for o in (dict(est.step(*z, speed, h)) for z in meas)])
    s = road_scores(t, out[:, 0], zr, out[:, 1], warmup=WARMUP, distance=speed * t)
    s["mass_pct"] = float(100 * (np.mean(out[t >= WARMUP, 2]) / told.m_s - 1))
    return s


def steady(cls: int, speed: float, steps: list[float]) -> None:
    """The --steady table (module doc)."""
    noise = SensorNoise()
    R = measurement_covariance(noise.acc_sprung, noise.acc_unsprung, noise.deflection)
    gd_q = iso8608.class_psd_n0(max(cls, TUNING.q_class_min))
    print("| road in the plant | sampling | road held in the model | step | HP % | from the road | from the noise |")
    print("|---|---|---|---|---|---|---|")
    for road_input in (LINEAR, HELD):
        for acc, hold in ((0, False), (1, True), (1, False)):
            for h in steps:
                m = DiscreteModel.build(DEFAULT_VEHICLE, speed, gd_q, h, TUNING.road_model, acc_sampling=acc,
                                        road_hold=hold)
                K, _ = steady_gain(m, R)
                r = analyse(m.Phi, m.H, K, R, h, iso8608.class_psd_n0(cls), speed,
                            f=np.geomspace(1e-3, 0.499 / h, 3000), acc_sampling=acc, road_input=road_input)
                print(f"| {road_input} | {'averaged' if acc else 'point'} | {'yes' if hold else 'no'} | {1e3 * h:g} ms | "
                      f"{r['hp_pct']:.2f} | {r['hp_signal_pct']:.2f} | {r['hp_noise_pct']:.2f} |", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    robust_cores.grid_arguments(ap)
    ap.add_argument("--steps", default="1,2,5,10", help="logging steps, ms (multiples of 0.5; 1 first)")
    ap.add_argument("--set", default="{}", help='extra estimator keywords as JSON, e.g. \'{"mass_feedback": false}\'')
    ap.add_argument("--steady", action="store_true", help="the steady-state KF instead of simulations")
    a = ap.parse_args(argv)
    try:
        extra = json.loads(a.set)
        steps = [float(v) * 1e-3 for v in a.steps.split(",")]
    except ValueError:
        extra, steps = None, []
    if not isinstance(extra, dict) or not steps or any(abs(s / FINE - round(s / FINE)) > 1e-9 or s <= 0 for s in steps) \
            or a.duration <= WARMUP or a.seeds < 1:
        print("error: --set takes a JSON object, --steps positive multiples of 0.5 ms, --duration > 10 s, "
              "--seeds >= 1", file=sys.stderr)
        return 1
    if a.steady:
        for letter in a.classes.split(","):
            for kmh in (float(v) for v in a.speeds.split(",")):
                print(f"ISO {letter.upper()}, {kmh:g} km/h, exact linear vehicle\n")
                steady("ABCDEFGH".index(letter.strip().upper()) + 1, kmh / 3.6, steps)
        return 0
    print(f"plant {a.plant}; one row per (class, speed, plant, sampling, step), means over {a.seeds} seed(s)\n")
    print("| ISO | km/h | simulated | sampling | logged | HP % | x first step | cov | mass % |")
    print("|---|---|---|---|---|---|---|---|---|")
    for letter in a.classes.split(","):
        cls = "ABCDEFGH".index(letter.strip().upper()) + 1
        for kmh in (float(v) for v in a.speeds.split(",")):
            v = kmh / 3.6
            for fine in (True, False):
                for acc in (0, 1):
                    first = None
                    for h in steps:
                        rows = [score(*log(a.plant, fine, cls, v, a.duration, seed, h, acc), v, h, acc, **extra)
                                for seed in range(1, a.seeds + 1)]
                        hp, cov, mass = (float(np.mean([r[k] for r in rows]))
                                         for k in ("err_std_hp_pct", "coverage_2sigma", "mass_pct"))
                        first = hp if first is None else first
                        where = "0.5 ms, road linear" if fine else "at the logging step, road held"
                        print(f"| {letter.upper()} | {kmh:g} | {where} | {'averaged' if acc else 'point'} | "
                              f"{1e3 * h:g} ms | {hp:.2f} | {hp / first:.2f} | {cov:.2f} | {mass:+.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
