"""IRI of the estimated road against the IRI of the true road, through the FMUs.

    .venv/bin/python benchmarks/iri_error.py [--classes B,C,D] [--speeds 30,50,72,100]
        [--masses 590,230] [--seeds 1,2] [--length 600] [--skip 1] [--step 0.001] [--dist DIR]

Runs ISORoad -> QuarterCar -> SuspensionEstimator (default parameters: joint road + mass
estimation, online class) for every class, speed (km/h), true sprung mass (kg) and seed over
``--length`` m, reads ISORoad.iri and SuspensionEstimator.iri_est (both ASTM E1926 over the same
100 m segments, plant/iri.py) at each completed segment, leaves out the first ``--skip`` segments
(the filter's start), and prints per cell the mean and the worst IRI error in % over the segments,
and over all cells the share of segments within +-3 %. Exits 1 when no segment was scored.
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from harness.cosim import CoSimulation, System  # noqa: E402
from harness.metrics import iri_segments  # noqa: E402
from plant import iso8608  # noqa: E402

WIRES = ("acc_sprung", "acc_unsprung", "susp_deflection")


def run_cell(dist: Path, road_class: int, speed: float, mass: float, seed: int, length: float,
             step: float) -> np.ndarray:
    """One closed-loop run; returns the record with road.iri, e.iri_est and road.distance."""
    comps = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu", "e": dist / "SuspensionEstimator.fmu"}
    conn = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height"),
            ("vehicle_speed", "e.vehicle_speed")] + [(f"plant.{w}", f"e.{w}") for w in WIRES]
    params = {"road.road_class": road_class, "road.seed": seed, "plant.noise_seed": seed}
    with CoSimulation(System(comps, conn), parameters=params,
                      inputs={"vehicle_speed": speed, "plant.sprung_mass": mass},
                      record=["road.iri", "e.iri_est", "road.distance"]) as sim:
        return sim.run(round(length / speed / step) * step, step)


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--classes", default="B,C,D")
    ap.add_argument("--speeds", default="30,50,72,100", help="km/h")
    ap.add_argument("--masses", default="590,230", help="true sprung mass, kg (the estimator assumes 410 kg)")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--length", type=float, default=600.0, help="m per run")
    ap.add_argument("--skip", type=int, default=1, help="segments left out at the start")
    ap.add_argument("--step", type=float, default=1e-3, help="s")
    ap.add_argument("--dist", default=str(ROOT / "dist"))
    args = ap.parse_args(argv)
    classes = [iso8608.CLASSES.index(c.strip().upper()) + 1 for c in args.classes.split(",")]
    errors_all = []
    print("| class | km/h | true mass kg | segments | IRI true m/km (mean) | mean error % | worst error % |")
    print("|---|---|---|---|---|---|---|")
    for c in classes:
        for kmh in _floats(args.speeds):
            for mass in _floats(args.masses):
                rows = []
                for seed in (int(s) for s in _floats(args.seeds)):
                    rec = run_cell(Path(args.dist), c, kmh / 3.6, mass, seed, args.length, args.step)
                    rows += iri_segments(rec["road.distance"], rec["road.iri"], rec["e.iri_est"])[args.skip:]
                if not rows:
                    continue
                err = np.array([r[3] for r in rows])
                errors_all += err.tolist()
                print(f"| {iso8608.class_name(c)} | {kmh:g} | {mass:g} | {len(rows)} | "
                      f"{np.mean([r[1] for r in rows]):.2f} | {err.mean():+.2f} | {err[np.argmax(abs(err))]:+.2f} |")
    if not errors_all:
        print("no segment completed: make --length longer", file=sys.stderr)
        return 1
    e = np.abs(errors_all)
    print(f"\n{len(e)} segments: {100 * np.mean(e <= 3.0):.1f} % within +-3 %, median |error| "
          f"{np.median(e):.2f} %, max {e.max():.2f} %")
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # skip pythonfmu's exit handlers (PythonFMU issue 229)
