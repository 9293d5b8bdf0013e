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
from .scenario import Profile, Scenario, ScenarioError
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

# the parameters ``run`` prints before its results (``parameter_lines``), beside every other one
# the scenario sets and those of a nonlinear spring or damper law in use
SHOWN = {
    "QuarterCar": ("m_u", "k_s", "k_t", "c_s", "spring_model", "damper_model", "acc_sprung_noise_std",
                   "acc_unsprung_noise_std", "defl_noise_std", "noise_seed", "acc_sampling"),
    "SuspensionEstimator": ("m_s_nominal", "m_u", "k_s", "k_t", "c_s", "spring_model", "damper_model",
                            "road_estimator", "mass_estimator", "mass_feedback", "road_class",
                            "acc_sprung_noise_std", "acc_unsprung_noise_std", "defl_noise_std", "acc_sampling"),
}
_LABELS = {"QuarterCar": "vehicle (QuarterCar)", "SuspensionEstimator": "estimator (SuspensionEstimator)"}


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


def _start(var) -> object:
    """A parameter's start value (the model description's text) as a Python value."""
    if var.type == "Real":
        return float(var.start)
    if var.type == "Integer":
        return int(var.start)
    if var.type == "Boolean":
        return var.start in ("true", "1")
    return var.start


def _value_text(name: str, value, var, codes: dict) -> str:
    """``name value unit``; an integer code with its meaning (``codes``: the contract's names of the codes)."""
    if isinstance(value, bool):
        return f"{name} {str(value).lower()}"
    if var.type == "Integer":
        meaning = codes.get(name, {}).get(int(value))
        return f"{name} {int(value)}" + (f" ({meaning})" if meaning else "")
    unit = f" {var.unit}" if var.unit not in (None, "1") else ""
    return f"{name} {value:.6g}{unit}" if isinstance(value, (int, float)) else f"{name} {value!r}"


def _profile_text(p: Profile, unit: str) -> str:
    """A constant, or the breakpoints' values with their times (s)."""
    if p.is_constant:
        return f"{p.value[0]:.6g} {unit}"
    return (" -> ".join(f"{v:.6g}" for v in p.value) + f" {unit} ({p.interpolation} at "
            + ", ".join(f"{t:.6g}" for t in p.time) + " s)")


def parameter_lines(scenario: Scenario, system: System, width: int = 100) -> list[str]:
    """The vehicle's (QuarterCar) and the estimator's parameters a run of ``scenario`` on ``system``
    uses, with units, a few lines each: the ``SHOWN`` ones, those of a nonlinear spring (air_*) or
    damper (damper_*) law in use and every other the scenario sets; the scenario's value, else the
    FMU's start value. ``ScenarioError`` for a parameter the FMUs do not have."""
    from suspension_estimation.suspension_fmi.contract import CONTRACTS

    variables = model_variables(system)
    parameters = scenario.parameters("SuspensionEstimator" in system.components)
    _check_parameters(scenario, parameters, variables)
    lines = []
    for inst, shown in SHOWN.items():
        if inst not in variables:
            continue
        mv = variables[inst]
        codes = {v.name: v.allowed for v in CONTRACTS.get(inst, ()) if isinstance(v.allowed, dict)}
        value = {n: _start(v) for n, v in mv.items() if v.causality == "parameter"}
        given = {k.split(".", 1)[1]: v for k, v in parameters.items() if k.startswith(f"{inst}.")}
        value.update(given)
        laws = (("air_",) if value.get("spring_model") == 1 else ()) + (
            ("damper_c", "damper_knee") if value.get("damper_model") == 1 else ())
        names = dict.fromkeys([*(n for n in shown if n in value), *(n for n in value if laws and n.startswith(laws)),
                               *given])
        items = [_value_text(n, value[n], mv[n], codes) for n in names]
        if inst == "QuarterCar":
            items.insert(0, f"sprung_mass {_profile_text(scenario.sprung_mass, 'kg')}")
        line, on_line = f"  {_LABELS[inst]}:", 0
        for i, item in enumerate(items):  # whole items per line
            text = f" {item}" + ("," if i < len(items) - 1 else "")
            if on_line and len(line) + len(text) > width:
                lines.append(line)
                line, on_line = "   ", 0
            line, on_line = line + text, on_line + 1
        lines.append(line)
    return lines


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
    # with estimator_step: the estimator on the plant's outputs at its steps, the record at them
    every = scenario.estimator_every if with_estimator else 1
    try:
        with CoSimulation(system, parameters=parameters, inputs=inputs, record=record,
                          rates={"SuspensionEstimator": every}) as sim:
            result = sim.run(scenario.duration, scenario.step, progress=progress)[::every]
    except SimulationError as e:
        if e.result is not None:
            e.result = e.result[::every]
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
    n = round((r["time"][-1] - r["time"][0]) / run.scenario.step) if len(r) else 0  # communication steps
    lines = [f"{run.scenario.name}: {' -> '.join(run.system.order)}, {r['time'][-1]:.6g} s in {n} steps, "
             f"{run.wall_time:.2f} s wall ({1e6 * run.wall_time / max(n, 1):.0f} us/step)"
             + (f"; the estimator every {run.scenario.estimator_every} steps (the record at its steps)"
                if run.with_estimator and run.scenario.estimator_every > 1 else "")]

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
        cutoff = run.scenario.profile_cutoff
        try:
            s = metrics.road_scores(t, r["SuspensionEstimator.road_height_est"], r["ISORoad.road_height"], std,
                                    warmup=warmup, distance=r["ISORoad.distance"], cutoff=cutoff)
            lines.append(f"  road profile (high-passed at {cutoff:g} m of travel, after {warmup:g} s): rmse "
                         f"{s['rmse_raw_mm']:.2f} mm of {s['profile_rms_mm']:.2f} mm, {s['rmse_hp_mm']:.2f} mm "
                         f"high-passed at 0.5 Hz (error std {s['err_std_hp_pct']:.1f} %)"
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
