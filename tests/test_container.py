"""SuspensionSystem.fmu (harness/container.py), the fmucontainer of road -> plant -> estimator that
build.py makes: its interface, `fmpy validate`, and its results against the harness, run by FMPy in
this process and by a native C host (tests/native_host.c) with the environment of tools/fmu-env."""
from __future__ import annotations

import dataclasses
import os
import shlex
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu

from conftest import ROOT
from fmu_driver import Driven
from suspension_estimation.harness.container import CONTAINER, INPUTS, build_container, wiring
from suspension_estimation.harness.runner import run_scenario
from suspension_estimation.harness.scenario import load_scenario
from suspension_estimation.harness.ssp import ROAD_PLANT_ESTIMATOR, SYSTEMS

H = 1e-3  # s
DURATION = 2.0  # s of the default scenario compared
TOL = 1e-9  # max abs difference allowed against the harness (it is 0.0 here)

ALT = """
description = "non-default parameters of every FMU"
duration = 0.5
step = 0.001
system = "road_plant_estimator"
[road]
road_class = "D"
seed = 7
[speed]
value = 20.0
[sprung_mass]
value = 500.0
[noise]
seed = 3
acc_sprung_std = 0.05
[plant]
k_s = 25000.0
[estimator]
road_estimator = 1
m_s_nominal = 450.0
forgetting_factor = 0.99
"""


def _container(dist: Path) -> Path:
    return dist / f"{CONTAINER}.fmu"


def _harness(scenario, dist: Path) -> np.ndarray:
    return run_scenario(scenario, dist=dist).result


@pytest.fixture(scope="module")
def default_run(dist):
    """The harness on the default scenario (ISO C, 40 km/h, 410 kg, 1 ms), cut to DURATION."""
    scenario = dataclasses.replace(load_scenario("default"), duration=DURATION)
    return scenario, _harness(scenario, dist)


def _compared(result: np.ndarray, md) -> list[str]:
    """The recorded variables the container exposes under the same name (all outputs)."""
    names = {v.name for v in md.modelVariables}
    return [n for n in result.dtype.names if n != "time" and n in names]


def _run_in_fmpy(dist: Path, scenario, steps: int, outputs: list[str]) -> np.ndarray:
    """The container driven by FMPy in this process like the harness drives its FMUs: the
    scenario's parameters and inputs set in initialization mode, inputs again before every step.
    Rows: after initialization, then after every step."""
    speed, mass = float(scenario.speed(0.0)), float(scenario.sprung_mass(0.0))
    d = Driven(_container(dist), {**scenario.parameters(True), "vehicle_speed": speed, "sprung_mass": mass})
    try:
        rows = [[d.get(n) for n in outputs]]
        for _ in range(steps):
            d.step(H, vehicle_speed=speed, sprung_mass=mass)
            rows.append([d.get(n) for n in outputs])
        assert not [m for s, m in d.messages if s >= 2 and m != "Solver configure...."]
        return np.array(rows, dtype=float)
    finally:
        # no fmi2FreeInstance: the container would unload the pythonfmu binaries, which corrupts
        # this process's heap (see harness.cosim._Instance.keep_library)
        d.fmu.terminate()
        d.log.close()


def _assert_equal(result: np.ndarray, got: np.ndarray, names: list[str]) -> None:
    assert got.shape == (len(result), len(names))
    for j, name in enumerate(names):
        diff = np.max(np.abs(got[:, j] - result[name].astype(float)))
        assert diff <= TOL, f"{name}: max |container - harness| = {diff:.3g}"
    for name in ("ISORoad.road_height", "QuarterCar.z_s", "SuspensionEstimator.road_height_est",
                 "SuspensionEstimator.sprung_mass_est"):
        assert np.ptp(result[name]) > 0, name  # something happened


def test_build_writes_the_wiring_and_the_container(dist):
    rows = (dist / f"{CONTAINER}.csv").read_text().splitlines()
    assert rows[0] == "rule;from_fmu;from_port;to_fmu;to_port"
    assert [tuple(r.split(";")) for r in rows[1:]] == wiring(dist)
    md = read_model_description(str(_container(dist)))
    got = {v.name: v for v in md.modelVariables}
    assert md.coSimulation.modelIdentifier == CONTAINER

    order, connections, _ = SYSTEMS[ROAD_PLANT_ESTIMATOR]
    want_inputs = {s for s, _ in connections if "." not in s} | set(INPUTS.values())
    assert {n for n, v in got.items() if v.causality == "input"} == want_inputs == {"vehicle_speed", "sprung_mass"}
    want_outputs, want_parameters = set(), {}
    for c in order:
        for v in read_model_description(str(dist / f"{c}.fmu")).modelVariables:
            if v.causality == "output":
                want_outputs.add(f"{c}.{v.name}")
            elif v.causality == "parameter":
                want_parameters[f"{c}.{v.name}"] = (v.type, v.start)
    assert {n for n, v in got.items() if v.causality == "output"} == want_outputs
    assert {n: (v.type, v.start) for n, v in got.items() if v.causality == "parameter"} == want_parameters
    with zipfile.ZipFile(_container(dist)) as z:
        txt = z.read("resources/container.txt").decode()
    flags = txt.splitlines()[2]
    assert flags == "0 0 1"  # <MT> <Profiling> <Sequential>: one thread, sequential
    assert txt.splitlines()[4] == "0.001"  # internal step, s


def test_container_passes_fmpy_validate(dist):
    assert validate_fmu(str(_container(dist))) == []


def test_container_in_fmpy_equals_the_harness(dist, default_run):
    scenario, result = default_run
    names = _compared(result, read_model_description(str(_container(dist))))
    assert len(names) >= 20
    got = _run_in_fmpy(dist, scenario, len(result) - 1, names)
    _assert_equal(result, got, names)


def test_container_applies_its_parameters(dist, tmp_path):
    (tmp_path / "alt.toml").write_text(ALT)
    scenario = load_scenario(tmp_path / "alt.toml")
    result = _harness(scenario, dist)
    names = _compared(result, read_model_description(str(_container(dist))))
    got = _run_in_fmpy(dist, scenario, len(result) - 1, names)
    _assert_equal(result, got, names)
    default = _harness(dataclasses.replace(load_scenario("default"), duration=scenario.duration), dist)
    assert not np.array_equal(result["QuarterCar.acc_sprung"], default["QuarterCar.acc_sprung"])


# -- a native host ----------------------------------------------------------------------------------
def _fmu_env() -> dict[str, str]:
    """What `eval "$(python tools/fmu-env)"` exports, for the interpreter running the tests."""
    out = subprocess.run([sys.executable, str(ROOT / "tools" / "fmu-env")], capture_output=True, text=True,
                         check=True).stdout
    env = {}
    for line in out.splitlines():
        key, _, value = line.removeprefix("export ").partition("=")
        env[key] = shlex.split(value)[0]
    return env


@pytest.fixture(scope="module")
def native_host(tmp_path_factory) -> Path:
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        if os.environ.get("CI"):
            pytest.fail("no C compiler (cc, gcc) for the native-host test")
        pytest.skip("no C compiler (cc, gcc)")
    exe = tmp_path_factory.mktemp("host") / "native_host"
    subprocess.run([cc, "-O1", "-o", str(exe), str(ROOT / "tests" / "native_host.c"), "-ldl"], check=True)
    return exe


def _run_native(host: Path, dist: Path, tmp_path: Path, env: dict[str, str], steps: int, inputs: dict[str, float],
                outputs: list[str], options: tuple[str, ...] = ("maps",)) -> subprocess.CompletedProcess:
    md = read_model_description(str(_container(dist)))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(_container(dist)), unzipdir=str(tmp_path / "container"))
    args = [str(host), unzipped, CONTAINER, md.guid, str(steps), repr(H)]
    args += [f"r:{vr[k]}={v!r}" for k, v in inputs.items()] + [f"o:{vr[n]}" for n in outputs] + list(options)
    return subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)


def _without_python_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH")}


def test_native_host_with_fmu_env_equals_the_harness(dist, default_run, native_host, tmp_path):
    """The container's C master loads the three pythonfmu FMUs in a process without Python:
    with the tools/fmu-env environment they run this interpreter's libpython and the packages of
    its site-packages, and give the harness's numbers."""
    scenario, result = default_run
    md = read_model_description(str(_container(dist)))
    names = [n for n in _compared(result, md) if next(v for v in md.modelVariables if v.name == n).type == "Real"]
    env = {**_without_python_env(), **_fmu_env()}
    proc = _run_native(native_host, dist, tmp_path, env, len(result) - 1,
                       {"vehicle_speed": float(scenario.speed(0.0)), "sprung_mass": float(scenario.sprung_mass(0.0))},
                       names)
    assert proc.returncode == 0, proc.stderr[-2000:]
    table = np.loadtxt(proc.stdout.splitlines(), delimiter=",", ndmin=2)
    assert np.allclose(table[:, 0], result["time"], rtol=0, atol=1e-12)
    _assert_equal(result, table[:, 1:], names)

    maps = [line.split(None, 1)[1] for line in proc.stderr.splitlines() if line.startswith("map: ")]
    fmu_env = _fmu_env()
    libpython = {m for m in maps if Path(m).name.startswith("libpython")}
    assert libpython == {fmu_env["LD_PRELOAD"]}
    numpy_libs = {m for m in maps if "/numpy/" in m}
    assert numpy_libs and all(m.startswith(tuple(fmu_env["PYTHONPATH"].split(":"))) for m in numpy_libs)


def test_native_host_without_libpython_cannot_load_the_fmus(dist, native_host, tmp_path):
    proc = _run_native(native_host, dist, tmp_path, _without_python_env(), 1, {}, ["ISORoad.road_height"])
    assert proc.returncode == 1
    assert "undefined symbol: _Py" in proc.stderr
    assert "fmi2Instantiate failed" in proc.stderr


@pytest.mark.parametrize("leave", ["exit", "dlclose"])
def test_native_host_that_exits_normally_keeps_its_output_and_status(dist, native_host, tmp_path, leave):
    """A host that returns from main (after unloading the library, with "dlclose") runs its exit
    handlers, where pythonfmu 0.7.0's wrapper corrupts the heap (PythonFMU #229). With tools/fmu-env
    (SUSPENSION_FMU_QUICK_EXIT=1) the process ends with the host's status and every line it printed."""
    env = {**_without_python_env(), **_fmu_env()}
    assert env["SUSPENSION_FMU_QUICK_EXIT"] == "1" and env["OPENBLAS_NUM_THREADS"] == "1"
    steps = 20
    proc = _run_native(native_host, dist, tmp_path, env, steps, {"vehicle_speed": 11.1111},
                       ["QuarterCar.z_s"], (leave,))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert len(proc.stdout.splitlines()) == steps + 1 and proc.stdout.endswith("\n")
    # a host that fails after loading the FMUs leaves with its own status and message
    proc = _run_native(native_host, dist, tmp_path, env, steps, {"vehicle_speed": -5.0}, ["QuarterCar.z_s"], (leave,))
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "vehicle_speed = -5.0 is outside the allowed range [0, 100]" in proc.stderr
    assert "native_host: fmi2DoStep returned status" in proc.stderr


def test_python_host_that_exits_normally_keeps_its_status(dist):
    """The guard keeps a Python host's (FMPy's) exit status and output when it leaves with sys.exit
    instead of os._exit (such a host did not abort in these runs, with or without it)."""
    code = ("import sys; sys.path[:0] = [sys.argv[1], sys.argv[2]]\n"
            "from fmu_driver import Driven\n"
            "d = Driven(sys.argv[3] + '/SuspensionEstimator.fmu', {})\n"
            "d.step(1e-3, acc_sprung=0.1); print('stepped', d.get('sprung_mass_est')); d.close()\n"
            "sys.exit(3)\n")
    env = {**os.environ, "SUSPENSION_FMU_QUICK_EXIT": "1"}
    proc = subprocess.run([sys.executable, "-c", code, str(ROOT), str(ROOT / "tests"), str(dist)],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 3, proc.stderr[-2000:]
    assert proc.stdout.startswith("stepped ")


# -- build errors -----------------------------------------------------------------------------------
def test_a_wiring_that_does_not_fit_the_fmus_is_one_clear_error(dist, tmp_path):
    for c in SYSTEMS[ROAD_PLANT_ESTIMATOR][0]:
        shutil.copy(dist / f"{c}.fmu", tmp_path)
    with zipfile.ZipFile(dist / "QuarterCar.fmu") as src, zipfile.ZipFile(tmp_path / "QuarterCar.fmu", "w") as dst:
        for item in src.infolist():  # the plant's output acc_sprung renamed
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'name="acc_sprung"', b'name="acc_sprung_renamed"')
            dst.writestr(item, data)
    (tmp_path / f"{CONTAINER}.fmu").write_bytes(b"stale")
    with pytest.raises(RuntimeError, match=r"^fmucontainer: .*QuarterCar\.fmu/acc_sprung' does not exist"):
        build_container(tmp_path)
    assert not (tmp_path / f"{CONTAINER}.fmu").exists()


def test_the_half_car_loop_container_is_the_harness(dist):
    """HalfCarSystem.fmu, paper 002's closed loop (road -> HalfCar <- SuspensionController <-
    HalfCarEstimator) in one container, driven by FMPy at 1 ms, gives the harness's Gauss-Seidel
    run of HalfCarLoop.ssp to the last bit: the controller steps after the plant, so in both the
    plant gets each force a step after it was computed."""
    from suspension_estimation.harness.container import HALF_CAR_SYSTEM
    from suspension_estimation.harness.cosim import CoSimulation
    from suspension_estimation.harness.ssp import HALF_CAR_LOOP, read_ssp

    speed, mass, steps = 20.0, 672.0, 1000
    record = ["ISORoad.road_height", "HalfCar.heave_velocity", "HalfCar.acc_body_front_true",
              "HalfCarEstimator.heave_velocity_est", "HalfCarEstimator.sprung_mass_est",
              "SuspensionController.force_front", "SuspensionController.force_rear"]
    with CoSimulation(read_ssp(dist / f"{HALF_CAR_LOOP}.ssp", fmu_dir=dist), inputs={"vehicle_speed": speed},
                      record=record) as sim:
        result = sim.run(steps * H, H)
    d = Driven(dist / f"{HALF_CAR_SYSTEM.name}.fmu", {"vehicle_speed": speed, "sprung_mass": mass})
    try:
        rows = [[d.get(n) for n in record]]
        for _ in range(steps):
            d.step(H, vehicle_speed=speed, sprung_mass=mass)
            rows.append([d.get(n) for n in record])
        assert not [m for s, m in d.messages if s >= 2 and m != "Solver configure...."]
    finally:
        d.fmu.terminate()  # no fmi2FreeInstance (see _run_in_fmpy)
        d.log.close()
    got = np.array(rows, dtype=float)
    for j, name in enumerate(record):
        assert np.array_equal(got[:, j], result[name].astype(float)), name
    assert np.ptp(result["SuspensionController.force_front"]) > 100.0  # the loop is closed
