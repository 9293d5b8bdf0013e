"""Cost of the road -> plant -> estimator system in each master the project is tested with.

    .venv/bin/python benchmarks/masters.py [--seconds S] [--repeat N] [--dist DIR]

At a 1 ms step, ``--seconds`` of simulated time (default 2), the best of ``--repeat`` runs
(default 3) after one untimed warm-up run, each from a fresh instance:

- harness: ``harness.cosim.CoSimulation`` on RoadPlantEstimator.ssp (Gauss-Seidel, exact steps);
- simulate_fmu (estimator): ``fmpy.simulate_fmu`` of SuspensionEstimator.fmu alone, its inputs a
  table of the harness's plant measurements (FMPy steps on its own time grid);
- libcosim: ``libcosimpy`` on RoadPlantEstimator.ssp (its fixed-step algorithm, 1 ms from the SSP);
- Ecos: ``ecospy`` on RoadPlantEstimator.ssp (1 ms; needs Debian's libtbb12);
- container (FMPy): ``fmpy.simulate_fmu`` of SuspensionSystem.fmu (fmucontainer's C master inside).

Prints a markdown table (wall time, real-time factor = simulated / wall time, µs per step).
BLAS/OpenMP threads are pinned to 1 before numpy loads, as tools/fmu-env does for native hosts.
The script leaves with ``os._exit`` (pythonfmu's exit handlers, PythonFMU issue 229).
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy is imported, here or in the FMUs (same interpreter)

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from suspension_estimation.harness.cosim import CoSimulation  # noqa: E402
from suspension_estimation.harness.ssp import ROAD_PLANT_ESTIMATOR, read_ssp  # noqa: E402

H = 1e-3  # s
V = 11.1111  # m/s, vehicle_speed's start value (what the SSP runners hold)
MEASURED = ("acc_sprung", "acc_unsprung", "susp_deflection")


def harness(dist: Path, seconds: float) -> Callable[[], None]:
    system = read_ssp(dist / f"{ROAD_PLANT_ESTIMATOR}.ssp", fmu_dir=dist)

    def run() -> None:
        with CoSimulation(system, inputs={"vehicle_speed": V},
                          record=["SuspensionEstimator.road_height_est"]) as sim:
            sim.run(seconds, H)
    return run


def _simulate_fmu(fmu: Path, seconds: float, **kwargs) -> Callable[[], None]:
    """``fmpy.simulate_fmu`` on a fresh instance that is never freed: freeing it unloads the
    pythonfmu binaries, whose unload corrupts this process's heap (PythonFMU #229)."""
    from fmpy import extract, read_model_description, simulate_fmu
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    unzipdir = extract(str(fmu))
    kept = []

    def run() -> None:
        inst = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                         instanceName="bench")
        inst.instantiate()
        kept.append(inst)
        simulate_fmu(unzipdir, stop_time=seconds, step_size=H, fmu_instance=inst, **kwargs)
    return run


def simulate_estimator(dist: Path, seconds: float) -> Callable[[], None]:
    system = read_ssp(dist / f"{ROAD_PLANT_ESTIMATOR}.ssp", fmu_dir=dist)
    with CoSimulation(system, inputs={"vehicle_speed": V}, record=[f"QuarterCar.{m}" for m in MEASURED]) as sim:
        gs = sim.run(seconds, H)
    table = np.zeros(len(gs), dtype=[("time", float), *((m, float) for m in MEASURED), ("vehicle_speed", float)])
    table["time"] = gs["time"]
    for m in MEASURED:
        table[m] = gs[f"QuarterCar.{m}"]
    table["vehicle_speed"] = V
    return _simulate_fmu(dist / "SuspensionEstimator.fmu", seconds, input=table, output=["road_height_est"])


def libcosim(dist: Path, seconds: float) -> Callable[[], None]:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel.ERROR)
    kept = []  # never freed: freeing unloads the pythonfmu binaries (PythonFMU #229)

    def run() -> None:
        execution = CosimExecution.from_ssp_file(str((dist / f"{ROAD_PLANT_ESTIMATOR}.ssp").resolve()))
        kept.append(execution)
        if not execution.simulate_until(round(seconds * 1e9)):
            raise RuntimeError(f"libcosim failed: {execution.status()}")
    return run


def ecos(dist: Path, seconds: float) -> Callable[[], None]:
    from ecospy import EcosSimulation

    kept = []  # never freed, as libcosim's executions

    def run() -> None:
        sim = EcosSimulation(step_size=H, ssp_path=str((dist / f"{ROAD_PLANT_ESTIMATOR}.ssp").resolve()))
        kept.append(sim)
        sim.init()
        sim.step(round(seconds / H))
    return run


def container(dist: Path, seconds: float) -> Callable[[], None]:
    return _simulate_fmu(dist / "SuspensionSystem.fmu", seconds, output=["SuspensionEstimator.road_height_est"])


MASTERS = {"harness (FMPy, Gauss-Seidel)": harness, "fmpy.simulate_fmu (estimator alone)": simulate_estimator,
           "libcosim (RoadPlantEstimator.ssp)": libcosim, "Ecos (RoadPlantEstimator.ssp)": ecos,
           "container SuspensionSystem.fmu (FMPy)": container}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated time per run, s (default 2)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per master (default 3)")
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="folder of the built FMUs (default dist/)")
    args = ap.parse_args(argv)
    steps = round(args.seconds / H)
    print(f"| master | wall s for {args.seconds:g} s | real-time factor | µs per step |")
    print("| --- | --- | --- | --- |")
    for label, make in MASTERS.items():
        try:
            run = make(args.dist, args.seconds)
            run()  # warm-up: imports, model building, caches
            best = min(_timed(run) for _ in range(args.repeat))
        except Exception as e:  # noqa: BLE001 - one line per master that cannot run here
            print(f"| {label} | not run: {type(e).__name__}: {e} | | |")
            continue
        print(f"| {label} | {best:.2f} | {args.seconds / best:.1f} | {1e6 * best / steps:.0f} |", flush=True)
    return 0


def _timed(run: Callable[[], None]) -> float:
    t0 = time.perf_counter()
    run()
    return time.perf_counter() - t0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)
