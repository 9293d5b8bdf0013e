"""The nonlinear quarter car's verification figures and how far it is from its linearisation.

    .venv/bin/python benchmarks/nonlinear_plant.py

Prints (markdown) the tables of docs/nonlinear-plant.md: (0) the plant's nonlinear parameters
from the contract; (1) the RK4 plant against DOP853 (rtol 1e-10) on the bump and the ISO D road
of tests/test_nonlinear_plant.py, max error per signal in % of its peak, and the plant's time per
step; (2) the energy balance over 4 s of ISO D at 100 km/h at three substeps, and what is left of
it if the tyre's energy ignores the contact loss; (3) on ISO B, C, D at 40 and 80 km/h (20 s,
1 ms, seed 1): the largest deflection and suspension velocity, the share of steps with the tyre
off the road or a stop touched, the mean deflection (an asymmetric damper pulls the body down),
and the rms difference between the nonlinear car and the linear car of its static point (as a
share of the linear car's rms) for the body acceleration, the deflection and the tyre force.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from plant import iso8608, nonlinear_car  # noqa: E402
from plant.quarter_car import QuarterCar  # noqa: E402
from plant.road import SyntheticRoad  # noqa: E402
from test_nonlinear_plant import (QUIET, bump, car, energy_balance, iso_d, peak_error, reference,  # noqa: E402
                                  run_core)

SIGNALS = ["z_s", "v_s", "z_u", "v_u", "a_s", "a_u"]


def against_dop853() -> None:
    print("| road | h (ms) | " + " | ".join(f"{s} err %" for s in SIGNALS) + " | plant us/step |")
    print("|---|---|" + "---|" * (len(SIGNALS) + 1))
    for name, make in (("bump 60 mm", lambda h: bump(h, 0.06)), ("ISO D 80 km/h", iso_d)):
        for h in (0.001, 0.01):
            road = make(h)
            p = car()
            p.settle(0.0)
            t0 = time.perf_counter()
            got = run_core(p, road, h)
            us = (time.perf_counter() - t0) / len(road) * 1e6
            err = peak_error(got[:, :6], reference(road, h)[:, :6]) * 100
            print(f"| {name} | {h * 1e3:g} | " + " | ".join(f"{e:.2e}" for e in err) + f" | {us:.0f} |")


def energy() -> None:
    road = iso_d(0.001, 4.0, kmh=100.0)
    print("| RK4 substep (ms) | road work (J) | damper work (J) | final energy (J) | residual (J) "
          "| steps off the road | residual if the tyre could pull (J) |")
    print("|---|---|---|---|---|---|---|")
    default = nonlinear_car.H_MAX
    for h_max in (1e-3, 0.5e-3, 0.25e-3):
        nonlinear_car.H_MAX = h_max
        b = energy_balance(road, 0.001)
        wrong = energy_balance(road, 0.001, tyre_pulls=True)["residual"]
        print(f"| {h_max * 1e3:g} | {b['road_work']:.2f} | {b['dissipated']:.2f} | {b['final']:.3f} | "
              f"{b['residual']:.1e} | {b['steps_off_road']} | {wrong:.1f} |")
    nonlinear_car.H_MAX = default


def against_linearisation() -> None:
    print("| ISO class | km/h | max deflection (m) | mean deflection (mm) | max susp. velocity (m/s) "
          "| tyre off (% steps) | stop (% steps) | a_s diff % | deflection diff % | tyre force diff % |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    h, n = 0.001, 20000
    for cls in (2, 3, 4):
        road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=1)
        for kmh in (40, 80):
            z = np.array([road.height((k + 1) * h * kmh / 3.6) for k in range(n)]) - road.height(0.0)
            nl = car()
            lin = QuarterCar(nl.linearisation(), QUIET)
            out = np.empty((n, 2, 3))
            defl, vel, off, stop = 0.0, 0.0, 0, 0
            for p in (nl, lin):
                p.settle(0.0)
            for k, r in enumerate(z):
                for j, p in enumerate((nl, lin)):
                    p.step(r, h)
                    out[k, j] = (p.acc_true[0], p.x[0] - p.x[2], p.tire_force)
                defl = max(defl, abs(nl.x[0] - nl.x[2]))
                vel = max(vel, abs(nl.x[1] - nl.x[3]))
                off += 1 - nl.tire_contact
                stop += nl.bump_stop > 0
            diff = np.sqrt(np.mean((out[:, 0] - out[:, 1]) ** 2, axis=0) / np.mean(out[:, 1] ** 2, axis=0)) * 100
            print(f"| {iso8608.class_name(cls)} | {kmh} | {defl:.3f} | {out[:, 0, 1].mean() * 1e3:.1f} | {vel:.2f} | "
                  f"{off / n * 100:.2f} | "
                  f"{stop / n * 100:.2f} | " + " | ".join(f"{d:.1f}" for d in diff) + " |")


def parameters() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fmu_src"))
    from suspension_fmi.contract import QUARTER_CAR, allowed_text
    from plant.suspension_forces import FORCE_RANGES

    print("| parameter | unit | default | allowed | meaning |")
    print("|---|---|---|---|---|")
    for v in QUARTER_CAR:
        if v.name in FORCE_RANGES:
            print(f"| `{v.name}` | {v.unit} | {v.start:.6g} | {allowed_text(v)} | {v.description} |")


def main() -> int:
    parameters()
    print()
    against_dop853()
    print()
    energy()
    print()
    against_linearisation()
    return 0


if __name__ == "__main__":
    sys.exit(main())
