"""Run a scenario: pick the SSP system from ``dist/``, map the scenario to parameters and inputs,
co-simulate, write the CSV (also the partial one when an FMU refuses during the run, none when it
refuses at initialization) and summarize."""
from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .cosim import CoSimulation, SimulationError, System, model_variables, write_csv
from .scenario import Scenario, ScenarioError
from .ssp import ROAD_PLANT, ROAD_PLANT_ESTIMATOR, ensure_system_ssp, read_ssp

ROOT = Path(__file__).resolve().parents[1]
DIST = ROOT / "dist"
RESULTS = ROOT / "results"

# recorded by default (those the FMU has); a scenario's [output] record adds to these
RECORD = {
    "ISORoad": ["road_height", "road_velocity", "distance", "vehicle_speed", "iri"],
    "QuarterCar": ["road_height", "sprung_mass", "acc_sprung", "acc_unsprung", "susp_deflection",
                   "acc_sprung_true", "acc_unsprung_true", "z_s", "v_s", "z_u", "v_u", "tire_deflection",
                   "tire_force"],
    "SuspensionEstimator": ["road_height_est", "road_velocity_est", "road_height_std", "sprung_mass_est",
                            "road_class_est", "susp_deflection_est", "nis", "status", "iri_est"],
}
_TABLE = {"ISORoad": "road", "QuarterCar": "plant", "SuspensionEstimator": "estimator"}


@dataclass
class Run:
    """The outcome of ``run_scenario``: the record (structured array), where it was written, the
    wall-clock time in s, and whether the estimator took part."""

    scenario: Scenario
    system: System
    result: np.ndarray
    csv: Path | None
    wall_time: float
    with_estimator: bool


def choose_system(scenario: Scenario, dist: Path = DIST) -> System:
    """The system the scenario asks for, read from ``dist/<system>.ssp`` (written if missing or stale);
    the FMUs are loaded from ``dist``."""
    dist = Path(dist)
    has_estimator = (dist / "SuspensionEstimator.fmu").is_file()
    if scenario.system == "road_plant_estimator" and not has_estimator:
        raise ScenarioError(f"scenario {scenario.path.name}: system road_plant_estimator needs "
                            f"SuspensionEstimator.fmu, which is not in {dist}")
    name = ROAD_PLANT_ESTIMATOR if scenario.system == "road_plant_estimator" or (
        scenario.system == "auto" and has_estimator) else ROAD_PLANT
    return read_ssp(ensure_system_ssp(dist, name), fmu_dir=dist)


def _check_parameters(scenario: Scenario, parameters: dict, variables: dict[str, dict]) -> None:
    """Unknown names and wrong types, reported with the scenario key."""
    where = f"scenario {scenario.path.name}"
    for key, value in parameters.items():
        inst, var = key.split(".", 1)
        table = _TABLE.get(inst, inst)
        v = variables[inst].get(var)
        if v is None or v.causality != "parameter":
            names = ", ".join(n for n, x in variables[inst].items() if x.causality == "parameter")
            raise ScenarioError(f"{where}: '{table}.{var}' is not a parameter of {inst} (parameters: {names})")
        ok = {"Real": isinstance(value, (int, float)) and not isinstance(value, bool),
              "Integer": isinstance(value, int) and not isinstance(value, bool),
              "Boolean": isinstance(value, bool),
              "String": isinstance(value, str)}.get(v.type, True)
        if not ok:
            raise ScenarioError(f"{where}: '{table}.{var}' must be a {v.type}, got {value!r}")


def run_scenario(scenario: Scenario, dist: Path = DIST, out: Path | None = None,
                 progress: Callable[[int], None] | None = None) -> Run:
    """Co-simulate ``scenario`` with the FMUs in ``dist``; write ``out/<scenario>.csv`` if ``out``.

    Raises ``ScenarioError`` for a scenario that does not fit the FMUs, and ``SimulationError``
    when an FMU refuses: after writing the record up to the refused step, or, when it refused at
    initialization, writing no file (and removing the one an earlier run left at that path).
    """
    system = choose_system(scenario, dist)
    with_estimator = "SuspensionEstimator" in system.components
    parameters = scenario.parameters(with_estimator)
    inputs = {"vehicle_speed": scenario.speed, "QuarterCar.sprung_mass": scenario.sprung_mass}
    csv = Path(out) / f"{scenario.name}.csv" if out is not None else None
    t0 = _time.perf_counter()
    variables = model_variables(system)
    _check_parameters(scenario, parameters, variables)
    record = [f"{i}.{v}" for i, names in RECORD.items() if i in variables for v in names if v in variables[i]]
    for key in scenario.record:
        inst, var = key.split(".", 1)
        if inst not in variables or var not in variables[inst]:
            raise ScenarioError(f"scenario {scenario.path.name}: 'output.record' names {key}, "
                                f"which is not a variable of this system ({', '.join(system.components)})")
        record.append(key)
    try:
        with CoSimulation(system, parameters=parameters, inputs=inputs, record=record) as sim:
            result = sim.run(scenario.duration, scenario.step, progress=progress)
    except SimulationError as e:
        if csv is not None:
            if e.result is not None and len(e.result):
                write_csv(csv, e.result)
            else:  # refused at initialization: no result, and none of an earlier run left to mistake for it
                csv.unlink(missing_ok=True)
        raise
    if csv is not None:
        write_csv(csv, result)
    return Run(scenario, system, result, csv, _time.perf_counter() - t0, with_estimator)


def summary(run: Run) -> list[str]:
    """A few lines: the run, the plant response and, with the estimator, the scores of harness/metrics."""
    r = run.result
    n = len(r) - 1
    lines = [f"{run.scenario.name}: {' -> '.join(run.system.order)}, {r['time'][-1]:.6g} s in {n} steps, "
             f"{run.wall_time:.2f} s wall ({1e6 * run.wall_time / max(n, 1):.0f} us/step)"]

    def rms(x):
        return float(np.sqrt(np.mean(np.square(x))))

    lines.append(f"  road: {r['ISORoad.distance'][-1]:.1f} m travelled, height rms {1e3 * rms(r['ISORoad.road_height']):.2f} mm")
    lines.append(f"  plant: acc_sprung rms {rms(r['QuarterCar.acc_sprung_true']):.3f} m/s2, "
                 f"acc_unsprung rms {rms(r['QuarterCar.acc_unsprung_true']):.3f} m/s2, "
                 f"|susp_deflection| max {1e3 * np.max(np.abs(r['QuarterCar.z_s'] - r['QuarterCar.z_u'])):.2f} mm")
    if run.with_estimator:
        from . import metrics

        t = r["time"]
        warmup = metrics.warmup_for(t)
        std = r["SuspensionEstimator.road_height_std"] if "SuspensionEstimator.road_height_std" in r.dtype.names else None
        try:
            s = metrics.road_scores(t, r["SuspensionEstimator.road_height_est"], r["ISORoad.road_height"], std,
                                    warmup=warmup)
            lines.append(f"  road estimate (after {warmup:g} s): error std {s['err_std_raw_pct']:.1f} % raw, "
                         f"{s['err_std_hp_pct']:.1f} % high-passed; rmse {s['rmse_raw_mm']:.2f} mm raw, "
                         f"{s['rmse_hp_mm']:.2f} mm high-passed"
                         + (f"; within 2 sigma {100 * s['coverage_2sigma']:.0f} %" if "coverage_2sigma" in s else ""))
        except Exception as e:  # noqa: BLE001 - a failing score must not hide the run
            lines.append(f"  road estimate: no score ({type(e).__name__}: {e})")
        if "SuspensionEstimator.iri_est" in r.dtype.names:
            rows = metrics.iri_segments(r["ISORoad.distance"], r["ISORoad.iri"], r["SuspensionEstimator.iri_est"])
            if rows:
                lines.append("  IRI per segment (m/km, true / estimated / error): " + "; ".join(
                    f"{d:.0f} m {t:.2f} / {e:.2f} / {p:+.1f} %" for d, t, e, p in rows))
        err = metrics.mass_error_pct(r["SuspensionEstimator.sprung_mass_est"], r["QuarterCar.sprung_mass"])
        tail = t >= t[0] + 0.75 * (t[-1] - t[0])
        lines.append(f"  sprung mass: estimate {r['SuspensionEstimator.sprung_mass_est'][-1]:.1f} kg at the end "
                     f"(true {r['QuarterCar.sprung_mass'][-1]:.1f} kg), mean |error| over the last quarter "
                     f"{np.mean(np.abs(err[tail])):.2f} %")
    return lines
