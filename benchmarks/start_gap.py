"""The default estimator's start: how far the output (the force-error filter pulled towards the
anchor, with the anchor's low frequencies) and the force-error filter run without the pull differ
in the profile's band, in units of the output's band std, once the damping is identified
(anchored_road.START_BAND_GATE).

    .venv/bin/python benchmarks/start_gap.py [--classes B,C,D] [--speeds 40,80] [--seeds 1]
        [--cases exact,...,nonlinear] [--steps 1,10]

Linear cases (harness/studies/robust.py's vehicles) simulated at 1 ms with the road held, logged
at 1 ms; the air-spring car ("nonlinear") simulated at 0.5 ms with the road moving linearly and
logged at each of --steps ms as point samples (benchmarks/logging_rates.py). One markdown row per
run: the largest gap (mm) and gap / std once the damping is identified, the std there, and the
anchor's mode at the end of the start (4.2 s).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import logging_rates  # noqa: E402
import robust_cores  # noqa: E402

from suspension_estimation.estimators import SuspensionEstimator  # noqa: E402
from suspension_estimation.estimators.anchored_road import START  # noqa: E402

SPAN = 4.2  # s, past anchored_road.START_DISAGREE_SPAN


def largest_gap(meas, told, speed: float, h: float) -> tuple[float, float, float, str]:
    """(largest |gap| mm, largest gap / std, the std there mm, the anchor's mode at the end)."""
    est = SuspensionEstimator(m_s_nominal=told.m_s, m_u=told.m_u, k_s=told.k_s, k_t=told.k_t, c_s=told.c_s)
    road, me = est.road, est.mass_est
    worst = (0.0, 0.0, math.nan)
    for z in meas:
        est.step(z[0], z[1], z[2], speed, h)
        if road.start != START:
            continue
        if me.damping_identified:
            gap, sd = abs(road._start_band_gap), math.sqrt(road._band_variance())
            worst = (max(worst[0], gap), *max(worst[1:], (gap / sd, sd)))
    return 1e3 * worst[0], worst[1], 1e3 * worst[2], road.mode


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--classes", default="B,C,D")
    ap.add_argument("--speeds", default="40,80", help="km/h")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--cases", default=",".join([*robust_cores.CASES, "nonlinear"]))
    ap.add_argument("--steps", default="1,10", help="ms, the air-spring car's logging steps")
    a = ap.parse_args(argv)
    print("| ISO | km/h | plant | step ms | seed | largest gap mm | gap / std | std mm | anchor |")
    print("|---|---|---|---|---|---|---|---|---|")
    for cls in a.classes.split(","):
        c = "ABCDEFGH".index(cls.strip()) + 1
        for kmh in (float(s) for s in a.speeds.split(",")):
            v = kmh / 3.6
            for case in a.cases.split(","):
                steps = [float(s) for s in a.steps.split(",")] if case == "nonlinear" else [1.0]
                for ms in steps:
                    for seed in range(1, a.seeds + 1):
                        if case == "nonlinear":
                            _, meas, _, told = logging_rates.log("nonlinear", True, c, v, SPAN, seed, ms / 1e3, 0)
                        else:
                            _, meas, _, told = robust_cores.drive(case, c, v, SPAN, seed)
                        gap, ratio, sd, mode = largest_gap(meas, told, v, ms / 1e3)
                        print(f"| {cls} | {kmh:g} | {case} | {ms:g} | {seed} | {gap:.1f} | {ratio:.1f} | {sd:.2f} | {mode} |",
                              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
