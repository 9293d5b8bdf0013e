"""build.py and the model descriptions: validation, the written contract (docs/fmu-interface.md, generated
from the contract by ``python build.py --docs``), units, rebuilds, names."""
from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from conftest import ROOT
from fmu_driver import Driven

NAMES = ["ISORoad", "QuarterCar", "SuspensionEstimator", "HalfCar", "SuspensionController", "HalfCarEstimator"]
INTERFACE_DOC = ROOT / "docs" / "fmu-interface.md"


def _load_build_script():
    spec = importlib.util.spec_from_file_location("build_script", ROOT / "build.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


build_script = _load_build_script()


def built(dist: Path) -> list[str]:
    return [n for n in NAMES if (dist / f"{n}.fmu").is_file()]


def test_road_and_plant_are_built(dist):
    assert {"ISORoad", "QuarterCar"} <= set(built(dist))


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validate_finds_no_problem(dist, name):
    if name not in built(dist):
        pytest.skip(f"{name}.fmu is not part of this build")
    assert validate_fmu(str(dist / f"{name}.fmu")) == []


def contract_rows(md_text: str) -> dict[str, dict[str, dict]]:
    """{model identifier: {variable: {causality, type, unit, start}}} from docs/fmu-interface.md."""
    out: dict[str, dict[str, dict]] = {}
    current = None
    for line in md_text.splitlines():
        if m := re.match(r"## `(\w+)\.fmu`", line):
            current = out.setdefault(m.group(1), {})
            continue
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if current is None or len(cells) != 7 or not cells[0].startswith("`"):
            continue
        current[cells[0].strip("`")] = {"causality": cells[1], "type": cells[2], "unit": cells[3], "start": cells[4]}
    return out


def test_interface_doc_and_readme_table_are_up_to_date():
    fresh = "run `python build.py --docs` and commit the result"
    assert INTERFACE_DOC.is_file(), f"{INTERFACE_DOC.relative_to(ROOT)} is missing: {fresh}"
    assert INTERFACE_DOC.read_text() == build_script.interface_doc(), \
        f"{INTERFACE_DOC.relative_to(ROOT)} is stale (contract.py changed): {fresh}"
    readme = (ROOT / "README.md").read_text()
    assert build_script.readme_with_table(readme) == readme, f"the FMU table in README.md is stale: {fresh}"


def test_interface_doc_lists_every_variable():
    rows = contract_rows(INTERFACE_DOC.read_text())
    assert set(rows) == set(NAMES) and all(len(v) > 8 for v in rows.values())


@pytest.mark.parametrize("name", NAMES)
def test_model_description_follows_the_written_contract(dist, name):
    if name not in built(dist):
        pytest.skip(f"{name}.fmu is not part of this build")
    rows = contract_rows(INTERFACE_DOC.read_text())[name]
    md = read_model_description(str(dist / f"{name}.fmu"))
    assert md.coSimulation.modelIdentifier == name
    variables = {v.name: v for v in md.modelVariables}
    units = {u.name for u in md.unitDefinitions}
    for var in md.modelVariables:
        assert var.description, f"{var.name} has no description"
        if var.type == "Real":
            assert var.unit and var.unit in units, f"{var.name} has no declared unit"
    for vname, row in rows.items():
        assert vname in variables, f"{name}.{vname} is missing"
        var = variables[vname]
        assert var.causality == row["causality"], vname
        assert var.type == row["type"], vname
        if row["unit"] != "–":
            assert var.unit == row["unit"], vname
        if var.causality == "parameter":
            assert var.variability in ("fixed", "tunable"), vname
        start = row["start"]
        if start:
            if var.type == "Real":
                assert float(var.start) == pytest.approx(float(start)), vname
            elif var.type == "Integer":
                assert int(var.start) == int(start), vname
            elif var.type == "Boolean":
                assert str(var.start).lower() == start, vname
            else:
                assert (var.start or "") == start.strip('"'), vname


def _build(*args) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, str(ROOT / "build.py"), *map(str, args)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return proc


def test_rebuild_is_idempotent_and_only_when_something_changed(dist, tmp_path):
    _build("--dist", tmp_path, "ISORoad")
    fmu = tmp_path / "ISORoad.fmu"
    first = fmu.stat().st_mtime_ns
    assert "ISORoad.fmu is up to date" in _build("--dist", tmp_path, "ISORoad").stdout
    assert fmu.stat().st_mtime_ns == first
    with zipfile.ZipFile(fmu) as a, zipfile.ZipFile(dist / "ISORoad.fmu") as b:
        undated = [re.sub(rb'generationDateAndTime="[^"]*"', b"", z.read("modelDescription.xml")) for z in (a, b)]
        assert undated[0] == undated[1]  # the GUID included
        assert sorted(a.namelist()) == sorted(b.namelist())
    # a stamp that no longer matches the sources (as after an edit) rebuilds, and so does --force
    stamps = tmp_path / build_script.STAMPS
    stamps.write_text(stamps.read_text().replace('"ISORoad": "', '"ISORoad": "0'))
    assert "built" in _build("--dist", tmp_path, "ISORoad").stdout
    assert "built" in _build("--dist", tmp_path, "--force", "ISORoad").stdout


def test_source_hash_follows_content_names_and_options(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "__pycache__").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    h = build_script.source_hash([pkg], {"o": 1})
    (pkg / "__pycache__" / "a.cpython-311.pyc").write_bytes(b"compiled")
    assert build_script.source_hash([pkg], {"o": 1}) == h
    assert build_script.source_hash([pkg], {"o": 2}) != h
    (pkg / "a.py").write_text("x = 2\n")
    edited = build_script.source_hash([pkg], {"o": 1})
    assert edited != h
    (pkg / "a.py").rename(pkg / "b.py")
    assert build_script.source_hash([pkg], {"o": 1}) not in (h, edited)


def test_failing_build_exits_non_zero_with_the_reason(tmp_path):
    proc = subprocess.run([sys.executable, str(ROOT / "build.py"), "--dist", str(tmp_path), "NoSuchFMU"],
                          capture_output=True, text=True)
    assert proc.returncode != 0
    assert "NoSuchFMU" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    blocked = tmp_path / "file"
    blocked.write_text("")
    proc = subprocess.run([sys.executable, str(ROOT / "build.py"), "--dist", str(blocked / "sub")],
                          capture_output=True, text=True)
    assert proc.returncode != 0 and "build failed" in proc.stderr


def test_scripts_are_unique_and_shared_packages_identical(dist):
    modules, packages = {}, {}
    for name in built(dist):
        with zipfile.ZipFile(dist / f"{name}.fmu") as z:
            modules[name] = z.read("resources/slavemodule.txt").decode().strip()
            for info in z.infolist():
                parts = Path(info.filename).parts
                if len(parts) > 2 and parts[0] == "resources" and info.filename.endswith(".py"):
                    packages.setdefault(info.filename, set()).add(z.read(info.filename))
    assert len(set(modules.values())) == len(modules)
    # each FMU bundles its sources under a package name private to it and its build
    private = {name: build_script.private_name(name, build_script.project_version()) for name in modules}
    assert modules == {name: f"{private[name]}_{name}" for name in modules}
    assert len(set(private.values())) == len(private)
    assert all(len(versions) == 1 for versions in packages.values())
    assert {Path(f).parts[1] for f in packages} == {*private.values(), "pythonfmu"}
    assert all(f"resources/{p}/suspension_fmi/contract.py" in packages for p in private.values())


def test_all_fmus_in_one_process_and_two_instances_stay_independent(dist):
    a = Driven(dist / "ISORoad.fmu", {"road_class": 2, "seed": 1}, name="a")
    b = Driven(dist / "ISORoad.fmu", {"road_class": 6, "seed": 1}, name="b")
    p = Driven(dist / "QuarterCar.fmu", {}, name="p")
    try:
        ya = a.run(0.001, 500, ["road_height"], vehicle_speed=10.0)
        yb = b.run(0.001, 500, ["road_height"], vehicle_speed=10.0)
        yp = p.run(0.001, 500, ["z_s"], road_height=0.01)
        assert np.allclose(yb, 16.0 * ya)  # same seed, Gd(n0) 256x larger: amplitude 16x
        assert yp[-1, 0] > 0.005
    finally:
        for d in (a, b, p):
            d.close()


def test_messages_reach_the_instance_that_logged_them(driven):
    good = driven("ISORoad", road_class=2)
    bad = driven("ISORoad", road_class=9)
    later = driven("QuarterCar", k_s=-1.0)
    assert good.messages == []
    assert any("road_class = 9" in m for _, m in bad.messages) and not any("k_s" in m for _, m in bad.messages)
    assert any("k_s = -1.0" in m for _, m in later.messages)
