"""``SuspensionSystem.fmu``: ISORoad -> QuarterCar -> SuspensionEstimator in one FMI 2.0
co-simulation FMU, built by fmu-manipulation-toolbox's ``fmucontainer`` (a native C master that
loads the three FMUs inside it) from a wiring file that ``build.py`` writes next to it.

The wiring is the one of ``RoadPlantEstimator.ssp`` (``harness.ssp.SYSTEMS``):

- container inputs: ``vehicle_speed`` (m/s, to ISORoad and SuspensionEstimator) and
  ``sprung_mass`` (kg, the plant's payload input);
- links: ISORoad.road_height -> QuarterCar.road_height, QuarterCar.acc_sprung / acc_unsprung /
  susp_deflection -> SuspensionEstimator;
- container outputs: every output of the three FMUs, named ``"instance.variable"``
  (``ISORoad.road_height``, ``QuarterCar.z_s``, ``SuspensionEstimator.road_height_est``, ...);
- container parameters: every parameter of the three FMUs, named the same way
  (``ISORoad.road_class``, ``QuarterCar.noise_seed``, ...), with the FMUs' start values.

The FMUs step sequentially in that order, each with the outputs the ones before it computed in
this step (``-sequential``: no connection lags a step), with an internal step of 1 ms, so the
container reproduces the harness (``harness.cosim``) exactly. Equivalent command line:

    fmucontainer -container SuspensionSystem.csv:0.001 -fmu-directory dist -sequential \\
                 -no-auto-input -no-auto-output -no-auto-link
"""
from __future__ import annotations

import logging
from pathlib import Path

from fmpy import read_model_description

from .ssp import ROAD_PLANT_ESTIMATOR, SYSTEMS

CONTAINER = "SuspensionSystem"
STEP = 1e-3  # s, internal step of the container
INPUTS = {"QuarterCar.sprung_mass": "sprung_mass"}  # FMU inputs no connection feeds -> container input


def wiring(dist: Path) -> list[tuple[str, str, str, str, str]]:
    """Rows ``(rule, from_fmu, from_port, to_fmu, to_port)`` of the fmucontainer CSV for the FMUs
    in ``dist``: FMUs in stepping order, inputs, links, outputs and parameters (see the module doc)."""
    order, connections, _ = SYSTEMS[ROAD_PLANT_ESTIMATOR]
    fmu = {c: f"{c}.fmu" for c in order}
    rows = [("FMU", fmu[c], "", "", "") for c in order]
    fed = set()
    for start, end in connections:
        inst, var = end.split(".", 1)
        fed.add(end)
        if "." in start:
            s_inst, s_var = start.split(".", 1)
            rows.append(("LINK", fmu[s_inst], s_var, fmu[inst], var))
        else:
            rows.append(("INPUT", "", start, fmu[inst], var))
    for c in order:
        md = read_model_description(str(Path(dist) / fmu[c]), validate=False)
        for v in md.modelVariables:
            name = f"{c}.{v.name}"
            if v.causality == "input" and name not in fed:
                if name not in INPUTS:
                    raise ValueError(f"{name} is fed by no connection and has no container input")
                rows.append(("INPUT", "", INPUTS[name], fmu[c], v.name))
            elif v.causality == "output":
                rows.append(("OUTPUT", fmu[c], v.name, "", name))
            elif v.causality == "parameter":
                rows.append(("INPUT", "", name, fmu[c], v.name))
    return rows


def write_wiring(dist: Path) -> Path:
    """Write ``dist/SuspensionSystem.csv`` (fmucontainer's CSV format) and return it."""
    path = Path(dist) / f"{CONTAINER}.csv"
    lines = ["rule;from_fmu;from_port;to_fmu;to_port"] + [";".join(r) for r in wiring(dist)]
    path.write_text("\n".join(lines) + "\n")
    return path


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def build_container(dist: Path, step: float = STEP) -> Path:
    """Write the wiring file and build ``dist/SuspensionSystem.fmu`` from the FMUs in ``dist``
    (internal step ``step`` in s). Raises ``RuntimeError`` with fmucontainer's first error:
    fmucontainer only logs some of them (a CSV line it cannot use is skipped, not refused)."""
    from fmu_manipulation_toolbox.assembly import Assembly

    dist = Path(dist)
    out = dist / f"{CONTAINER}.fmu"
    out.unlink(missing_ok=True)
    csv = write_wiring(dist)
    logger = logging.getLogger("fmu_manipulation_toolbox")
    handler = _Collect()
    logger.addHandler(handler)
    level = logger.level
    logger.setLevel(logging.WARNING)
    try:
        assembly = Assembly(csv.name, fmu_directory=dist, default_step_size=step, default_sequential=True,
                            default_auto_input=False, default_auto_output=False, default_auto_link=False)
        assembly.make_fmu()
    except Exception as e:  # noqa: BLE001 - FMUContainerError, AssemblyError: one message
        raise RuntimeError(f"fmucontainer: {getattr(e, 'reason', e)}") from None
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
    problems = [r.getMessage() for r in handler.records]
    if problems:
        raise RuntimeError(f"fmucontainer: {problems[0]}")
    if not out.is_file():
        raise RuntimeError(f"fmucontainer did not write {out.name}")
    return out
