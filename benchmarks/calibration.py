"""Calibrating the vehicle on a known profile, then estimating on other roads with it.

    .venv/bin/python benchmarks/calibration.py [--cases "exact;k_t +10%;..."] [--classes B,D]
        [--speeds 40,80] [--seeds 2] [--duration 40] [--length 300] [--spacing 0.025] [--workers 2]
        [--sensitivity] [--no-roads]

For each vehicle case of harness/studies/robust.py (the contract's vehicle with k_t +-10 %, m_u
+-15 %, k_s +-15 %, c_s +-30 % alone and all together): the plant core (plant.QuarterCar, the
contract's sensor noise, noise seed 1000) drives ``--length`` m of ISO C (road seed 1) at 40 km/h
from 5 m of it, with a deflection-sensor offset of 1 mm; the road, a SyntheticRoad, is written to
a CSV every ``--spacing`` m (an inertial profiler's 25 mm by default) and the log to a CSV; the
``calibrate`` command (harness/calibrate.py) is run on them with the true sprung mass 410 kg and
``--offset 5``. Table 1: the calibrated parameters' error and reported 1-sigma (%).

Then on other roads (ISO ``--classes`` at ``--speeds``, road seeds ``--seeds``, ``--duration`` s,
scored after 10 s) the default estimator core (estimators.SuspensionEstimator) is told the
plant's exact vehicle, the calibrated one and the contract's nominal one. Table 2: the HP road
error (harness.metrics.road_scores 'err_std_hp_pct': road_height_est, the profile, against
metrics.reference_profile of the road) of each, the ratio calibrated / exact, and
the sprung-mass error of the calibrated run (mean after the warm-up). The target: the ratio at
most 1.1 and the mass within 1 %.

``--sensitivity``: the calibration of the "all -" vehicle again with the command told a wrong
placement (``--offset``), the logged speed off, and the profile every 0.05 and 0.1 m (table 3).
``--no-roads``: tables 1 (and 3) only.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import tomllib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # small matrices: the worker processes are the parallelism

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.estimators import SuspensionEstimator  # noqa: E402
from suspension_estimation.harness.cli import main as harness  # noqa: E402
from suspension_estimation.harness.metrics import road_scores  # noqa: E402
from suspension_estimation.harness.studies.robust import CASES  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE, Vehicle  # noqa: E402

H = 1e-3  # s
WARMUP = 10.0  # s
NAMES = ("m_u", "k_s", "k_t", "c_s")
DEFL_OFFSET = 1e-3  # m, the deflection sensor's offset in the calibration log
START = 5.0  # m of the profile file at the log's first sample


def plant_of(case: str) -> Vehicle:
    return DEFAULT_VEHICLE.with_(**{k: getattr(DEFAULT_VEHICLE, k) * f for k, f in CASES[case].items()})


def drive(vehicle: Vehicle, road: SyntheticRoad, speed: float, n: int, noise_seed: int, s0: float = 0.0) -> np.ndarray:
    """(n, 3) measurements of the plant core from rest on the road at s0 m; row k after step k
    (road at s0 + v k h)."""
    car = QuarterCar(vehicle, SensorNoise(), noise_seed=noise_seed)
    car.settle(road.height(s0))
    meas = np.empty((n, 3))
    for k in range(n):
        car.step(road.height(s0 + speed * k * H), H)
        meas[k] = car.measured
    return meas


def write_section(folder: Path, vehicle: Vehicle, length: float, spacing: float, speed: float = 40 / 3.6,
                  speed_scale: float = 1.0) -> tuple[Path, Path]:
    """The calibration log (CSV, the speed column times ``speed_scale``) from START m of the profile
    (CSV, from 0 m)."""
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=1)
    n = int(length / speed / H)
    meas = drive(vehicle, road, speed, n, noise_seed=1000, s0=START)
    meas[:, 2] += DEFL_OFFSET
    t = np.arange(1, n + 1) * H
    log, profile = folder / "log.csv", folder / "profile.csv"
    np.savetxt(log, np.column_stack([t, meas, np.full(n, speed * speed_scale)]), delimiter=",", fmt="%.10g",
               header="time,acc_sprung,acc_unsprung,susp_deflection,vehicle_speed", comments="")
    s = np.arange(0.0, START + length + 10.0, spacing)
    np.savetxt(profile, np.column_stack([s, [road.height(x) for x in s]]), delimiter=",", fmt="%.10g",
               header="distance (m), elevation (m)", comments="")
    return log, profile


def calibrate(vehicle: Vehicle, length: float, spacing: float, misplaced: float = 0.0,
              speed_scale: float = 1.0) -> tuple[dict, dict, list[str], tuple[float, float]]:
    """Run the ``calibrate`` command, told the log starts ``misplaced`` m after where it does:
    (values, 1-sigma by name, warnings, (fitted start m - true start, true / logged distance))."""
    with tempfile.TemporaryDirectory() as tmp:
        log, profile = write_section(Path(tmp), vehicle, length, spacing, speed_scale=speed_scale)
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = harness(["calibrate", str(log), "--profile", str(profile), "--mass", str(vehicle.m_s),
                            "--offset", str(START + misplaced), "--out", str(Path(tmp) / "vehicle.toml")])
        if code != 0:
            raise RuntimeError(err.getvalue().strip())
        with open(Path(tmp) / "vehicle.toml", "rb") as f:
            values = tomllib.load(f)
    sigma = {}
    for line in out.getvalue().splitlines():
        words = line.split()
        if words and words[0] in NAMES and "+-" in words:
            sigma[words[0]] = float(words[words.index("+-") + 1])
        if words[:4] == ["the", "log", "starts", "at"]:
            placement = (float(words[4]) - START, float(words[words.index("distance") + 1]))
    return values, sigma, [w for w in err.getvalue().splitlines() if w.startswith("warning")], placement


def estimate(meas: np.ndarray, told: dict, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Road and mass estimates of the default estimator core told ``told`` (contract names)."""
    est = SuspensionEstimator(**told)
    out = np.array([[o["road_height_est"], o["sprung_mass_est"]]
                    for o in (est.step(z[0], z[1], z[2], speed, H) for z in meas)])
    return out[:, 0], out[:, 1]


def evaluate(job: tuple) -> dict:
    """One road: HP error told the exact, calibrated and nominal vehicle; the calibrated mass error."""
    case, calibrated, cls, kmh, seed, duration = job
    plant = plant_of(case)
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    n = int(round(duration / H))
    meas = drive(plant, road, kmh / 3.6, n, noise_seed=2000 + seed)
    d = kmh / 3.6 * np.arange(n) * H  # m, where the road was at each step
    zr = np.array([road.height(x) for x in d])
    t = np.arange(1, n + 1) * H
    told = {"exact": {"m_s_nominal": plant.m_s, **{k: getattr(plant, k) for k in NAMES}},
            "calibrated": calibrated,
            "nominal": {"m_s_nominal": plant.m_s, **{k: getattr(DEFAULT_VEHICLE, k) for k in NAMES}}}
    row = {"case": case, "cls": cls, "kmh": kmh, "seed": seed}
    for name, params in told.items():
        road_est, mass = estimate(meas, params, kmh / 3.6)
        row[name] = road_scores(t, road_est, zr, warmup=WARMUP, distance=d)["err_std_hp_pct"]
        if name == "calibrated":
            row["mass_pct"] = float(100 * (np.mean(mass[t >= WARMUP]) / plant.m_s - 1))
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=";".join(CASES),
                    help="vehicle cases of harness/studies/robust.py, ';'-separated")
    ap.add_argument("--classes", default="B,D", help="ISO classes of the evaluation roads (default B,D)")
    ap.add_argument("--speeds", default="40,80", help="km/h of the evaluation roads (default 40,80)")
    ap.add_argument("--seeds", default="2",
                    help="road seeds of the evaluation, ','-separated (default 2; seed 1 calibrates)")
    ap.add_argument("--duration", type=float, default=40.0, help="s per evaluation run, 10 s not scored (default 40)")
    ap.add_argument("--length", type=float, default=300.0, help="m of the calibration section (default 300)")
    ap.add_argument("--spacing", type=float, default=0.025, help="m between the profile's points (default 0.025)")
    ap.add_argument("--workers", type=int, default=2, help="processes for the evaluation (default 2)")
    ap.add_argument("--sensitivity", action="store_true", help="also table 3 (placement, speed, spacing)")
    ap.add_argument("--no-roads", dest="roads", action="store_false", help="no table 2 (the other roads)")
    a = ap.parse_args(argv)
    cases = [c.strip() for c in a.cases.split(";")]
    if [c for c in cases if c not in CASES] or a.duration <= WARMUP:
        print(f"error: --cases takes names of {'; '.join(CASES)}, and --duration must exceed {WARMUP:g} s",
              file=sys.stderr)
        return 1
    classes = ["ABCDEFGH".index(c.strip().upper()) + 1 for c in a.classes.split(",")]
    speeds = [float(v) for v in a.speeds.split(",")]
    seeds = [int(v) for v in a.seeds.split(",")]

    print(f"Table 1: calibrated on {a.length:g} m of ISO C (seed 1) at 40 km/h, profile every {a.spacing:g} m; "
          "error % (1-sigma %)\n")
    print("| plant | " + " | ".join(NAMES) + " | warnings |\n|---|" + "---|" * (len(NAMES) + 1))
    calibrated = {}
    for case in cases:
        values, sigma, warnings, _ = calibrate(plant_of(case), a.length, a.spacing)
        calibrated[case] = values
        plant = plant_of(case)
        cells = [f"{100 * (values[k] / getattr(plant, k) - 1):+.3f} ({100 * sigma[k] / values[k]:.3f})" for k in NAMES]
        print(f"| {case} | " + " | ".join(cells) + f" | {'; '.join(warnings) or '-'} |", flush=True)

    jobs = [(case, calibrated[case], cls, kmh, seed, a.duration)
            for case in cases for cls in classes for kmh in speeds for seed in seeds] if a.roads else []
    if jobs:
        print(f"\nTable 2: the default estimator on other roads ({a.duration:g} s, scored after {WARMUP:g} s), "
              "HP road error % told the exact / calibrated / nominal vehicle; sprung mass told the calibrated one\n")
        print("| plant | ISO | km/h | seed | exact | calibrated | calibrated / exact | nominal | mass % |\n"
              "|---|---|---|---|---|---|---|---|---|")
        rows = []
        with ProcessPoolExecutor(max(1, a.workers)) as pool:
            for r in pool.map(evaluate, jobs):
                rows.append(r)
                print(f"| {r['case']} | {'ABCDEFGH'[r['cls'] - 1]} | {r['kmh']:g} | {r['seed']} | {r['exact']:.2f} | "
                      f"{r['calibrated']:.2f} | {r['calibrated'] / r['exact']:.3f} | {r['nominal']:.2f} | "
                      f"{r['mass_pct']:+.2f} |", flush=True)
        ratio = [r["calibrated"] / r["exact"] for r in rows]
        mass = [abs(r["mass_pct"]) for r in rows]
        print(f"\ncalibrated / exact {min(ratio):.3f}-{max(ratio):.3f} (target <= 1.1: "
              f"{'met' if max(ratio) <= 1.1 else 'MISSED'}); |mass error| at most {max(mass):.2f} % (target 1 %: "
              f"{'met' if max(mass) <= 1.0 else 'MISSED'}); {len(rows)} runs")

    if a.sensitivity:
        print("\nTable 3: the \"all -\" vehicle calibrated with one thing wrong; error % (1-sigma %)\n")
        print("| what | " + " | ".join(NAMES) + " | start found - true (m) | true / logged distance | warnings |\n"
              "|---|" + "---|" * (len(NAMES) + 3))
        plant = plant_of("all -")
        for what, kw in (("nothing", {}), ("--offset 0.05 m too far", {"misplaced": 0.05}),
                         ("--offset 0.3 m short", {"misplaced": -0.3}), ("--offset 1 m too far", {"misplaced": 1.0}),
                         ("--offset 3 m too far (--search 2 m)", {"misplaced": 3.0}),
                         ("speed logged 0.5 % high", {"speed_scale": 1.005}),
                         ("speed logged 1 % low", {"speed_scale": 0.99}),
                         ("speed logged 2 % high", {"speed_scale": 1.02}),
                         ("--offset 1 m too far, speed 1 % low", {"misplaced": 1.0, "speed_scale": 0.99}),
                         ("profile every 0.05 m", {"spacing": 0.05}), ("profile every 0.1 m", {"spacing": 0.1})):
            kw = {"spacing": a.spacing, **kw}
            values, sigma, warnings, (start, scale) = calibrate(plant, a.length, **kw)
            cells = [f"{100 * (values[k] / getattr(plant, k) - 1):+.2f} ({100 * sigma[k] / values[k]:.3f})"
                     for k in NAMES] + [f"{start:+.4f}", f"{scale:.5f}", "; ".join(warnings) or "-"]
            print(f"| {what} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
