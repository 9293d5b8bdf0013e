"""SSP 1.0 files (System Structure and Parameterization) for the project's systems.

An ``.ssp`` is a zip with ``SystemStructure.ssd`` and the FMUs under ``resources/``, so the
same wiring runs in FMPy (``fmpy.ssp.simulation.simulate_ssp``) and in other SSP tools. The
harness reads the structure back with FMPy's SSP reader (``fmpy.ssp.ssd.read_ssd``).

Systems (component names are the model identifiers, so records read ``ISORoad.road_height``):

- ``RoadPlant.ssp``: ISORoad.road_height -> QuarterCar.road_height
- ``RoadPlantEstimator.ssp``: the above, plus QuarterCar.acc_sprung / acc_unsprung /
  susp_deflection -> SuspensionEstimator inputs of the same names

- ``HalfCarLoop.ssp``: paper 002's closed loop, ISORoad.road_height / road_height_rear ->
  HalfCar, HalfCar's measured outputs -> HalfCarEstimator, HalfCarEstimator's ``*_est`` and
  ``road_class_est`` -> SuspensionController, its forces -> HalfCar and HalfCarEstimator. The
  controller's ``sprung_mass`` is not wired, as the plant's is not (below): it keeps its start
  value, HalfCar's 672 kg. The harness's loop (``harness.studies.paper002``) adds
  ``sprung_mass_est`` -> ``sprung_mass``.

In all, ``vehicle_speed`` (m/s) is an input of the system feeding ISORoad (and the estimator,
and the controller). libcosim (the Open Simulation Platform's SSP loader) accepts no
connection from a connector of the system itself (it requires ``startElement``, which SSP 1.0
leaves out for one), so such inputs are not written as connectors and connections: an
annotation of type ``INPUTS_ANNOTATION`` lists them, and ``read_ssp`` turns them back into the
harness's system inputs. SSP runners (FMPy's, libcosim) leave those FMU inputs at their start
values (11.1111 m/s). The plant's ``sprung_mass`` input is not wired either: SSP runners start
connections at 0.0, which the plant would refuse; it keeps its start value (410 kg) unless the
harness drives it. The default experiment carries libcosim's fixed step (1 ms).
"""
from __future__ import annotations

import zipfile
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, fromstring, indent, register_namespace, tostring

from fmpy import read_model_description

from .cosim import System

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
OSP_NS = "http://opensimulationplatform.com/SSP/OSPAnnotations"
# annotation of the system listing its inputs:
# <inputs:Inputs><inputs:Input name="..." endElement="..." endConnector="..."/>...</inputs:Inputs>
INPUTS_ANNOTATION = "org.suspension-estimation-fmu.system-inputs"
INPUTS_NS = "urn:suspension-estimation-fmu:system-inputs"
STEP = 1e-3  # s, the fixed step the default experiment asks libcosim for

# SI base-unit exponents of the units the connectors use (as in the FMUs' UnitDefinitions)
_UNITS = {"m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s2": {"m": 1, "s": -2}, "kg": {"kg": 1}}

register_namespace("ssd", SSD_NS)
register_namespace("ssc", SSC_NS)
register_namespace("osp", OSP_NS)
register_namespace("inputs", INPUTS_NS)

ROAD_PLANT = "RoadPlant"
ROAD_PLANT_ESTIMATOR = "RoadPlantEstimator"
HALF_CAR_LOOP = "HalfCarLoop"
# the controller's relative states (controllers.lqr.STATES), HalfCarEstimator's "<name>_est"
HALF_CAR_STATES = ("heave_velocity", "pitch_rate", "v_u_front", "v_u_rear", "susp_deflection_front",
                   "susp_deflection_rear", "tire_deflection_front", "tire_deflection_rear")
HALF_CAR_MEASURED = ("acc_body_front", "acc_body_rear", "acc_unsprung_front", "acc_unsprung_rear",
                     "susp_deflection_front", "susp_deflection_rear")

# system name -> (components in stepping order, connections, outputs declared as connectors)
SYSTEMS: dict[str, tuple[list[str], list[tuple[str, str]], dict[str, list[str]]]] = {
    ROAD_PLANT: (
        ["ISORoad", "QuarterCar"],
        [("vehicle_speed", "ISORoad.vehicle_speed"),
         ("ISORoad.road_height", "QuarterCar.road_height")],
        {"ISORoad": ["road_velocity", "distance"],
         "QuarterCar": ["acc_sprung", "acc_unsprung", "susp_deflection", "acc_sprung_true",
                        "acc_unsprung_true", "z_s", "v_s", "z_u", "v_u", "tire_deflection", "tire_force"]},
    ),
    ROAD_PLANT_ESTIMATOR: (
        ["ISORoad", "QuarterCar", "SuspensionEstimator"],
        [("vehicle_speed", "ISORoad.vehicle_speed"),
         ("vehicle_speed", "SuspensionEstimator.vehicle_speed"),
         ("ISORoad.road_height", "QuarterCar.road_height"),
         ("QuarterCar.acc_sprung", "SuspensionEstimator.acc_sprung"),
         ("QuarterCar.acc_unsprung", "SuspensionEstimator.acc_unsprung"),
         ("QuarterCar.susp_deflection", "SuspensionEstimator.susp_deflection")],
        {"ISORoad": ["road_velocity", "distance"],
         "QuarterCar": ["acc_sprung_true", "acc_unsprung_true", "z_s", "v_s", "z_u", "v_u",
                        "tire_deflection", "tire_force"],
         "SuspensionEstimator": ["road_height_est", "road_velocity_est", "road_height_std", "sprung_mass_est",
                                 "road_class_est", "nis", "status"]},
    ),
    HALF_CAR_LOOP: (
        ["ISORoad", "HalfCar", "HalfCarEstimator", "SuspensionController"],
        [("vehicle_speed", "ISORoad.vehicle_speed"),
         ("vehicle_speed", "HalfCarEstimator.vehicle_speed"),
         ("vehicle_speed", "SuspensionController.vehicle_speed"),
         ("ISORoad.road_height", "HalfCar.road_height_front"),
         ("ISORoad.road_height_rear", "HalfCar.road_height_rear"),
         *((f"HalfCar.{m}", f"HalfCarEstimator.{m}") for m in HALF_CAR_MEASURED),
         *((f"SuspensionController.{f}", f"{c}.{f}") for c in ("HalfCar", "HalfCarEstimator")
           for f in ("force_front", "force_rear")),
         *((f"HalfCarEstimator.{s}_est", f"SuspensionController.{s}") for s in HALF_CAR_STATES),
         ("HalfCarEstimator.road_class_est", "SuspensionController.road_class")],
        {"ISORoad": ["distance"],
         "HalfCar": ["heave_velocity", "pitch_rate", "v_u_front", "v_u_rear", "acc_body_front_true",
                     "acc_body_rear_true", "susp_deflection_front_true", "susp_deflection_rear_true",
                     "tire_deflection_front_true", "tire_deflection_rear_true", "tire_force_front",
                     "tire_force_rear"],
         "HalfCarEstimator": ["sprung_mass_est", "status"],
         "SuspensionController": ["saturated"]},
    ),
}


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _type_element(parent: Element, variable) -> str | None:
    """Add the connector's type (ssc:Real with unit, ssc:Integer, ...); returns the unit."""
    vtype = "Integer" if variable.type == "Enumeration" else variable.type
    el = SubElement(parent, _q(SSC_NS, vtype))
    unit = getattr(variable, "unit", None) or (variable.declaredType.unit if variable.declaredType else None)
    if vtype == "Real" and unit:
        el.set("unit", unit)
        return unit
    return None


def write_ssp(path: Path, name: str, components: dict[str, Path], connections: list[tuple[str, str]],
              outputs: dict[str, list[str]] | None = None, description: str = "",
              stop_time: float | None = None) -> Path:
    """Write an SSP with the FMUs ``components`` (instance name -> FMU file) and ``connections``.

    A connection is ``("instance.output", "instance.input")``, or ``("input", "instance.input")``
    for an input of the system (listed in the ``INPUTS_ANNOTATION`` annotation: see the module doc).
    ``outputs`` adds unconnected output connectors (SSP runners record connectors). Checks
    every name and causality against the FMUs' model descriptions.
    """
    path = Path(path)
    mds = {n: read_model_description(str(f), validate=False) for n, f in components.items()}
    variables = {n: {v.name: v for v in md.modelVariables} for n, md in mds.items()}

    def lookup(ref: str, causality: str):
        inst, var = ref.split(".", 1)
        if inst not in variables:
            raise ValueError(f"{name}: connection names unknown component {inst!r}")
        v = variables[inst].get(var)
        if v is None or v.causality != causality:
            raise ValueError(f"{name}: {ref} is not an {causality} of {components[inst].name}")
        return v

    connectors: dict[str, dict[str, tuple[str, object]]] = {n: {} for n in components}  # name -> var -> kind
    system_inputs: list[tuple[str, str]] = []
    for start, end in connections:
        v_end = lookup(end, "input")
        if "." in start:
            connectors[end.split(".", 1)[0]][end.split(".", 1)[1]] = ("input", v_end)
            v_start = lookup(start, "output")
            connectors[start.split(".", 1)[0]][start.split(".", 1)[1]] = ("output", v_start)
        else:
            system_inputs.append((start, end))
    for inst, names in (outputs or {}).items():
        for var in names:
            connectors[inst].setdefault(var, ("output", lookup(f"{inst}.{var}", "output")))

    root = Element(_q(SSD_NS, "SystemStructureDescription"), {"version": "1.0", "name": name})
    system = SubElement(root, _q(SSD_NS, "System"), {"name": name})
    if description:
        system.set("description", description)
    used_units: list[str] = []
    elements = SubElement(system, _q(SSD_NS, "Elements"))
    for inst, fmu in components.items():
        comp = SubElement(elements, _q(SSD_NS, "Component"), {
            "name": inst, "type": "application/x-fmu-sharedlibrary", "source": f"resources/{Path(fmu).name}"})
        cons = SubElement(comp, _q(SSD_NS, "Connectors"))
        for var, (kind, v) in connectors[inst].items():
            c = SubElement(cons, _q(SSD_NS, "Connector"), {"name": var, "kind": kind})
            if unit := _type_element(c, v):
                used_units.append(unit)
    conns = SubElement(system, _q(SSD_NS, "Connections"))
    for start, end in connections:
        if "." in start:
            attrs = dict(zip(("startElement", "startConnector"), start.split(".", 1)))
            attrs.update(zip(("endElement", "endConnector"), end.split(".", 1)))
            SubElement(conns, _q(SSD_NS, "Connection"), attrs)
    if system_inputs:
        note = SubElement(SubElement(SubElement(system, _q(SSD_NS, "Annotations")), _q(SSC_NS, "Annotation"),
                                     {"type": INPUTS_ANNOTATION}), _q(INPUTS_NS, "Inputs"))
        for start, end in system_inputs:
            SubElement(note, _q(INPUTS_NS, "Input"), {"name": start, **dict(zip(("endElement", "endConnector"), end.split(".", 1)))})
    units = [u for u in dict.fromkeys(used_units) if u in _UNITS]
    if units:
        ue = SubElement(root, _q(SSD_NS, "Units"))
        for u in units:
            SubElement(SubElement(ue, _q(SSC_NS, "Unit"), {"name": u}), _q(SSC_NS, "BaseUnit"),
                       {k: str(e) for k, e in _UNITS[u].items()})
    exp = SubElement(root, _q(SSD_NS, "DefaultExperiment"), {"startTime": "0"})
    if stop_time is not None:
        exp.set("stopTime", repr(float(stop_time)))
    osp = SubElement(SubElement(exp, _q(SSD_NS, "Annotations")), _q(SSC_NS, "Annotation"),
                     {"type": "com.opensimulationplatform"})
    SubElement(SubElement(osp, _q(OSP_NS, "Algorithm")), _q(OSP_NS, "FixedStepAlgorithm"),
               {"baseStepSize": repr(STEP)})

    indent(root)
    xml = b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root) + b"\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", xml)
        for fmu in dict.fromkeys(Path(f) for f in components.values()):
            z.write(fmu, f"resources/{fmu.name}", compress_type=zipfile.ZIP_STORED)  # an FMU is a zip already
    tmp.replace(path)
    return path


def write_system_ssps(dist: Path) -> list[Path]:
    """Write ``<name>.ssp`` of every system of ``SYSTEMS`` whose FMUs are all in ``dist``, from those
    FMUs (``RoadPlant.ssp`` needs only ISORoad and QuarterCar). Returns the files written."""
    dist = Path(dist)
    written = []
    for name, (order, connections, outputs) in SYSTEMS.items():
        fmus = {c: dist / f"{c}.fmu" for c in order}
        if not all(f.is_file() for f in fmus.values()):
            continue
        desc = " -> ".join(order) + "; input vehicle_speed (m/s)"
        written.append(write_ssp(dist / f"{name}.ssp", name, fmus, connections, outputs, desc, stop_time=20.0))
    return written


def ensure_system_ssp(dist: Path, name: str) -> Path:
    """``dist/<name>.ssp``, (re-)written when missing or older than one of its FMUs."""
    dist = Path(dist)
    order, connections, outputs = SYSTEMS[name]
    fmus = {c: dist / f"{c}.fmu" for c in order}
    for f in fmus.values():
        if not f.is_file():
            raise FileNotFoundError(f"{f.name} is not in {dist} (run build.py)")
    path = dist / f"{name}.ssp"
    if not path.is_file() or any(f.stat().st_mtime > path.stat().st_mtime for f in fmus.values()):
        desc = " -> ".join(order) + "; input vehicle_speed (m/s)"
        write_ssp(path, name, fmus, connections, outputs, desc, stop_time=20.0)
    return path


def read_ssp(path: Path, fmu_dir: Path | None = None) -> System:
    """The ``System`` (components, connections, stepping order) of an SSP, read with FMPy's reader.

    Only a flat system of FMU components is supported. The FMUs are taken from ``fmu_dir``
    (by file name) when given, else extracted from the SSP into a temporary folder that lives
    as long as the process (see ``extract_ssp_fmus``).
    The stepping order is the components' order in the SSD, adjusted so connections point forward.
    """
    from fmpy.ssp.ssd import Component, read_ssd

    path = Path(path)
    ssd = read_ssd(str(path))
    system = ssd.system
    components = {}
    for el in system.elements:
        if not isinstance(el, Component):
            raise ValueError(f"{path.name}: element {el.name!r} is not an FMU component (nested systems are not supported)")
        components[el.name] = el.source
    connections = _annotated_inputs(path)
    for c in system.connections:
        if c.endElement is None:
            continue  # to a system output: nothing for the master to do
        start = c.startConnector if c.startElement is None else f"{c.startElement}.{c.startConnector}"
        connections.append((start, f"{c.endElement}.{c.endConnector}"))
    if fmu_dir is not None:
        files = {n: Path(fmu_dir) / Path(src).name for n, src in components.items()}
    else:
        files = extract_ssp_fmus(path, components)
    return System(components=files, connections=connections, name=system.name or path.stem)


def _annotated_inputs(path: Path) -> list[tuple[str, str]]:
    """The system inputs an SSP lists in its ``INPUTS_ANNOTATION`` annotation, as connections."""
    with zipfile.ZipFile(path) as z:
        root = fromstring(z.read("SystemStructure.ssd"))
    found = []
    for note in root.iterfind(f"{_q(SSD_NS, 'System')}/{_q(SSD_NS, 'Annotations')}/{_q(SSC_NS, 'Annotation')}"):
        if note.get("type") == INPUTS_ANNOTATION:
            found += [(i.get("name"), f"{i.get('endElement')}.{i.get('endConnector')}") for i in note.iter(_q(INPUTS_NS, "Input"))]
    return found


_EXTRACTED: dict[tuple[Path, float], Path] = {}


def extract_ssp_fmus(path: Path, components: dict[str, str]) -> dict[str, Path]:
    """Extract the FMUs an SSP holds (once per SSP and process) and return instance -> FMU file."""
    import atexit
    import shutil
    import tempfile

    key = (Path(path).resolve(), Path(path).stat().st_mtime)
    if key not in _EXTRACTED:
        out = Path(tempfile.mkdtemp(prefix="harness-ssp-"))
        atexit.register(shutil.rmtree, out, True)
        with zipfile.ZipFile(path) as z:
            z.extractall(out)
        _EXTRACTED[key] = out
    out = _EXTRACTED[key]
    files = {}
    for n, src in components.items():
        f = (out / src).resolve()
        if not f.is_relative_to(out.resolve()) or not f.is_file():
            raise ValueError(f"{Path(path).name}: component {n!r} source {src!r} is not in the SSP")
        files[n] = f
    return files
