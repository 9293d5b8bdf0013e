"""What a strict importer reads in the model descriptions of the built FMUs and of the container:
the outputs' dependencies (checked against the FMUs' behaviour), min/max from the contract's
ranges, DefaultExperiment, version, generationDateAndTime, units, author and licence, and that
`fmpy validate` and `fmutool -check` find nothing."""
from __future__ import annotations

import datetime
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from conftest import ROOT
from fmu_driver import Driven
from suspension_estimation.suspension_fmi.contract import CONTRACTS, DEPENDENCIES

NAMES = list(CONTRACTS)
CONTAINER = "SuspensionSystem"
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _fmutool_check(fmu: Path) -> str:
    exe = Path(sys.executable).with_name("fmutool")
    proc = subprocess.run([str(exe), "-input", str(fmu), "-check"], capture_output=True, text=True, timeout=120)
    return proc.stdout + proc.stderr


@pytest.mark.parametrize("name", [*NAMES, CONTAINER])
def test_fmpy_validate_and_fmutool_check_are_clean(dist, name):
    fmu = dist / f"{name}.fmu"
    assert validate_fmu(str(fmu)) == []
    out = _fmutool_check(fmu)
    assert "seems to be compliant with FMI-2.0" in out and "No semantic error" in out, out
    assert "ERROR" not in out, out


def _when(md) -> datetime.datetime:
    return datetime.datetime.strptime(md.generationDateAndTime, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=datetime.timezone.utc)


@pytest.mark.parametrize("name", NAMES)
def test_header_and_default_experiment(dist, name):
    md = read_model_description(str(dist / f"{name}.fmu"))
    assert md.version == PROJECT["version"]
    assert md.license == PROJECT["license"] and md.author
    assert abs(datetime.datetime.now(datetime.timezone.utc) - _when(md)) < datetime.timedelta(hours=6)
    assert md.defaultExperiment is not None
    assert float(md.defaultExperiment.stepSize) == 1e-3 and float(md.defaultExperiment.startTime) == 0.0


@pytest.mark.parametrize("name", NAMES)
def test_every_ranged_parameter_and_input_declares_min_and_max(dist, name):
    variables = {v.name: v for v in read_model_description(str(dist / f"{name}.fmu")).modelVariables}
    ranged = 0
    for var in CONTRACTS[name]:
        v = variables[var.name]
        if var.causality == "output" or var.allowed is None:
            assert v.min is None and v.max is None, var.name
            continue
        low, high = (min(var.allowed), max(var.allowed)) if isinstance(var.allowed, dict) else var.allowed[:2]
        assert (float(v.min), float(v.max)) == (low, high), var.name
        assert float(v.min) <= float(v.start) <= float(v.max), var.name
        ranged += 1
    assert ranged >= 5


@pytest.mark.parametrize("name", NAMES)
def test_outputs_declare_the_dependencies_of_the_contract(dist, name):
    md = read_model_description(str(dist / f"{name}.fmu"))
    assert {u.variable.name for u in md.outputs} == {v.name for v in CONTRACTS[name] if v.causality == "output"}
    for u in md.outputs:
        want = list(DEPENDENCIES[name].get(u.variable.name, ()))
        assert [v.name for v in u.dependencies] == want, u.variable.name
        assert u.dependenciesKind == ["dependent"] * len(want)


# a value of each Real input, inside its range, unlike its start value
_OTHER = {"vehicle_speed": 25.0, "road_height": 0.05, "sprung_mass": 600.0,
          "acc_sprung": 3.0, "acc_unsprung": -20.0, "susp_deflection": 0.02,
          "road_height_front": 0.05, "road_height_rear": -0.03, "force_front": 500.0, "force_rear": -300.0,
          "heave_velocity": 0.1, "pitch_rate": 0.05, "v_u_front": 0.2, "v_u_rear": -0.2, "susp_deflection_front": 0.01,
          "susp_deflection_rear": -0.01, "tire_deflection_front": 0.002, "tire_deflection_rear": -0.002,
          "road_class": 1, "acc_body_front": 1.0, "acc_body_rear": -1.0, "acc_unsprung_front": 5.0,
          "acc_unsprung_rear": -5.0}


@pytest.mark.parametrize("name", NAMES)
def test_no_output_moves_when_an_input_is_set_at_a_communication_point(dist, name):
    """The dependencies declared are the FMUs' behaviour: after some steps, each input set to
    another value changes no output it is not declared to depend on until the next doStep, and
    that doStep does change some output (the input is used)."""
    d = Driven(dist / f"{name}.fmu", {})
    try:
        outputs = [v.name for v in CONTRACTS[name] if v.causality == "output"]
        inputs = [v.name for v in CONTRACTS[name] if v.causality == "input"]
        for _ in range(50):
            d.step(1e-3)
        for inp in inputs:
            before = {o: d.get(o) for o in outputs}
            d.set(inp, _OTHER[inp])
            after = {o: d.get(o) for o in outputs}
            free = [o for o in outputs if inp not in DEPENDENCIES[name].get(o, ())]
            assert {o: after[o] for o in free} == {o: before[o] for o in free}, inp
        before = {o: d.get(o) for o in outputs}
        d.step(1e-3)
        assert {o: d.get(o) for o in outputs} != before
        assert not [m for s, m in d.messages if s >= 2]
    finally:
        d.close()


def test_generation_date_follows_source_date_epoch_and_the_guid_does_not(dist, tmp_path):
    env = {**os.environ, "SOURCE_DATE_EPOCH": "1700000000"}
    for out in ("a", "b"):
        proc = subprocess.run([sys.executable, str(ROOT / "build.py"), "--dist", str(tmp_path / out), "ISORoad"],
                              capture_output=True, text=True, env=env)
        assert proc.returncode == 0, proc.stderr
    xml = [zipfile.ZipFile(tmp_path / o / "ISORoad.fmu").read("modelDescription.xml") for o in ("a", "b")]
    assert xml[0] == xml[1]  # a reproducible build
    md = read_model_description(str(tmp_path / "a" / "ISORoad.fmu"))
    assert md.generationDateAndTime == "2023-11-14T22:13:20Z"
    assert md.guid == read_model_description(str(dist / "ISORoad.fmu")).guid  # another date, same model


def test_container_carries_units_descriptions_author_licence_and_dependencies(dist):
    md = read_model_description(str(dist / f"{CONTAINER}.fmu"))
    fmus = {n: read_model_description(str(dist / f"{n}.fmu")) for n in NAMES}
    assert (md.author, md.license, md.version) == (fmus["ISORoad"].author, PROJECT["license"], PROJECT["version"])
    units = {u.name for u in md.unitDefinitions}
    for v in md.modelVariables:
        assert v.description, v.name
        if v.causality == "independent":
            continue
        if v.type == "Real":
            assert v.unit in units, v.name
        inst, _, var = v.name.partition(".")
        if inst in fmus:  # "Instance.variable": the unit and range of that FMU variable
            src = next(s for s in fmus[inst].modelVariables if s.name == var)
            assert (v.unit, v.min, v.max) == (src.unit, src.min, src.max), v.name
    speed = next(v for v in md.modelVariables if v.name == "vehicle_speed")
    assert (speed.unit, float(speed.min), float(speed.max)) == ("m/s", 0.0, 100.0)
    assert all(u.dependencies == [] and u.dependenciesKind == [] for u in md.outputs)
    # fmucontainer 2.0's runtime does not implement fmi2GetFMUstate: the flag must not claim it
    assert md.coSimulation.canGetAndSetFMUstate is False
    assert md.defaultExperiment.stopTime is None and float(md.defaultExperiment.stepSize) == 1e-3

