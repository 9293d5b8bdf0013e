"""Self-diagnosis on the plain-Python cores (no FMU): what ``status`` 3 (estimators/sensor_check.py)
says about sensor errors beyond their range and about faults that start mid-run, and whether
road_height_std then covers the profile's error. docs/real-sensors.md quotes it.

    .venv/bin/python benchmarks/sensor_faults.py [--plant exact|nonlinear] [--classes C] [--speeds 40]
        [--seeds 1] [--seed0 1] [--duration 30] [--cases ideal,...]

Cases (``CASES``): ideal sensors, every error at the end of its range together (must not be
flagged), errors of plant/sensors.py beyond their range from the start, and faults applied to the
logged channels from ``ONSET`` s: a channel dead (its noise alone), the body accelerometer's sign
flipped, a bias stepping by 0.2-1 m/s2. Columns, the default estimator told the exact vehicle: the
largest diagnosis ratio (sensor_check.InnovationCheck.ratio, per channel: body, wheel,
deflection) after the check starts or after the onset, the largest mean ratio on the wheel
(InnovationCheck.mean_ratio), the first time status is 3 (s), the
share of samples after the 10 s warm-up with status 3, the profile's rms error (mm, against
harness.metrics.reference_profile) and the coverage of +-2 road_height_std after the warm-up,
and the mean sprung mass (kg).
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
from suspension_estimation.harness.metrics import reference_profile  # noqa: E402
from suspension_estimation.plant.sensors import SensorErrors  # noqa: E402

H = 1e-3  # s
WARMUP = 10.0  # s
ONSET = 15.0  # s, the mid-run faults
ALL_IN_RANGE = dict(deflection_offset=5e-3, acc_sprung_bias=0.1, acc_unsprung_bias=0.5, acc_sprung_scale=1.03,
                    acc_unsprung_scale=0.97, acc_sprung_delay=2e-3, acc_unsprung_delay=2e-3)
# name: (plant sensor errors, fault on the logged channels from ONSET: (channel, kind) or None)
CASES: dict[str, tuple[dict, tuple | None]] = {
    "ideal": ({}, None),
    "all in range": (ALL_IN_RANGE, None),
    "body bias 0.5 m/s2": ({"acc_sprung_bias": 0.5}, None),
    "body bias 2 m/s2": ({"acc_sprung_bias": 2.0}, None),
    "wheel bias 3 m/s2": ({"acc_unsprung_bias": 3.0}, None),
    "deflection offset 30 mm": ({"deflection_offset": 0.03}, None),
    "body gain 1.15": ({"acc_sprung_scale": 1.15}, None),
    "wheel gain 0.8": ({"acc_unsprung_scale": 0.8}, None),
    "body 10 ms late": ({"acc_sprung_delay": 0.01}, None),
    "wheel 6 ms late": ({"acc_unsprung_delay": 0.006}, None),
    "deflection 10 ms late": ({"deflection_delay": 0.01}, None),
    "body dead": ({}, (0, "dead")),
    "wheel dead": ({}, (1, "dead")),
    "deflection dead": ({}, (2, "dead")),
    "body sign flipped": ({}, (0, "flip")),
    "body bias step 1 m/s2": ({}, (0, "step", 1.0)),
    "body bias step 0.5 m/s2": ({}, (0, "step", 0.5)),
    "body bias step 0.2 m/s2": ({}, (0, "step", 0.2)),
    "wheel bias step 1 m/s2": ({}, (1, "step", 1.0)),
    # steps within the range the filter absorbs (issue 37 point 2): no alarm is due, only cover
    "body bias step 0.1 m/s2": ({}, (0, "step", 0.1)),
    "wheel bias step 0.5 m/s2": ({}, (1, "step", 0.5)),
    "deflection step 5 mm": ({}, (2, "step", 0.005)),
}
DEAD_NOISE = (0.05, 0.5, 1e-4)  # the std of what a dead channel reads: its noise floor (m/s2, m/s2, m)


def apply_fault(t: np.ndarray, meas: np.ndarray, fault: tuple | None, seed: int) -> None:
    """The mid-run fault on the logged measurements (n x 3), in place."""
    if fault is None:
        return
    ch, kind, *size = fault
    on = t >= ONSET
    if kind == "dead":
        meas[on, ch] = np.random.default_rng(seed + 77).normal(0.0, DEAD_NOISE[ch], int(on.sum()))
    elif kind == "flip":
        meas[on, ch] *= -1.0
    else:
        meas[on, ch] += size[0]


def run(t, meas, zr, told, speed: float, fault: tuple | None) -> dict:
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s)
    start = ONSET if fault is not None else est.cfg.tuning.diagnosis_start
    rows, ratio, mean = [], np.zeros(3), 0.0
    for tk, z in zip(t, meas):
        o = est.step(z[0], z[1], z[2], speed, H)
        rows.append((o["road_height_est"], o["road_height_std"], o["status"], o["sprung_mass_est"]))
        if tk > start:
            ratio = np.maximum(ratio, est.check.ratio)
            mean = max(mean, float(est.check.mean_ratio.max()))
    out = np.array(rows)
    err = out[:, 0] - reference_profile(speed * t, zr, est.cfg.profile_cutoff)
    late = t >= WARMUP
    flagged = np.flatnonzero(out[:, 2] == 3)
    return {"ratio": ratio, "mean": mean, "first": float(t[flagged[0]]) if flagged.size else float("nan"),
            "share": float(np.mean(out[late, 2] == 3)), "err_mm": float(1e3 * np.sqrt(np.mean(err[late] ** 2))),
            "cov": float(np.mean(np.abs(err[late]) <= 2.0 * out[late, 1])), "mass": float(np.mean(out[late, 3]))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    robust_cores.grid_arguments(ap)
    ap.add_argument("--seed0", type=int, default=1, help="first seed (default 1)")
    ap.add_argument("--cases", default=",".join(CASES))
    a = ap.parse_args(argv)
    cases = [c.strip() for c in a.cases.split(",")]
    bad = [c for c in cases if c not in CASES]
    if bad or a.duration <= ONSET or a.seeds < 1:
        print(f"error: unknown cases {bad}, or --duration <= {ONSET} s, or --seeds < 1", file=sys.stderr)
        return 1
    print(f"plant {a.plant}, default estimator; one row per seed\n")
    print("| ISO | km/h | case | seed | largest ratio (body, wheel, deflection) | largest wheel mean "
          "| first status 3, s | status 3 after 10 s | profile error mm | cov | mass kg |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for letter in a.classes.split(","):
        cls = "ABCDEFGH".index(letter.strip().upper()) + 1
        for kmh in (float(v) for v in a.speeds.split(",")):
            v = kmh / 3.6
            for case in cases:
                errors, fault = CASES[case]
                for seed in range(a.seed0, a.seed0 + a.seeds):
                    t, meas, zr, told = robust_cores.drive("nonlinear" if a.plant == "nonlinear" else "exact",
                                                           cls, v, a.duration, seed, SensorErrors(**errors))
                    apply_fault(t, meas, fault, seed)
                    r = run(t, meas, zr, told, v, fault)
                    ratio = ", ".join(f"{x:.2f}" for x in r["ratio"])
                    print(f"| {letter.upper()} | {kmh:g} | {case} | {seed} | {ratio} | {r['mean']:.1f} | {r['first']:.2f} | "
                          f"{r['share']:.2f} | {r['err_mm']:.2f} | {r['cov']:.2f} | {r['mass']:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
