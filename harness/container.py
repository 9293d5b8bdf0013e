"""The container FMUs, each a system of ``harness.ssp.SYSTEMS`` in one FMI 2.0 co-simulation FMU,
built by fmu-manipulation-toolbox's ``fmucontainer`` (a native C master that loads the FMUs inside
it) from a wiring file that ``build.py`` writes next to it (``CONTAINERS``):

- ``SuspensionSystem.fmu``: ISORoad -> QuarterCar -> SuspensionEstimator (below);
- ``HalfCarSystem.fmu``: paper 002's closed loop ISORoad -> HalfCar <- SuspensionController <-
  HalfCarEstimator (``HalfCarLoop.ssp``), its container inputs ``vehicle_speed``, ``sprung_mass``
  (HalfCar's payload and the mass the controller designs for) and HalfCarEstimator's velocity
  inputs (the paper's sensors, ``"HalfCarEstimator.heave_velocity"``, ...). The controller steps
  after the plant, so the plant gets each force a step after the controller computed it, as in
  the harness.

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
this step (``-sequential``: no connection lags a step but one back to an FMU stepped earlier), with
an internal step of 1 ms, so the container reproduces the harness (``harness.cosim``, Gauss-Seidel)
exactly. Equivalent command line:

    fmucontainer -container SuspensionSystem.csv:0.001 -fmu-directory dist -sequential \\
                 -no-auto-input -no-auto-output -no-auto-link

fmucontainer writes a model description with no units, "Proprietary" as licence and the login
name as author; ``complete_description`` then gives every variable the unit, range and
description of the FMU variable it stands for, and the container the FMUs' author, licence and
version. It cannot give FMU state: fmucontainer 2.0's runtime does not implement
fmi2GetFMUstate (it returns fmi2Error), so ``canGetAndSetFMUstate`` stays false.
"""
from __future__ import annotations

import logging
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, fromstring, indent, tostring

from fmpy import read_model_description

from .ssp import HALF_CAR_LOOP, ROAD_PLANT_ESTIMATOR, SYSTEMS


@dataclass(frozen=True)
class Container:
    """One container FMU: its name, the system it wires (``harness.ssp.SYSTEMS``), its internal
    step (s), the container input of each FMU input no connection feeds, and for a closed loop
    the FMUs at which fmucontainer cuts its loops at initialization (they start on their inputs'
    start values, as in the harness; fmucontainer warns, and any other warning is an error)."""

    name: str
    system: str
    step: float
    inputs: dict[str, str]
    loop_cuts: tuple[str, ...] = ()


SUSPENSION_SYSTEM = Container("SuspensionSystem", ROAD_PLANT_ESTIMATOR, 1e-3, {"QuarterCar.sprung_mass": "sprung_mass"})
HALF_CAR_SYSTEM = Container(
    "HalfCarSystem", HALF_CAR_LOOP, 1e-3,
    {"HalfCar.sprung_mass": "sprung_mass", "SuspensionController.sprung_mass": "sprung_mass",
     **{f"HalfCarEstimator.{v}": f"HalfCarEstimator.{v}" for v in ("heave_velocity", "pitch_rate", "v_u_front",
                                                                   "v_u_rear")}},
    loop_cuts=("HalfCar", "HalfCarEstimator"))
CONTAINERS: dict[str, Container] = {c.name: c for c in (SUSPENSION_SYSTEM, HALF_CAR_SYSTEM)}
CONTAINER, STEP, INPUTS = SUSPENSION_SYSTEM.name, SUSPENSION_SYSTEM.step, SUSPENSION_SYSTEM.inputs


def wiring(dist: Path, container: Container = SUSPENSION_SYSTEM) -> list[tuple[str, str, str, str, str]]:
    """Rows ``(rule, from_fmu, from_port, to_fmu, to_port)`` of the fmucontainer CSV for the FMUs
    in ``dist``: FMUs in stepping order, inputs, links, outputs and parameters (see the module doc)."""
    order, connections, _ = SYSTEMS[container.system]
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
                if name not in container.inputs:
                    raise ValueError(f"{name} is fed by no connection and has no container input")
                rows.append(("INPUT", "", container.inputs[name], fmu[c], v.name))
            elif v.causality == "output":
                rows.append(("OUTPUT", fmu[c], v.name, "", name))
            elif v.causality == "parameter":
                rows.append(("INPUT", "", name, fmu[c], v.name))
    return rows


def write_wiring(dist: Path, container: Container = SUSPENSION_SYSTEM) -> Path:
    """Write ``dist/<name>.csv`` (fmucontainer's CSV format) and return it."""
    path = Path(dist) / f"{container.name}.csv"
    lines = ["rule;from_fmu;from_port;to_fmu;to_port"] + [";".join(r) for r in wiring(dist, container)]
    path.write_text("\n".join(lines) + "\n")
    return path


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def build_container(dist: Path, step: float | None = None, container: Container = SUSPENSION_SYSTEM) -> Path:
    """Write the wiring file and build ``dist/<name>.fmu`` from the FMUs in ``dist`` (internal
    step ``step`` in s, the container's own by default). Raises ``RuntimeError`` with fmucontainer's
    first error: fmucontainer only logs some of them (a CSV line it cannot use is skipped, not
    refused)."""
    from fmu_manipulation_toolbox.assembly import Assembly

    dist = Path(dist)
    step = container.step if step is None else step
    out = dist / f"{container.name}.fmu"
    out.unlink(missing_ok=True)
    csv = write_wiring(dist, container)
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
    cuts = tuple(f"Loop of links through the embedded FMU '{c}.fmu':" for c in container.loop_cuts)
    problems = [r.getMessage() for r in handler.records if not (cuts and r.getMessage().startswith(cuts))]
    if problems:
        raise RuntimeError(f"fmucontainer: {problems[0]}")
    if not out.is_file():
        raise RuntimeError(f"fmucontainer did not write {out.name}")
    complete_description(out, dist, container)
    return out


def complete_description(path: Path, dist: Path, container: Container = SUSPENSION_SYSTEM) -> None:
    """Rewrite ``modelDescription.xml`` of the container FMU ``path`` (built from the FMUs in ``dist``) with the
    units, UnitDefinitions, min/max and descriptions of the FMU variables its variables stand for,
    the FMUs' author, licence and version, and the outputs' dependencies (none, when no FMU has
    direct feedthrough: a container output then changes only in doStep, like the FMUs' own)."""
    order = SYSTEMS[container.system][0]
    mds = {c: read_model_description(str(Path(dist) / f"{c}.fmu"), validate=False) for c in order}
    fmu_vars = {c: {v.name: v for v in md.modelVariables} for c, md in mds.items()}
    feeds = {}  # container input or output -> (instance, FMU variable)
    for rule, from_fmu, from_port, to_fmu, to_port in wiring(dist, container):
        if rule == "INPUT":
            feeds.setdefault(from_port, (to_fmu.removesuffix(".fmu"), to_port))
        elif rule == "OUTPUT":
            feeds[to_port] = (from_fmu.removesuffix(".fmu"), from_port)
    by_lower = {c.lower(): c for c in order}

    def source(name: str):
        """The FMU variable a container variable stands for, or None (``time``)."""
        if name in feeds:
            inst, var = feeds[name]
        elif "." in name and name.split(".", 1)[0].lower() in by_lower:  # "Inst.var", links "inst.var"
            inst, var = by_lower[name.split(".", 1)[0].lower()], name.split(".", 1)[1]
        else:
            return None
        return fmu_vars[inst].get(var)

    with zipfile.ZipFile(path) as z:
        entries = [(info, z.read(info)) for info in z.infolist()]
    root = fromstring(dict((i.filename, b) for i, b in entries)["modelDescription.xml"])
    first = mds[order[0]]
    for attr in ("author", "license", "version"):
        values = {getattr(md, attr) for md in mds.values()}
        if len(values) != 1 or None in values:
            raise RuntimeError(f"the FMUs disagree on {attr}: {sorted(map(str, values))}")
        root.set(attr, values.pop())
    root.attrib.pop("copyright", None)  # "See Embedded FMU's copyrights.": they declare none
    experiment = root.find("DefaultExperiment")
    if experiment is not None and first.defaultExperiment is not None and first.defaultExperiment.stopTime is None:
        experiment.attrib.pop("stopTime", None)  # fmucontainer's own default, not the FMUs'
    used = []
    svs = list(root.find("ModelVariables"))
    for sv in svs:
        typed = sv[0]
        if sv.get("causality") == "independent":
            sv.set("description", "simulation time")
            continue
        var = source(sv.get("name"))
        if var is None:
            continue
        if var.description and not sv.get("description"):
            sv.set("description", var.description)
        if var.unit:
            typed.set("unit", var.unit)
            used.append(var.unit)
        if sv.get("causality") in ("parameter", "input"):
            for attr in ("min", "max"):
                if (value := getattr(var, attr)) is not None:
                    typed.set(attr, value)
    definitions = {u.name: u for u in first.unitDefinitions}
    for md in mds.values():
        definitions.update({u.name: u for u in md.unitDefinitions})
    if used:
        units = Element("UnitDefinitions")
        for name in dict.fromkeys(used):
            base = definitions[name].baseUnit
            exps = {k: str(getattr(base, k)) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
                    if getattr(base, k, 0)} if base is not None else {}
            SubElement(SubElement(units, "Unit", name=name), "BaseUnit", exps)
        root.insert(list(root).index(root.find("CoSimulation")) + 1, units)
    no_feedthrough = all(u.dependencies == [] for md in mds.values() for u in md.outputs)
    outputs = root.find("ModelStructure/Outputs")
    if no_feedthrough and outputs is not None:
        for unknown in outputs:
            unknown.set("dependencies", "")
            unknown.set("dependenciesKind", "")
    indent(root)
    xml = b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root) + b"\n"
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w") as z:
        for info, data in entries:
            z.writestr(info, xml if info.filename == "modelDescription.xml" else data)
    tmp.replace(path)
