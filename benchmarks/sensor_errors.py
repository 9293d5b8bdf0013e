"""Real sensor errors on the plain-Python cores (no FMU): what each error does to the road and mass
estimates of the KF (road_estimator 0) and the default (2), scored both as the contract defines
road_height_est today (against harness.metrics.reference_road) and in a distance band (the error
high-passed in distance, as inertial profilers report elevation), which shows where an error
sits in wavelength. docs/real-sensors.md quotes it.

    .venv/bin/python benchmarks/sensor_errors.py [--plant exact|nonlinear] [--classes C] [--speeds 40]
        [--seeds 1] [--duration 30] [--estimators "KF (0);default"] [--cases ideal,...] [--debias]

Cases: those of the sensors study (harness/studies/sensors.py ``ERRORS``: each error of
plant/sensors.py alone at the end of its range, and all together) and a body bias of 0.01 m/s2.
Band errors: road_height_est's error through the profile's high-pass in distance
(harness.metrics.band_scores) at 30 m and 91.44 m (300 ft) wavelength. ``--debias`` feeds the
estimator accelerations from which their running mean (over the elapsed time for 20 s, then
exponentially with 100 s) was removed: a model-free bias removal, since a body's vertical
acceleration averages to zero, and what it costs.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import robust_cores  # noqa: E402

from suspension_estimation.estimators import SuspensionEstimator  # noqa: E402
from suspension_estimation.harness.metrics import band_scores, profile_scores, road_scores  # noqa: E402
from suspension_estimation.harness.studies.sensors import ERRORS  # noqa: E402
from suspension_estimation.plant.sensors import SensorErrors  # noqa: E402

H = 1e-3  # s
WARMUP = 10.0  # s
BANDS = (30.0, 91.44)  # m
# the sensors study's cases (each error at the end of its range, all together), and a small body bias
CASES: dict[str, dict[str, float]] = {**ERRORS, "body acc bias +0.01 m/s2": {"acc_sprung_bias": 0.01}}
ESTIMATORS = {"KF (0)": {"road_estimator": 0}, "default": {}}


def drive(plant: str, errors: SensorErrors, cls: int, speed: float, duration: float, seed: int):
    """(t, measurements, true road, the vehicle the estimator is told): robust_cores.drive's
    exact or air-spring plant with the sensor errors ``errors``."""
    return robust_cores.drive("nonlinear" if plant == "nonlinear" else "exact", cls, speed, duration, seed, errors)


def debias(x: np.ndarray, t0: float = 20.0, tau: float = 100.0) -> np.ndarray:
    """x minus its running mean: over the elapsed time until t0 s, then exponential with tau s."""
    out, m = np.empty_like(x), 0.0
    for k, v in enumerate(x):
        m += (H / min((k + 1) * H, t0) if (k + 1) * H < t0 else H / tau) * (v - m)
        out[k] = v - m
    return out


def run(t, meas, zr, told, speed: float, **kw) -> dict:
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s, **kw)
    out = np.array([[o["road_height_est"], o["road_height_std"], o["sprung_mass_est"], o["road_profile_est"],
                     o["road_profile_std"]] for o in (est.step(z[0], z[1], z[2], speed, H) for z in meas)])
    keep = t >= WARMUP
    s = road_scores(t, out[:, 0], zr, out[:, 1], warmup=WARMUP)
    d = speed * t
    for lam in BANDS:
        s[f"band {lam:g} m"] = band_scores(t, d, out[:, 0], zr, lam, WARMUP)["band_rmse_mm"]
    p = profile_scores(t, d, out[:, 3], zr, out[:, 4], est.cfg.profile_cutoff, WARMUP)
    s["profile_mm"], s["profile_cov"] = p["profile_rmse_mm"], p["profile_coverage"]
    s["std_mm"] = float(1e3 * np.median(out[keep, 1]))
    s["profile_std_mm"] = float(1e3 * np.median(out[keep, 4]))
    s["mass_pct"] = float(100 * (np.mean(out[keep, 2]) / told.m_s - 1))
    return s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant", default="exact", choices=("exact", "nonlinear"))
    ap.add_argument("--classes", default="C")
    ap.add_argument("--speeds", default="40", help="km/h")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--duration", type=float, default=30.0, help="s (the first 10 s are not scored)")
    ap.add_argument("--estimators", default=";".join(ESTIMATORS))
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--debias", action="store_true", help="remove the accelerations' running mean first")
    a = ap.parse_args(argv)
    cases = [c.strip() for c in a.cases.split(",")]
    names = [n.strip() for n in a.estimators.split(";")]
    bad = [c for c in cases if c not in CASES] + [n for n in names if n not in ESTIMATORS]
    if bad or a.duration <= WARMUP or a.seeds < 1:
        print(f"error: unknown cases or estimators {bad}, or --duration <= {WARMUP} s, or --seeds < 1",
              file=sys.stderr)
        return 1
    print(f"plant {a.plant}{', accelerations debiased' if a.debias else ''}; means over {a.seeds} seed(s)\n")
    print("| ISO | km/h | case | estimator | HP % | raw rms mm | std mm | cov | "
          + " | ".join(f"band {lam:g} m mm" for lam in BANDS) + " | profile err mm | profile std mm | profile cov | mass % |")
    print("|---|---|---|---|---|---|---|---|" + "---|" * len(BANDS) + "---|---|---|---|")
    for letter in a.classes.split(","):
        cls = "ABCDEFGH".index(letter.strip().upper()) + 1
        for kmh in (float(v) for v in a.speeds.split(",")):
            v = kmh / 3.6
            for case in cases:
                runs = [drive(a.plant, SensorErrors(**CASES[case]), cls, v, a.duration, seed)
                        for seed in range(1, a.seeds + 1)]
                if a.debias:
                    for _, meas, _, _ in runs:
                        meas[:, 0], meas[:, 1] = debias(meas[:, 0]), debias(meas[:, 1])
                for name in names:
                    ss = [run(*r, v, **ESTIMATORS[name]) for r in runs]
                    m = {k: float(np.mean([s[k] for s in ss])) for k in ss[0]}
                    print(f"| {letter.upper()} | {kmh:g} | {case} | {name} | {m['err_std_hp_pct']:.2f} | "
                          f"{m['rmse_raw_mm']:.1f} | {m['std_mm']:.1f} | {m['coverage_2sigma']:.2f} | "
                          + " | ".join(f"{m[f'band {lam:g} m']:.1f}" for lam in BANDS)
                          + f" | {m['profile_mm']:.2f} | {m['profile_std_mm']:.2f} | {m['profile_cov']:.2f}"
                          + f" | {m['mass_pct']:+.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
