"""The robustness grid on the plain-Python cores (no FMU): fast, and the only place the nonlinear
plant (air spring + asymmetric damper, plant/nonlinear_car.py) is measured so far.

    .venv/bin/python benchmarks/robust_cores.py [--classes C] [--speeds 40,80] [--seeds 1] [--seed0 1]
        [--duration 60] [--cases exact,c_s -30%,...,nonlinear] [--estimators "default;KF (0)"]
        [--set '{"refilter_span": 4}'] [--std-scales 1.1,1.2,1.3] [--spread]

Plant: plant.QuarterCar with the vehicle of each case of harness/studies/robust.py, or
plant.NonlinearQuarterCar with the default air spring and damper ("nonlinear": the estimators
are told only its linearisation at the static point). Estimators told the nominal vehicle:
the default (road_estimator 2), the KF (road_estimator 0) and, as a diagnosis, the force-error
filter alone (road_estimator 2 without the anchor's blend and velocity pull, mass not fed back);
paper 003's observers (road_estimator 3 EKF, 5 UKF, mass_estimator 3 dual observer), on the
nonlinear case told the plant's maps (spring_model = damper_model = 1), else the nominal vehicle.
Prints one markdown row per (class, speed, case, estimator): HP / raw road error std %, the raw
error's rms (mm, with its mean), in-band gain, 2-sigma coverage (harness.metrics.road_scores:
road_height_est, the profile, against metrics.reference_profile of the road), mean sprung-mass
error % after the 10 s warm-up (means over seeds).
With --std-scales, also the coverage of +-2 k road_height_std for each k, and the rms of the
default's two force-error states over their stationary prior std sqrt(q v tau / 2) (fast, slow):
how far a wrong suspension pushes them past what their model expects.
With --spread, also the 2-sigma coverage of the single seeds (lowest, highest) and the mean's
95 % interval, mean +- 2 standard errors over the seeds: each seed's coverage is one number
(its error wanders slowly, so the steps of one run are not independent samples), and a cell's
coverage is scored by as many samples as it has seeds.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.estimators import SuspensionEstimator  # noqa: E402
from suspension_estimation.harness.metrics import road_scores  # noqa: E402
from suspension_estimation.harness.studies.robust import CASES, NOMINAL, plant_vehicle  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar  # noqa: E402
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.sensors import SensorErrors  # noqa: E402
from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402

H = 1e-3  # s
WARMUP = 10.0  # s
ESTIMATORS = {
    "default": {},
    "KF (0)": {"road_estimator": 0},
    "force-error filter alone": {"blend_hz": 1e-9, "blend_coarse_hz": 1e-9, "align_hz": 0.0, "mass_feedback": False},
    "EKF (3)": {"road_estimator": 3, "mass_estimator": 0},
    "UKF (5)": {"road_estimator": 5, "mass_estimator": 0},
    "dual observer (3, 3)": {"road_estimator": 3, "mass_estimator": 3},
}
OBSERVERS = ("EKF (3)", "UKF (5)", "dual observer (3, 3)")
MAPS = {"spring_model": 1, "damper_model": 1}  # the contract's default air spring and damper


def grid_arguments(ap: argparse.ArgumentParser) -> None:
    """The options the sensor benchmarks share: --plant, --classes, --speeds, --seeds, --duration."""
    ap.add_argument("--plant", default="exact", choices=("exact", "nonlinear"))
    ap.add_argument("--classes", default="C")
    ap.add_argument("--speeds", default="40", help="km/h")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--duration", type=float, default=30.0, help="s (the first 10 s are not scored)")


def drive(case: str, cls: int, speed: float, duration: float, seed: int, errors: SensorErrors = SensorErrors()):
    """(t, measurements, true road, the vehicle the estimators are told); ``errors``: the plant's
    sensor errors beside its noise (plant/sensors.py)."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    if case == "nonlinear":
        car = NonlinearQuarterCar(DEFAULT_VEHICLE, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, noise=SensorNoise(),
                                  noise_seed=1000 + seed, errors=errors)
        told = car.linearisation()
    else:
        car = QuarterCar(DEFAULT_VEHICLE.with_(**dict(zip(("m_u", "k_s", "k_t", "c_s"), plant_vehicle(case)))),
                         SensorNoise(), noise_seed=1000 + seed, errors=errors)
        told = DEFAULT_VEHICLE.with_(**NOMINAL)
    car.settle(road.height(0.0))  # at rest on the road at t = 0, as QuarterCar.fmu starts
    n = int(round(duration / H))
    meas, zr = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        car.step(road.height(speed * k * H), H)
        meas[k], zr[k] = car.measured, car.road
    return np.arange(1, n + 1) * H, meas, zr, told


def score(t, meas, zr, told, speed: float, scales: tuple = (), **kw) -> dict:
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s, **kw)
    nf = est.road.force_states
    rows = []
    for z in meas:
        o = est.step(z[0], z[1], z[2], speed, H)
        rows.append([o["road_height_est"], o["road_height_std"], o["sprung_mass_est"],
                     *est.kf.x[est.n_states - nf:est.n_states]])
    out, late, d = np.array(rows), t >= WARMUP, speed * t
    s = road_scores(t, out[:, 0], zr, out[:, 1], warmup=WARMUP, distance=d)
    s["mass_err_pct"] = float(100 * (np.mean(out[late, 2]) / DEFAULT_VEHICLE.m_s - 1))
    for k in scales:
        s[f"cov x{k:g}"] = road_scores(t, out[:, 0], zr, k * out[:, 1], warmup=WARMUP, distance=d)["coverage_2sigma"]
    if scales and nf == 2:
        n = est.road.noise
        prior = np.sqrt([n.q_f * speed * n.tau_f / 2, n.q_b * speed * n.tau_b / 2])
        s["fe_fast"], s["fe_slow"] = np.sqrt(np.mean(out[late, 3:] ** 2, axis=0)) / prior
    return s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--classes", default="C")
    ap.add_argument("--speeds", default="40,80", help="km/h")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--duration", type=float, default=60.0, help="s (the first 10 s are not scored)")
    ap.add_argument("--cases", default=",".join([*CASES, "nonlinear"]))
    ap.add_argument("--estimators", default=";".join(ESTIMATORS), help="names of ESTIMATORS, separated by ';'")
    ap.add_argument("--seed0", type=int, default=1, help="first seed (default 1)")
    ap.add_argument("--set", default="{}", help='extra estimator keywords as JSON, e.g. \'{"refilter_span": 4}\'')
    ap.add_argument("--std-scales", default="", help="factors k: also print the coverage of +-2 k road_height_std")
    ap.add_argument("--spread", action="store_true",
                    help="also the coverage's seed range and the mean +- 2 standard errors over seeds")
    a = ap.parse_args(argv)
    try:
        extra = json.loads(a.set)
    except ValueError:
        extra = None
    if not isinstance(extra, dict):
        print(f"error: --set takes a JSON object, not {a.set!r}", file=sys.stderr)
        return 1
    try:
        scales = tuple(float(v) for v in a.std_scales.split(",") if v.strip())
    except ValueError:
        scales = (0.0,)
    if any(not k > 0 for k in scales):
        print(f"error: --std-scales takes positive factors separated by ',', not {a.std_scales!r}", file=sys.stderr)
        return 1
    cases = [c.strip() for c in a.cases.split(",")]
    chosen = {n.strip(): ESTIMATORS.get(n.strip()) for n in a.estimators.split(";")}
    if None in chosen.values():
        print(f"error: --estimators takes names of {'; '.join(ESTIMATORS)}", file=sys.stderr)
        return 1
    unknown = [c for c in cases if c not in CASES and c != "nonlinear"]
    if unknown or a.duration <= WARMUP or a.seeds < 1:
        print(f"error: unknown cases {unknown}, or --duration <= {WARMUP} s, or --seeds < 1", file=sys.stderr)
        return 1
    extra_cols = ([f"cov x{k:g}" for k in scales] + (["force err / prior (fast, slow)"] if scales else [])
                  + (["cov seeds (min-max)", "cov mean +- 2 SE"] if a.spread else []))
    print("| ISO | km/h | plant | estimator | HP % | raw % | raw rms mm | gain | cov | mass % |"
          + "".join(f" {c} |" for c in extra_cols) + "\n|---|---|---|---|---|---|---|---|---|---|" + "---|" * len(extra_cols))
    for letter in a.classes.split(","):
        cls = "ABCDEFGH".index(letter.strip().upper()) + 1
        for kmh in (float(v) for v in a.speeds.split(",")):
            for case in cases:
                rows = {name: [] for name in chosen}
                for seed in range(a.seed0, a.seed0 + a.seeds):
                    t, meas, zr, told = drive(case, cls, kmh / 3.6, a.duration, seed)
                    for name, kw in chosen.items():
                        maps = MAPS if case == "nonlinear" and name in OBSERVERS else {}
                        rows[name].append(score(t, meas, zr, told, kmh / 3.6, scales, **{**kw, **extra}, **maps))
                for name, r in rows.items():
                    m = {k: np.mean([x[k] for x in r]) for k in r[0]}
                    more = "".join(f" {m[f'cov x{k:g}']:.3f} |" for k in scales)
                    if scales:
                        more += f" {m['fe_fast']:.2f}, {m['fe_slow']:.2f} |" if "fe_fast" in m else " |"
                    if a.spread:
                        c = np.array([x["coverage_2sigma"] for x in r])
                        se = c.std(ddof=1) / np.sqrt(c.size) if c.size > 1 else np.nan
                        more += f" {c.min():.3f} to {c.max():.3f} | {c.mean() - 2 * se:.3f} to {c.mean() + 2 * se:.3f} |"
                    print(f"| {letter.strip().upper()} | {kmh:g} | {case} | {name} | {m['err_std_hp_pct']:.2f} | "
                          f"{m['err_std_raw_pct']:.1f} | {m['rmse_raw_mm']:.2f} | {m['gain_hp']:.3f} | {m['coverage_2sigma']:.3f} | "
                          f"{m['mass_err_pct']:+.2f} |{more}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
