"""Is ``road_height_std`` honest? The cores over many seeds.

    .venv/bin/python benchmarks/std_calibration.py [--classes 2,3,4] [--seeds 1-20] [--kmh 40] [--workers 2]
        [--duration 70]
    .venv/bin/python benchmarks/std_calibration.py --grid 30 [--classes 2,3,4] [--seeds 1]

For each ISO class and seed: the paper's vehicle at 410 kg, its sensor noise, 40 km/h, 1 ms,
the plant settled on the road at t = 0 (as ``QuarterCar.fmu`` starts), the default road
estimator at the right mass with the online class (``mass_estimator`` 0, ``road_class`` 0),
70 s (``--duration``: longer runs add windows up to 200 s); road_height_est (the profile) scored
against ``harness.metrics.reference_profile`` of the road. It prints, per class and time window
after the start, the rms raw road error against the rms reported ``road_height_std`` over all
seeds (a ratio near 1 is an honest std), and the 2σ coverage and raw error-STD % of
``harness.metrics.road_scores`` (10-70 s) as mean ± std over seeds. The cores, not the FMUs:
the FMU runs are those of ``python -m suspension_estimation.harness paper``; this is the many-seed
check behind them.
"""
from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

WINDOWS = ((10, 20), (20, 30), (30, 45), (45, 70), (10, 70))
LONG_WINDOWS = ((70, 100), (100, 150), (150, 200))  # s, with --duration beyond 70 s
T, H, SPEED = 70.0, 1e-3, 40 / 3.6


def drive(road, car, est, speed: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n steps of H at ``speed`` (m/s): road estimate, true road and road_height_std (m)."""
    e, r, s = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        r[k] = road.height(speed * (k + 1) * H)
        car.step(r[k], H)
        o = est.step(*car.measured, speed, H)
        e[k], s[k] = o["road_height_est"], o["road_height_std"]
    return e, r, s


def windows(duration: float) -> tuple[tuple[float, float], ...]:
    """The scoring windows (s) of a run of ``duration`` s."""
    return WINDOWS + tuple(w for w in LONG_WINDOWS if w[1] <= duration + 1e-9)


def run(cls: int, seed: int, speed: float = SPEED, duration: float = T) -> dict:
    """One core run of ``duration`` s: per-window sums of squared error and std, and the run's
    scores (those over 10-70 s)."""
    from suspension_estimation.estimators import SuspensionEstimator
    from suspension_estimation.harness.metrics import reference_profile, road_scores
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(0.02, 0.2, 1e-4), noise_seed=1000 + seed)
    car.settle(road.height(0.0))
    est = SuspensionEstimator(mass_estimator=0, road_class=0)
    n = int(round(duration / H))
    e, r, s = drive(road, car, est, speed, n)
    t = np.arange(1, n + 1) * H
    d = speed * t  # m travelled at each sample
    early = t <= T
    sc = road_scores(t[early], e[early], r[early], s[early], distance=d[early])
    r = reference_profile(d, r)  # what road_height_est estimates
    win = {w: (float(np.mean((e - r)[(t >= w[0]) & (t < w[1])] ** 2)),
               float(np.mean(s[(t >= w[0]) & (t < w[1])] ** 2))) for w in windows(duration)}
    return {"cls": cls, "seed": seed, "win": win, "coverage": 100 * sc["coverage_2sigma"], "raw": sc["err_std_raw_pct"]}


def grid_run(case: str, cls: int, kmh: float, seed: int, duration: float) -> dict:
    """One run of the robustness grid (harness/studies/robust.py's cases) on the cores: the plant
    with the case's vehicle settled on the road, the default estimator told the nominal vehicle
    (mass estimated and fed back); scores after 10 s against metrics.reference_profile."""
    from suspension_estimation.estimators import SuspensionEstimator
    from suspension_estimation.harness.metrics import road_scores
    from suspension_estimation.harness.studies.robust import NOMINAL, plant_vehicle
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    car = QuarterCar(DEFAULT_VEHICLE.with_(**dict(zip(("m_u", "k_s", "k_t", "c_s"), plant_vehicle(case)))),
                     SensorNoise(), noise_seed=1000 + seed)
    car.settle(road.height(0.0))
    told = DEFAULT_VEHICLE.with_(**NOMINAL)
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s)
    v, n = kmh / 3.6, int(round(duration / H))
    e, r, sd = drive(road, car, est, v, n)
    t = np.arange(1, n + 1) * H
    sc = road_scores(t, e, r, sd, warmup=10.0, distance=v * t)
    return {"case": case, "cls": cls, "kmh": kmh, "seed": seed, "cov": sc["coverage_2sigma"],
            "raw": sc["err_std_raw_pct"], "rmse": sc["rmse_raw_mm"],
            "std": float(1e3 * np.sqrt(np.mean(sd[int(10.0 / H):] ** 2)))}


def grid(classes: list[int], seeds: range, duration: float, workers: int) -> None:
    """The robustness grid (B, C, D x 40, 80 km/h x the cases): 2-sigma coverage per cell."""
    from suspension_estimation.harness.studies.robust import CASES

    jobs = [(c, k, kmh, s, duration) for k in classes for kmh in (40.0, 80.0) for c in CASES for s in seeds]
    with ProcessPoolExecutor(workers) as pool:
        res = list(pool.map(grid_run, *zip(*jobs)))
    print(f"default estimator on the cores, {duration:g} s, seeds {seeds.start}-{seeds.stop - 1}, scored after 10 s "
          "against metrics.reference_profile: 2σ coverage % / raw error % / rms error / rms std (mm)")
    print("| ISO | km/h | " + " | ".join(CASES) + " |\n|---|---|" + "---|" * len(CASES))
    inside = 0
    for k in classes:
        for kmh in (40.0, 80.0):
            cells = []
            for c in CASES:
                x = [y for y in res if y["case"] == c and y["cls"] == k and y["kmh"] == kmh]
                cov = 100 * np.mean([y["cov"] for y in x])
                inside += 90.0 <= cov <= 99.0
                cells.append(f"{cov:.0f} / {np.mean([y['raw'] for y in x]):.1f} / "
                             f"{np.sqrt(np.mean([y['rmse'] ** 2 for y in x])):.2f} / "
                             f"{np.sqrt(np.mean([y['std'] ** 2 for y in x])):.2f}")
            print(f"| {'ABCDEFGH'[k - 1]} | {kmh:g} | " + " | ".join(cells) + " |")
    print(f"cells with 90-99 % coverage: {inside}/{len(classes) * 2 * len(CASES)}")


def _seeds(text: str) -> range:
    lo, _, hi = text.partition("-")
    return range(int(lo), int(hi or lo) + 1)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--classes", default="2,3,4", help="ISO classes as numbers, 1 = A (default 2,3,4)")
    p.add_argument("--seeds", default="1-20", help="seed range (default 1-20)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--kmh", type=float, default=3.6 * SPEED, help="speed in km/h (default 40)")
    p.add_argument("--duration", type=float, default=T, help="s per run (default 70; up to 200 adds windows)")
    p.add_argument("--grid", type=float, default=0.0, metavar="SECONDS",
                   help="instead: the robustness grid's cases (harness/studies/robust.py), runs of this length")
    a = p.parse_args(argv)
    try:
        classes = [int(c) for c in a.classes.split(",")]
        seeds = _seeds(a.seeds)
        if (not classes or not all(1 <= c <= 8 for c in classes) or len(seeds) < 1 or a.workers < 1
                or not T <= a.duration <= 1000.0):
            raise ValueError
    except ValueError:
        print("std_calibration: --classes takes numbers 1-8, --seeds a range like 1-20, --workers >= 1, "
              f"--duration {T:g}-1000 s",
              file=sys.stderr)
        return 2
    if a.grid > 10.0:
        grid(classes, seeds, a.grid, a.workers)
        return 0
    jobs = [(c, s, a.kmh / 3.6, a.duration) for c in classes for s in seeds]
    with ProcessPoolExecutor(a.workers) as pool:
        res = list(pool.map(run, *zip(*jobs)))
    print(f"cores, {a.kmh:g} km/h, seeds {a.seeds}: rms raw error / rms road_height_std (ratio)")
    for c in classes:
        rows = [x for x in res if x["cls"] == c]
        cells = []
        for w in windows(a.duration):
            e2 = np.mean([x["win"][w][0] for x in rows])
            s2 = np.mean([x["win"][w][1] for x in rows])
            cells.append(f"{w[0]}-{w[1]} s {1e3 * e2 ** 0.5:.2f}/{1e3 * s2 ** 0.5:.2f} mm ({(e2 / s2) ** 0.5:.3f})")
        cov = np.array([x["coverage"] for x in rows])
        raw = np.array([x["raw"] for x in rows])
        print(f"ISO {'ABCDEFGH'[c - 1]}: " + "; ".join(cells)
              + f"; 2σ coverage {cov.mean():.1f} ± {cov.std(ddof=1) if len(cov) > 1 else 0:.1f} %"
              + f" (first 10 seeds {cov[:10].mean():.1f} %); raw {raw.mean():.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
