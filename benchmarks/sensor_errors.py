"""Real sensor errors on the plain-Python cores (no FMU): what each error does to the road and mass
estimates of the KF (road_estimator 0) and the default (2), scored as the contract defines
road_height_est (the profile, high-passed in distance at 91.44 m as inertial profilers report
elevation: against harness.metrics.reference_profile) and in a shorter distance band (that error
high-passed again at 30 m), which shows where an error sits in wavelength. docs/real-sensors.md
quotes it.

    .venv/bin/python benchmarks/sensor_errors.py [--plant exact|nonlinear] [--classes C] [--speeds 40]
        [--seeds 1] [--duration 30] [--estimators "KF (0);default"] [--cases ideal,...] [--debias]

Cases: those of the sensors study (harness/studies/sensors.py ``ERRORS``: each error of
plant/sensors.py alone at the end of its range, and all together) and a body bias of 0.01 m/s2.
Columns after the 10 s warm-up (harness.metrics.road_scores): HP error %, the rms error (mm) of
road_height_est against the true profile, the median road_height_std (mm), the share of errors
within +-2 road_height_std, the rms of that error high-passed in distance at 30 m (``band``, mm:
both road_height_est and the true profile through metrics.reference_profile at 30 m), and the
mean sprung-mass error %. ``--debias`` feeds the estimator accelerations from which their
running mean (over the elapsed time for 20 s, then exponentially with 100 s) was removed: a
model-free bias removal, since a body's vertical acceleration averages to zero, and what it costs.
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
from suspension_estimation.harness.metrics import reference_profile, road_scores  # noqa: E402
from suspension_estimation.harness.studies.sensors import ERRORS  # noqa: E402
from suspension_estimation.plant.sensors import SensorErrors  # noqa: E402

H = 1e-3  # s
WARMUP = 10.0  # s
BAND = 30.0  # m, the shorter distance band
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
    """The scores of the module doc for one run: t (s), meas (n x 3), true road zr (m), ``told``
    the vehicle the estimator is told, at ``speed`` m/s; ``kw``: estimator parameters."""
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s, **kw)
    out = np.array([[o["road_height_est"], o["road_height_std"], o["sprung_mass_est"]]
                    for o in (est.step(z[0], z[1], z[2], speed, H) for z in meas)])
    keep = t >= WARMUP
    d, cutoff = speed * t, est.cfg.profile_cutoff
    s = road_scores(t, out[:, 0], zr, out[:, 1], warmup=WARMUP, distance=d, cutoff=cutoff)
    # the error high-passed again at BAND m: both sides through the same high-pass
    s["band_mm"] = road_scores(t, reference_profile(d, out[:, 0], BAND), reference_profile(d, zr, cutoff),
                               warmup=WARMUP, distance=d, cutoff=BAND)["rmse_raw_mm"]
    s["std_mm"] = float(1e3 * np.median(out[keep, 1]))
    s["mass_pct"] = float(100 * (np.mean(out[keep, 2]) / told.m_s - 1))
    return s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    robust_cores.grid_arguments(ap)
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
    print(f"| ISO | km/h | case | estimator | HP % | raw rms mm | std mm | cov | band {BAND:g} m mm | mass % |")
    print("|---|---|---|---|---|---|---|---|---|---|")
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
                          f"{m['rmse_raw_mm']:.2f} | {m['std_mm']:.2f} | {m['coverage_2sigma']:.2f} | "
                          f"{m['band_mm']:.2f} | {m['mass_pct']:+.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
