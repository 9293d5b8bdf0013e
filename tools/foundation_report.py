#!/usr/bin/env python3
"""Print the road and plant accuracy figures, measured through the built FMUs in dist/.

    .venv/bin/python tools/foundation_report.py

- ISORoad: PSD error against ISO 8608 in each octave band 0.02-2 cycle/m for every class
  (20 km at 0.2 m, Welch with 1 km Hann segments), the worst band per class.
- QuarterCar: largest error against scipy.signal.lsim at a 10x finer step, in % of the peak
  response, for a 20 mm bump and a 0.5-20 Hz sweep at 1 ms and 10 ms.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import numpy as np  # noqa: E402

from fmu_driver import Driven  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE  # noqa: E402
from test_plant_fmu import OUT, QUIET, bump, drive, reference, sweep  # noqa: E402


def main(dist: Path = ROOT / "dist") -> None:
    print("ISORoad PSD error per octave band (20 km, seed = class):")
    bands = [(0.02 * 2 ** k, min(0.02 * 2 ** (k + 1), 2.0)) for k in range(7)]
    print("| class | " + " | ".join(f"{lo:.2f}-{hi:.2f}" for lo, hi in bands) + " | worst band | worst |")
    for c in range(1, 9):
        r = Driven(dist / "ISORoad.fmu", {"road_class": c, "seed": c})
        h = r.run(0.01, 100_000, ["road_height"], vehicle_speed=20.0)[:, 0]
        r.close()
        errs = iso8608.band_psd_errors(h, 0.2, iso8608.class_psd_n0(c), segment=1000.0)
        lo, hi, worst = max(errs, key=lambda e: abs(e[2]))
        print(f"| {iso8608.class_name(c)} | " + " | ".join(f"{e[2]:+.1%}" for e in errs)
              + f" | {lo:.2f}-{hi:.2f} | {worst:+.1%} |")
    print("\nQuarterCar error against lsim (10x finer step), max over the run, % of the peak:")
    for h in (0.001, 0.01):
        for make in (bump, sweep):
            road = make(h)
            p = Driven(dist / "QuarterCar.fmu", QUIET)
            got = drive(p, road, h)
            p.close()
            ref, _ = reference(DEFAULT_VEHICLE, road, h)
            errs = np.max(np.abs(got - ref), axis=0) / np.max(np.abs(ref), axis=0)
            worst = int(np.argmax(errs))
            print(f"  h = {h * 1e3:g} ms, {make.__name__:5s}: worst {OUT[worst]} {100 * errs[worst]:.2e} %")


if __name__ == "__main__":
    main()
