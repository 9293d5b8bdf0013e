"""The FMUs bundle the project's packages under a name private to each and its build (build.py): a
user's own modules named plant, estimators, harness or suspension_fmi, imported first, do not
shadow them, and FMUs of two builds with different version strings run side by side in one
process. Each case runs in a fresh interpreter, so that this process's imports do not interfere."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

from conftest import ROOT
from test_build import build_script

NAMES = ("plant", "estimators", "harness", "suspension_fmi")

# road -> plant -> one or more estimators, 2 s at 1 ms, in a fresh interpreter; writes the
# estimators' outputs, who owns the modules named like the project's, and the private packages
PROBE = r'''
import json, os, sys
spec = json.loads(sys.argv[1])
if spec["user"]:
    sys.path.insert(0, spec["user"])
    import estimators, harness, plant, suspension_fmi  # the user's own, imported before any FMU
from suspension_estimation.harness.cosim import CoSimulation, System
comps, wires = spec["components"], ("acc_sprung", "acc_unsprung", "susp_deflection")
estimators_ = [n for n in comps if n not in ("road", "plant")]
conn = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height")]
for e in estimators_:
    conn += [("vehicle_speed", f"{e}.vehicle_speed")] + [(f"plant.{w}", f"{e}.{w}") for w in wires]
outputs = ("road_height_est", "sprung_mass_est", "road_class_est", "status")
with CoSimulation(System(comps, conn), parameters={"road.road_class": 4, "road.seed": 3, "plant.noise_seed": 3},
                  inputs={"vehicle_speed": 15.0, "plant.sprung_mass": 520.0},
                  record=[f"{e}.{o}" for e in estimators_ for o in outputs]) as sim:
    res = sim.run(2.0, 1e-3)
    out = {"outputs": {e: {o: [float(x) for x in res[f"{e}.{o}"]] for o in outputs} for e in estimators_},
           "owners": {m: getattr(mod, "OWNER", "project") for m, mod in list(sys.modules.items())
                      if m.split(".")[0] in ("plant", "estimators", "harness", "suspension_fmi")},
           "private": {m: [mod.__version__, mod.__file__] for m, mod in list(sys.modules.items())
                       if m.startswith("_suspension_estimation_") and "." not in m and hasattr(mod, "__version__")}}
with open(spec["out"], "w") as f:
    json.dump(out, f)
sys.stdout.flush()
os._exit(0)  # not the pythonfmu exit handlers (PythonFMU issue 229)
'''


def probe(tmp_path: Path, components: dict[str, Path], user: Path | None = None) -> dict:
    out = tmp_path / f"probe-{len(list(tmp_path.glob('probe-*')))}.json"
    spec = {"user": str(user or ""), "components": {k: str(v) for k, v in components.items()}, "out": str(out)}
    proc = subprocess.run([sys.executable, "-c", PROBE, json.dumps(spec)], capture_output=True, text=True,
                          cwd=tmp_path, timeout=120)
    assert proc.returncode == 0 and out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads(out.read_text())


def private_of(fmu: Path) -> str:
    """The private package an FMU bundles, from the name of its script module."""
    with zipfile.ZipFile(fmu) as z:
        module = z.read("resources/slavemodule.txt").decode().strip()
    return module.removesuffix("_" + fmu.stem)


def own_modules(folder: Path) -> Path:
    """Packages named like the project's, with submodules named like its modules, that are not them."""
    for name, subs in {"plant": ("iso8608", "vehicle", "quarter_car"), "estimators": ("suspension", "model"),
                       "harness": ("cosim",), "suspension_fmi": ("slave", "contract")}.items():
        (folder / name).mkdir(parents=True)
        for sub in ("__init__", *subs):
            (folder / name / f"{sub}.py").write_text("OWNER = 'user'\n")
    return folder


def test_own_modules_named_like_the_project_do_not_shadow_the_fmus(dist, tmp_path):
    comps = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu", "e": dist / "SuspensionEstimator.fmu"}
    normal = probe(tmp_path, comps)
    shadowed = probe(tmp_path, comps, user=own_modules(tmp_path / "user"))
    assert shadowed["outputs"] == normal["outputs"]  # bit for bit
    est = normal["outputs"]["e"]
    assert len(est["road_height_est"]) == 2001 and set(est["status"]) == {0}
    assert abs(est["sprung_mass_est"][-1] - 520.0) < abs(est["sprung_mass_est"][0] - 520.0)  # it estimates
    # the user's modules stay the user's, and none of the FMUs' modules took one of their names
    assert set(shadowed["owners"]) >= set(NAMES) and set(shadowed["owners"].values()) == {"user"}
    assert normal["owners"] == {}
    version = build_script.project_version()
    loaded = ("ISORoad", "QuarterCar", "SuspensionEstimator")
    assert set(shadowed["private"]) == {build_script.private_name(n, version) for n in loaded}
    assert all("resources" in f and v == version for v, f in shadowed["private"].values())


def test_two_builds_of_different_versions_run_side_by_side(dist, tmp_path):
    builds = {}
    for version in ("1.0.0", "2.0.0rc1"):
        (tmp_path / version).mkdir()
        shutil.copy(dist / build_script.STAMPS, tmp_path / version)  # the classifier's model is current
        proc = subprocess.run([sys.executable, str(ROOT / "build.py"), "--dist", str(tmp_path / version),
                               "--version", version, "SuspensionEstimator"], capture_output=True, text=True,
                              cwd=tmp_path, timeout=120)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        builds[version] = tmp_path / version / "SuspensionEstimator.fmu"
    comps = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu", "e": dist / "SuspensionEstimator.fmu",
             "e1": builds["1.0.0"], "e2": builds["2.0.0rc1"]}
    r = probe(tmp_path, comps)
    out = r["outputs"]
    assert out["e1"] == out["e"] and out["e2"] == out["e"]  # same sources: the same estimates, bit for bit
    assert set(out["e"]["status"]) == {0}
    # the three estimators' private packages in one process, each of its build, from its own FMU
    names = {v: private_of(f) for v, f in builds.items()}
    names[build_script.project_version()] = private_of(dist / "SuspensionEstimator.fmu")
    assert len(set(names.values())) == 3
    assert {n: r["private"][n][0] for n in names.values()} == {n: v for v, n in names.items()}
    assert len({Path(r["private"][n][1]).parents[1] for n in names.values()}) == 3


def test_the_private_name_follows_version_and_sources(tmp_path, monkeypatch):
    name = build_script.private_name
    a = name("ISORoad", "1.0.0")
    assert re.fullmatch(r"_suspension_estimation_1_0_0_[0-9a-f]{8}", a) and a.isidentifier()
    assert name("ISORoad", "1.0.0+local.2") == a.replace("1_0_0", "1_0_0_local_2")
    assert len({name(n, "1.0.0") for n in build_script.FMUS}) == len(build_script.FMUS)
    src = tmp_path / "plant"
    src.mkdir()
    (src / "x.py").write_text("A = 1\n")
    monkeypatch.setitem(build_script.SOURCES, "plant", src)
    b = name("ISORoad", "1.0.0")
    (src / "x.py").write_text("A = 2\n")
    assert len({a, b, name("ISORoad", "1.0.0")}) == 3
    with pytest.raises(ValueError, match="version string is empty"):
        name("ISORoad", " ")


def test_the_fmu_scripts_get_the_private_name_and_nothing_else(tmp_path):
    script = tmp_path / "Good.py"
    script.write_text("from suspension_estimation.plant import iso8608\nimport numpy\n")
    packages = [build_script.SOURCES["plant"]]
    staged = build_script.stage(script, packages, "_p_1", "1", tmp_path)
    assert staged.name == "_p_1_Good.py"
    assert staged.read_text() == "from _p_1.plant import iso8608\nimport numpy\n"
    assert (tmp_path / "_p_1" / "plant" / "iso8608.py").is_file()
    assert (tmp_path / "_p_1" / "__init__.py").read_text().endswith("__version__ = '1'\n")
    for text in ("import plant\nfrom suspension_estimation.plant import iso8608\n",
                 "from suspension_estimation.plant import iso8608\nfrom harness.cosim import System\n",
                 "import numpy\n"):
        script.write_text(text)
        with pytest.raises(ValueError, match="must import the project only as"):
            build_script.stage(script, packages, "_p_2", "1", tmp_path / "bad")


def test_a_code_first_used_after_the_first_instances_folder_is_gone(dist):
    """A host may delete the folder it unpacked an FMU into (FMPy's simulate_fmu does) while
    another instance of the same FMU, sharing its modules, goes on or starts: every estimator
    code must still load, also when the first instance never built one (its parameters were
    refused). In a fresh process, so that the first folder is really the first."""
    script = textwrap.dedent(f"""
        import shutil, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from fmu_driver import Driven
        fmu = {str(dist / "SuspensionEstimator.fmu")!r}
        first = Driven(fmu, {{"forgetting_factor": 0.5}})  # refused: no estimator is ever built
        first.close()
        shutil.rmtree(first.dir, ignore_errors=True)  # (close deletes it already)
        for params in ({{"road_estimator": 3, "mass_estimator": 0}}, {{"road_estimator": 4}},
                       {{"road_estimator": 0, "mass_estimator": 4}}, {{"road_estimator": 5, "mass_estimator": 3}}):
            e = Driven(fmu, params)
            e.step(1e-3, acc_sprung=0.01, acc_unsprung=0.1, susp_deflection=1e-4, vehicle_speed=10.0)
            assert not any(s >= 3 for s, _ in e.messages), (params, e.messages)
            e.close()
        print("ok", flush=True)
        import os
        os._exit(0)  # no exit handlers: PythonFMU issue 229 (docs/native-hosts.md)
        """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert out.stdout.strip().endswith("ok"), out.stdout + out.stderr
