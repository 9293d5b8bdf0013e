"""Per-step cost of the cores, of the FMUs through FMPy and of the closed loop in the harness.

    .venv/bin/python benchmarks/run.py [--repeat N] [--steps N] [--loop-time S] [--loop-repeat N]
                                       [--json PATH] [--dist DIR] [--profile] [--vb-iterations N]

Everything runs at a 1 ms step on the default scenario's data (ISO 8608 class C, 40 km/h, 410 kg,
seed 1). Every figure is the median over ``--repeat`` timed passes, each after an untimed warm-up
pass, with the garbage collector off while a pass is timed (as ``timeit`` does); a pass starts
from a fresh object, so it includes the start-up transient of ``--steps`` samples.

- cores (plain Python, no FMI): the road-profile filter alone (KF; MME&KF: road_class = 3,
  no mass estimator), the default estimator (KF + RLS mass with feedback + online class), the
  VB-AKF (road_estimator 4 with ``--vb-iterations``, otherwise the defaults: RLS mass, response
  classifier; its step against the default's is a ratio of the table), the IMM
  (road_estimator 0 with mass_estimator 2, paper 002's fixed bank, and 4, the moving bank), the
  RLS mass estimator alone (``MassEstimator.update``), the road generator (``SyntheticRoad.eval``)
  and the plant (``QuarterCar.step``). The estimators are fed the measurements of a plain-Python
  road + plant simulation: random input would make most samples outliers and time the wrong path.
- FMU rounds through ``fmpy.fmi2.FMU2Slave``: setReal(all Real inputs) + doStep + getReal(all
  Real outputs) [+ getInteger(all Integer outputs)], for dist/ISORoad.fmu, dist/QuarterCar.fmu,
  dist/SuspensionEstimator.fmu (default parameters, road_estimator 4, and mass_estimator 2 and 4,
  whose step is reported relative to the default's, target <= 5; the same measurements as
  input), a trivial
  pythonfmu FMU (one Real input u, one Real output y = u) built here into a temporary folder as
  the yardstick of the FMI plumbing, and a shape yardstick built beside it: the estimator's own
  inputs and outputs (names from the contract) with the same cached accessors and no core, the
  floor of an estimator round inside pythonfmu.
- the closed loop road -> plant -> estimator in ``harness.cosim.CoSimulation`` (the default
  scenario, recording what ``python -m suspension_estimation.harness run default`` records): µs per step and the
  real-time factor (simulated time / wall time).

It prints a markdown table with the speed ratios (estimator FMU round / trivial FMU round,
target <= 2.5, <= 2 with a compiled kernel; real-time factor of the closed loop, target >= 15,
>= 20 with a kernel), marked as measured, never
asserted, and writes JSON (default benchmarks/results.json). ``--profile`` adds a cProfile of
the default estimator's step and of the closed loop.

BLAS/OpenMP threads are pinned to 1 before numpy loads (small matrices: threads only add
overhead and noise). The script ends with ``os._exit`` so that pythonfmu's exit handlers do not
run (the pythonfmu binary can abort the process at exit, PythonFMU issue 229).
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy is imported, here or in the FMUs (same interpreter)

import argparse  # noqa: E402
import cProfile  # noqa: E402
import gc  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import pstats  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

H = 1e-3  # s, the communication step of every measurement
SPEED = 40 / 3.6  # m/s (the default scenario's 11.1111 m/s)
MASS = 410.0  # kg
ROAD_CLASS = 3  # ISO C
SEED = 1
VB_ITERATIONS = [6]  # vb_iterations of the VB-AKF rows (--vb-iterations)

TRIVIAL_FMU = '''\
"""Trivial FMU for benchmarks/run.py: y = u (the yardstick of the FMI plumbing)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class BenchIdentityYardstick(Fmi2Slave):
    author = "benchmarks/run.py"
    description = "y = u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous, start=0.0))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        self.y = self.u
        return True
'''

# the estimator's interface (4 Real inputs, 13 Real + 2 Integer outputs) with the project's cached
# accessors and no core: the floor of a SuspensionEstimator.fmu round inside pythonfmu
SHAPE_FMU = '''\
"""Shape yardstick for benchmarks/run.py: the estimator's inputs and outputs, no core."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

INPUTS = %r
REALS = %r
INTEGERS = %r


class BenchShapeYardstick(Fmi2Slave):
    author = "benchmarks/run.py"
    description = "the estimator's variables; road_height_est = acc_sprung, the rest constant"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._names = {"Real": {}, "Integer": {}}
        for kind, names, causality, variability in (
                (Real, INPUTS, Fmi2Causality.input, Fmi2Variability.continuous),
                (Real, REALS, Fmi2Causality.output, Fmi2Variability.continuous),
                (Integer, INTEGERS, Fmi2Causality.output, Fmi2Variability.discrete)):
            for n in names:
                setattr(self, n, 0 if kind is Integer else 0.0)
                start = dict(start=0.0) if causality == Fmi2Causality.input else {}
                self.register_variable(kind(n, causality=causality, variability=variability, **start))
                self._names["Integer" if kind is Integer else "Real"][len(self.vars) - 1] = n
        self._out = dict.fromkeys(REALS, 0.0)
        self._out.update(dict.fromkeys(INTEGERS, 0))

    def get_real(self, vrs):
        names = self._names["Real"]
        return [float(getattr(self, names[vr])) for vr in vrs]

    def get_integer(self, vrs):
        names = self._names["Integer"]
        return [int(getattr(self, names[vr])) for vr in vrs]

    def set_real(self, vrs, values):
        names = self._names["Real"]
        for vr, value in zip(vrs, values):
            setattr(self, names[vr], value)

    def do_step(self, current_time, step_size):
        self._out["road_height_est"] = self.acc_sprung
        self.__dict__.update(self._out)
        return True
'''


# -- timing ---------------------------------------------------------------------------------------
def bench(make, run, steps: int, repeat: int, warmup: int = 1) -> dict:
    """µs per step: ``make()`` builds a fresh state (untimed), ``run(state)`` does ``steps`` steps
    (timed, gc off). Returns the median, min and every pass."""
    for _ in range(warmup):
        run(make())
    per_step = []
    for _ in range(repeat):
        state = make()
        gc.collect()
        gc.disable()
        try:
            t0 = time.perf_counter()
            run(state)
            dt = time.perf_counter() - t0
        finally:
            gc.enable()
        per_step.append(dt / steps * 1e6)
    return {"us_per_step": statistics.median(per_step), "min": min(per_step), "passes": per_step,
            "steps": steps}


# -- realistic data -------------------------------------------------------------------------------
def simulate(n: int) -> dict:
    """Road + plant in plain Python as the harness wires them: the road is evaluated at the
    distance after each step, the plant steps with it held; the plant starts settled on the road."""
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    road = SyntheticRoad(iso8608.class_psd_n0(ROAD_CLASS), seed=SEED)
    car = QuarterCar(DEFAULT_VEHICLE.with_(m_s=MASS), SensorNoise(), noise_seed=SEED)
    dist = SPEED * H * np.arange(1, n + 1)
    heights = np.empty(n)
    meas = np.empty((n, 3))
    car.settle(road.eval(0.0)[0])
    for k in range(n):
        heights[k] = road.eval(dist[k])[0]
        car.step(heights[k], H, MASS)
        meas[k] = car.measured
    return {"road": road, "h0": road.eval(0.0)[0], "dist": dist.tolist(), "heights": heights.tolist(),
            "meas": [tuple(r) for r in meas.tolist()]}


# -- cores ----------------------------------------------------------------------------------------
def estimator_configs() -> dict:
    from suspension_estimation.estimators import EstimatorConfig

    return {
        "KF": EstimatorConfig(road_estimator=0, mass_estimator=0, road_class=ROAD_CLASS),
        "MME&KF": EstimatorConfig(road_estimator=1, mass_estimator=0, road_class=ROAD_CLASS),
        "default estimator": EstimatorConfig(),
        "VB-AKF": EstimatorConfig(road_estimator=4, vb_iterations=VB_ITERATIONS[0]),
        # paper 003's codes told the default air spring and damper (on the linear plant's data: the
        # cost of a step does not depend on which plant made the measurements)
        "EKF (3)": EstimatorConfig(road_estimator=3, mass_estimator=0, road_class=ROAD_CLASS, **NONLINEAR_MAPS),
        "UKF (5)": EstimatorConfig(road_estimator=5, mass_estimator=0, road_class=ROAD_CLASS, **NONLINEAR_MAPS),
        "dual observer (3, 3)": EstimatorConfig(road_estimator=3, mass_estimator=3, road_class=ROAD_CLASS,
                                                **NONLINEAR_MAPS),
        "IMM": EstimatorConfig(road_estimator=0, mass_estimator=2),
        "moving IMM": EstimatorConfig(road_estimator=0, mass_estimator=4),
    }


NONLINEAR_MAPS = {"spring_model": 1, "damper_model": 1}


def bench_ukf_cores(meas: list, steps: int, repeat: int) -> dict:
    """The UKF of road_estimator 5 against filterpy's UnscentedKalmanFilter on the same model and
    data (tests/test_airspring_observers.py holds them equal to 1e-9)."""
    from suspension_estimation.estimators.airspring_observers import UKF, FilterpyUKF, NonlinearModel
    from suspension_estimation.estimators.model import measurement_covariance
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    model = NonlinearModel(DEFAULT_VEHICLE, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, SPEED, iso8608.class_psd_n0(ROAD_CLASS))
    R = measurement_covariance(0.02, 0.2, 1e-4)
    z = [np.array(m) for m in meas]

    def run(f):
        st = f.step
        for m in z:
            st(m)

    return {name: bench(lambda cls=cls: cls(model, H, R, DEFAULT_VEHICLE.m_s), run, steps, repeat)
            for name, cls in (("UKF core (own)", UKF), ("UKF core (filterpy)", FilterpyUKF))}


def run_estimator(est, meas) -> None:
    step = est.step
    for a, u, d in meas:
        step(a, u, d, SPEED, H)


def bench_cores(data: dict, steps: int, repeat: int) -> dict:
    from suspension_estimation.estimators import SuspensionEstimator
    from suspension_estimation.estimators.mass import MassEstimator
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.road import SyntheticRoad
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    meas, heights, dist = data["meas"][:steps], data["heights"][:steps], data["dist"][:steps]
    out = {}
    for name, cfg in estimator_configs().items():
        out[name] = bench(lambda cfg=cfg: SuspensionEstimator(cfg), lambda e: run_estimator(e, meas),
                          steps, repeat)

    v = DEFAULT_VEHICLE

    def run_mass(me):
        update = me.update
        for a, _, d in meas:
            update(a, d, H)

    out["RLS mass"] = bench(lambda: MassEstimator(v.m_s, v.k_s, v.c_s, 0.995), run_mass, steps, repeat)
    out.update(bench_ukf_cores(meas, min(steps, 5000), repeat))  # filterpy's: ~0.5 ms a step

    road = data["road"]

    def run_road(r):
        ev = r.eval
        for s in dist:
            ev(s)

    out["road generator"] = bench(lambda: SyntheticRoad(road.gd_n0, seed=SEED), run_road, steps, repeat)

    def make_car():
        car = QuarterCar(v.with_(m_s=MASS), SensorNoise(), noise_seed=SEED)
        car.settle(data["h0"])
        return car

    def run_car(car):
        st = car.step
        for r in heights:
            st(r, H, MASS)

    out["plant"] = bench(make_car, run_car, steps, repeat)
    return out


# -- FMUs through FMPy ----------------------------------------------------------------------------
class Slave:
    """One FMU2Slave instance with the value references of all its Real inputs and outputs.
    The pythonfmu binary is never unloaded (unloading it corrupts the heap, see harness.cosim)."""

    def __init__(self, fmu: Path, tmp: Path, parameters: dict | None = None, tag: str = ""):
        """``tag``: a suffix of the folder it is extracted to and of its instance name, for a second
        instance of the same FMU (extracting into the loaded one's folder overwrites its binary)."""
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        md = read_model_description(str(fmu), validate=False)
        self.name = md.coSimulation.modelIdentifier
        self.vars = {v.name: v for v in md.modelVariables}
        unzip = extract(str(fmu), unzipdir=str(tmp / f"{fmu.stem}{tag}"))
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=self.name,
                             instanceName=f"bench_{self.name}{tag}")
        self.parameters = dict(parameters or {})
        self.real_outputs = [v.valueReference for v in md.modelVariables
                             if v.causality == "output" and v.type == "Real"]
        self.int_outputs = [v.valueReference for v in md.modelVariables
                            if v.causality == "output" and v.type == "Integer"]
        self.fmu.instantiate(loggingOn=False)
        self.fresh = True

    def vr(self, *names: str) -> list[int]:
        return [self.vars[n].valueReference for n in names]

    def start(self, inputs: dict | None = None) -> "Slave":
        """(Re)initialize: reset (fmi2Reset re-runs the slave's __init__), parameters, inputs."""
        f = self.fmu
        if not self.fresh:
            f.reset()
        self.fresh = False
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        for name, value in {**self.parameters, **(inputs or {})}.items():
            v = self.vars[name]
            (f.setReal if v.type == "Real" else f.setInteger)([v.valueReference], [value])
        f.exitInitializationMode()
        return self

    def close(self) -> None:
        try:
            self.fmu.terminate()
            self.fmu.freeInstance()
        except Exception:  # noqa: BLE001 - nothing to do at the end of a benchmark
            pass


def build_yardstick(tmp: Path, model: str, source: str) -> Path:
    """Build the pythonfmu FMU of class ``model`` from ``source`` into ``tmp``."""
    from pythonfmu.builder import FmuBuilder

    src = tmp / f"{model}_src"
    src.mkdir()
    script = src / f"{model}.py"  # unique module names: FMUs share one module cache
    script.write_text(source)
    return Path(FmuBuilder.build_FMU(script, dest=tmp / f"{model}_dist"))


def build_trivial(tmp: Path) -> Path:
    return build_yardstick(tmp, "BenchIdentityYardstick", TRIVIAL_FMU)


def build_shape(tmp: Path) -> Path:
    """The shape yardstick (SHAPE_FMU) with the estimator's variable names from the contract."""
    from suspension_estimation.suspension_fmi.contract import SUSPENSION_ESTIMATOR

    def names(causality, kind):
        return tuple(v.name for v in SUSPENSION_ESTIMATOR if v.causality == causality and v.type == kind)

    return build_yardstick(tmp, "BenchShapeYardstick",
                           SHAPE_FMU % (names("input", "Real"), names("output", "Real"), names("output", "Integer")))


def round_loop(s: Slave, in_vrs: list[int], rows: list) -> None:
    """set all Real inputs, doStep, get all outputs, for each row of input values."""
    f = s.fmu
    set_real, do_step, get_real, get_int = f.setReal, f.doStep, f.getReal, f.getInteger
    outs, ints = s.real_outputs, s.int_outputs
    t = 0.0
    for row in rows:
        set_real(in_vrs, row)
        do_step(currentCommunicationPoint=t, communicationStepSize=H)
        get_real(outs)
        if ints:
            get_int(ints)
        t += H


def raw_round_loop(s: Slave, in_vrs: list[int], rows: list) -> None:
    """``round_loop`` calling FMPy's ctypes functions directly with preallocated arrays (no
    FMPy wrapper, no per-call array building): what a leaner master could reach."""
    from fmpy.fmi2 import fmi2Integer, fmi2Real, fmi2True, fmi2ValueReference

    fn = s.fmu._functions  # FMPy internals (0.3.x): name -> ctypes function
    set_real, do_step, get_real, get_int = (fn[k] for k in ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal",
                                                            "fmi2GetInteger"))
    c = s.fmu.component
    n_in, n_out, n_int = len(in_vrs), len(s.real_outputs), len(s.int_outputs)
    vr_in, val_in = (fmi2ValueReference * n_in)(*in_vrs), (fmi2Real * n_in)()
    vr_out, val_out = (fmi2ValueReference * n_out)(*s.real_outputs), (fmi2Real * n_out)()
    vr_int, val_int = (fmi2ValueReference * max(n_int, 1))(*s.int_outputs), (fmi2Integer * max(n_int, 1))()
    t = 0.0
    for row in rows:
        val_in[:] = row
        if set_real(c, vr_in, n_in, val_in) or do_step(c, t, H, fmi2True) or get_real(c, vr_out, n_out, val_out):
            raise RuntimeError(f"{s.name}: an FMI call failed at t = {t:g} s")
        list(val_out)
        if n_int:
            get_int(c, vr_int, n_int, val_int)
            list(val_int)
        t += H


VB_FMU = "SuspensionEstimator.fmu, road_estimator 4 (VB-AKF)"
SHAPE = "shape yardstick: the estimator's variables, no core"


def bench_fmus(data: dict, steps: int, repeat: int, tmp: Path, dist: Path) -> tuple[dict, dict]:
    out, info = {}, {}
    t0 = time.perf_counter()
    trivial = build_trivial(tmp)
    info["trivial_build_s"] = time.perf_counter() - t0
    meas, heights = data["meas"][:steps], data["heights"][:steps]

    cases = []
    s = Slave(trivial, tmp)
    cases.append(("trivial FMU (y = u)", s, s.vr("u"), [[x] for x in heights], {}))
    t0 = time.perf_counter()
    shape = build_shape(tmp)
    info["shape_build_s"] = time.perf_counter() - t0
    s = Slave(shape, tmp)
    cases.append((SHAPE, s, s.vr("acc_sprung", "acc_unsprung", "susp_deflection", "vehicle_speed"),
                  [[a, u, d, SPEED] for a, u, d in meas], {}))
    s = Slave(dist / "ISORoad.fmu", tmp, {"road_class": ROAD_CLASS, "seed": SEED})
    cases.append(("ISORoad.fmu", s, s.vr("vehicle_speed"), [[SPEED]] * steps, {"vehicle_speed": SPEED}))
    s = Slave(dist / "QuarterCar.fmu", tmp, {"noise_seed": SEED})
    cases.append(("QuarterCar.fmu", s, s.vr("road_height", "sprung_mass"), [[r, MASS] for r in heights],
                  {"road_height": data["h0"], "sprung_mass": MASS}))
    s = Slave(dist / "SuspensionEstimator.fmu", tmp)
    cases.append(("SuspensionEstimator.fmu", s, s.vr("acc_sprung", "acc_unsprung", "susp_deflection",
                                                     "vehicle_speed"),
                  [[a, u, d, SPEED] for a, u, d in meas], {"vehicle_speed": SPEED}))
    s = Slave(dist / "SuspensionEstimator.fmu", tmp, {"road_estimator": 4, "vb_iterations": VB_ITERATIONS[0]},
              tag="_vb")
    cases.append((VB_FMU, s, s.vr("acc_sprung", "acc_unsprung", "susp_deflection", "vehicle_speed"),
                  [[a, u, d, SPEED] for a, u, d in meas], {"vehicle_speed": SPEED}))
    for code, label in ((2, "SuspensionEstimator.fmu, IMM (mass_estimator 2)"),
                        (4, "SuspensionEstimator.fmu, moving IMM (mass_estimator 4)")):
        s = Slave(dist / "SuspensionEstimator.fmu", tmp, {"road_estimator": 0, "mass_estimator": code},
                  tag=f"_imm{code}")
        cases.append((label, s, s.vr("acc_sprung", "acc_unsprung", "susp_deflection", "vehicle_speed"),
                      [[a, u, d, SPEED] for a, u, d in meas], {"vehicle_speed": SPEED}))
    raw = hasattr(cases[0][1].fmu, "_functions")
    for name, s, in_vrs, rows, init in cases:
        sizes = dict(inputs=len(in_vrs), real_outputs=len(s.real_outputs), int_outputs=len(s.int_outputs))
        out[name] = bench(lambda s=s, init=init: s.start(init), lambda s, vrs=in_vrs, rows=rows:
                          round_loop(s, vrs, rows), steps, repeat)
        out[name].update(sizes)
        if raw and name in ("trivial FMU (y = u)", SHAPE, "SuspensionEstimator.fmu"):
            key = f"{name}, raw ctypes"
            out[key] = bench(lambda s=s, init=init: s.start(init), lambda s, vrs=in_vrs, rows=rows:
                             raw_round_loop(s, vrs, rows), steps, repeat)
            out[key].update(sizes, info=True)
        s.close()
    return out, info


# -- closed loop in the harness -------------------------------------------------------------------
def closed_loop_setup(dist: Path):
    from suspension_estimation.harness.cosim import System
    from suspension_estimation.harness.runner import RECORD
    from suspension_estimation.harness.scenario import load_scenario
    from suspension_estimation.harness.ssp import ROAD_PLANT_ESTIMATOR, SYSTEMS

    scenario = load_scenario("default")
    order, connections, _ = SYSTEMS[ROAD_PLANT_ESTIMATOR]
    system = System(components={c: dist / f"{c}.fmu" for c in order}, connections=list(connections),
                    order=list(order), name=ROAD_PLANT_ESTIMATOR)
    parameters = scenario.parameters(True)
    inputs = {"vehicle_speed": scenario.speed, "QuarterCar.sprung_mass": scenario.sprung_mass}
    record = [f"{i}.{v}" for i, names in RECORD.items() for v in names]
    return scenario, system, parameters, inputs, record


def bench_loop(dist: Path, seconds: float, repeat: int) -> dict:
    from suspension_estimation.harness.cosim import CoSimulation

    scenario, system, parameters, inputs, record = closed_loop_setup(dist)
    n = int(round(seconds / H))
    sims = []

    def make():
        sim = CoSimulation(system, parameters=parameters, inputs=inputs, record=record)
        sims.append(sim)
        return sim

    def run(sim):
        sim.run(seconds, H)

    try:
        r = bench(make, run, n, repeat)
    finally:
        for sim in sims:
            sim.close()
    r["simulated_s"] = seconds
    r["real_time_factor"] = 1e6 * H / r["us_per_step"]
    r["scenario"] = scenario.name
    r["recorded_variables"] = len(record)
    return r


# -- profiles -------------------------------------------------------------------------------------
def profile_text(fn, top: int = 18) -> str:
    pr = cProfile.Profile()
    pr.enable()
    fn()
    pr.disable()
    buf = io.StringIO()
    pstats.Stats(pr, stream=buf).strip_dirs().sort_stats("tottime").print_stats(top)
    lines = buf.getvalue().strip().splitlines()
    start = next((i for i, ln in enumerate(lines) if "ncalls" in ln), 0)
    head = [ln for ln in lines[:start] if "function calls" in ln]
    return "\n".join(head + lines[start:])


def profiles(data: dict, steps: int, dist: Path, tmp: Path) -> dict:
    from suspension_estimation.estimators import SuspensionEstimator
    from suspension_estimation.harness.cosim import CoSimulation

    meas = data["meas"][:steps]
    out = {}
    for name, cfg in estimator_configs().items():
        if name == "MME&KF":
            continue
        out[f"{name} core, {steps} steps"] = profile_text(lambda cfg=cfg: run_estimator(SuspensionEstimator(cfg), meas))
    s = Slave(dist / "SuspensionEstimator.fmu", tmp / "profile")
    s.start({"vehicle_speed": SPEED})
    rows = [[a, u, d, SPEED] for a, u, d in meas]
    in_vrs = s.vr("acc_sprung", "acc_unsprung", "susp_deflection", "vehicle_speed")
    out[f"SuspensionEstimator.fmu rounds through FMPy, {steps} steps"] = profile_text(
        lambda: round_loop(s, in_vrs, rows), top=25)
    s.close()
    _, system, parameters, inputs, record = closed_loop_setup(dist)
    seconds = 2.0
    with CoSimulation(system, parameters=parameters, inputs=inputs, record=record) as sim:
        out[f"closed loop in the harness, {seconds:g} s"] = profile_text(lambda: sim.run(seconds, H), top=25)
    return out


# -- report ---------------------------------------------------------------------------------------
def versions() -> dict:
    import fmpy
    import pythonfmu
    import scipy

    try:
        cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")),
                   platform.processor())
    except OSError:
        cpu = platform.processor()
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = None
    return {"cpu_count": os.cpu_count(), "cpus_usable": affinity, "cpu": cpu, "platform": platform.platform(),
            "python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__,
            "fmpy": fmpy.__version__, "pythonfmu": pythonfmu.__version__,
            "threads": {k: os.environ[k] for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}}


def stale_fmus(dist: Path) -> list[str]:
    """FMUs in dist/ older than a source file they bundle (then FMU and core numbers differ in code)."""
    bundles = {"ISORoad": ("plant", "fmu_src"), "QuarterCar": ("plant", "fmu_src"),
               "SuspensionEstimator": ("plant", "estimators", "fmu_src")}
    out = []
    for name, dirs in bundles.items():
        fmu = dist / f"{name}.fmu"
        if not fmu.is_file():
            continue
        newer = [p for d in dirs for p in (ROOT / d).rglob("*.py") if p.stat().st_mtime > fmu.stat().st_mtime]
        if newer:
            out.append(f"{fmu.name} is older than {', '.join(str(p.relative_to(ROOT)) for p in newer[:4])}"
                       f"{' ...' if len(newer) > 4 else ''}")
    return out


def fmt(x: float) -> str:
    return f"{x:.1f}" if x < 1000 else f"{x:.0f}"


def table(res: dict) -> str:
    cores, fmus, loop = res["cores"], res["fmus"], res["closed_loop"]
    rows = ["| what | µs per step (median) | min | passes × steps |", "| --- | ---: | ---: | ---: |"]

    def row(label, r):
        rows.append(f"| {label} | {fmt(r['us_per_step'])} | {fmt(r['min'])} | {len(r['passes'])} × {r['steps']} |")

    for k, label in (("KF", "core: KF (road_class 3, no mass)"), ("MME&KF", "core: MME&KF (road_class 3, no mass)"),
                     ("default estimator", "core: default estimator (KF + RLS mass + online class)"),
                     ("VB-AKF", f"core: VB-AKF, road_estimator 4, vb_iterations {VB_ITERATIONS[0]} "
                                "(+ RLS mass + response class)"),
                     ("IMM", "core: IMM (road_estimator 0, mass_estimator 2: 7 models)"),
                     ("moving IMM", "core: moving-bank IMM (road_estimator 0, mass_estimator 4: 5 models)"),
                     ("RLS mass", "core: RLS mass alone (MassEstimator.update)"),
                     ("EKF (3)", "core: EKF, road_estimator 3 (nonlinear maps, no mass)"),
                     ("UKF (5)", "core: UKF, road_estimator 5 (nonlinear maps, no mass)"),
                     ("dual observer (3, 3)", "core: dual observer, road_estimator 3 + mass_estimator 3"),
                     ("UKF core (own)", "core: UKF filter alone (airspring_observers.UKF)"),
                     ("UKF core (filterpy)", "core: filterpy's UnscentedKalmanFilter, same model and data"),
                     ("road generator", "core: road generator (SyntheticRoad.eval)"),
                     ("plant", "core: plant (QuarterCar.step)")):
        row(label, cores[k])
    for k, r in fmus.items():
        if r.get("info"):
            k = k.replace(", raw ctypes", "") + ", info: raw ctypes calls, preallocated arrays, no FMPy wrapper"
        ints = f" + {r['int_outputs']} Integer" if r["int_outputs"] else ""
        io_ = f"{r['inputs']} in, {r['real_outputs']} Real{ints} out"
        row(f"FMU round: {k} ({io_})", r)
    row(f"closed loop in the harness ({loop['scenario']}, {loop['simulated_s']:g} s, "
        f"{loop['recorded_variables']} recorded)", loop)
    lines = ["\n".join(rows), "", "Ratios (measured in this run, not asserted):", "",
             "| ratio | measured | target | met |", "| --- | ---: | ---: | --- |"]
    for r in res["ratios"].values():
        lines.append(f"| {r['what']} | {r['value']:.2f} | {r['target']} | {'—' if r['met'] is None else 'yes' if r['met'] else 'no'} |")
    lines += ["", "Where the closed loop's time goes (µs per step, medians of the runs above):", "",
              "| part | µs | share of the loop |", "| --- | ---: | ---: |"]
    for k, v in res["breakdown"].items():
        lines.append(f"| {k} | {fmt(v)} | {100 * v / loop['us_per_step']:.0f} % |")
    return "\n".join(lines)


def analyse(res: dict) -> None:
    cores, fmus, loop = res["cores"], res["fmus"], res["closed_loop"]
    triv = fmus["trivial FMU (y = u)"]["us_per_step"]
    est_fmu = fmus["SuspensionEstimator.fmu"]["us_per_step"]
    shape = fmus[SHAPE]["us_per_step"]
    rtf = loop["real_time_factor"]
    # targets: plain-Python step <= 2.5x and >= 15x; with a compiled kernel <= 2x and >= 20x
    res["ratios"] = {
        "estimator_fmu_over_trivial": {"what": "SuspensionEstimator.fmu round ÷ trivial FMU round",
                                       "value": est_fmu / triv, "target": "≤ 2.5 (kernel ≤ 2)",
                                       "met": est_fmu / triv <= 2.5},
        "shape_over_trivial": {"what": "shape yardstick round (the estimator's variables, no core) ÷ trivial "
                                       "FMU round: the floor of the ratio above", "value": shape / triv,
                               "target": "(info)", "met": None},
        "closed_loop_real_time_factor": {"what": "closed loop real-time factor (1 ms step ÷ wall time per step)",
                                         "value": rtf, "target": "≥ 15 (kernel ≥ 20)", "met": rtf >= 15},
        "vb_core_over_default_core": {"what": f"VB-AKF core step (vb_iterations {VB_ITERATIONS[0]}) ÷ default "
                                              "estimator core step", "value": cores["VB-AKF"]["us_per_step"]
                                      / cores["default estimator"]["us_per_step"], "target": "≤ 3",
                                      "met": cores["VB-AKF"]["us_per_step"] <= 3 * cores["default estimator"]["us_per_step"]},
        "vb_fmu_over_default_fmu": {"what": f"VB-AKF FMU round (vb_iterations {VB_ITERATIONS[0]}) ÷ default "
                                            "SuspensionEstimator.fmu round", "value": fmus[VB_FMU]["us_per_step"] / est_fmu,
                                    "target": "≤ 3", "met": fmus[VB_FMU]["us_per_step"] <= 3 * est_fmu},
        "default_core_over_trivial": {"what": "default estimator core step ÷ trivial FMU round",
                                      "value": cores["default estimator"]["us_per_step"] / triv,
                                      "target": "(info)", "met": None},
        "filterpy_ukf_over_own": {"what": "filterpy's UKF step ÷ the UKF of road_estimator 5 (same model, data)",
                                  "value": cores["UKF core (filterpy)"]["us_per_step"]
                                  / cores["UKF core (own)"]["us_per_step"], "target": "(info)", "met": None},
    }
    for k in ("EKF (3)", "UKF (5)", "dual observer (3, 3)"):
        res["ratios"][f"{k}_over_default"] = {
            "what": f"core {k} step ÷ default estimator core step",
            "value": cores[k]["us_per_step"] / cores["default estimator"]["us_per_step"], "target": "(info)",
            "met": None}
    for key, label in (("IMM", "IMM"), ("moving IMM", "moving-bank IMM")):
        fmu_key = next(k for k in fmus if k.startswith("SuspensionEstimator.fmu, ") and k.endswith(
            "(mass_estimator 2)" if key == "IMM" else "(mass_estimator 4)"))
        for what, a, b in (("core step", cores[key]["us_per_step"], cores["default estimator"]["us_per_step"]),
                           ("FMU round", fmus[fmu_key]["us_per_step"], est_fmu)):
            res["ratios"][f"{key.replace(' ', '_')}_{what.replace(' ', '_')}_over_default"] = {
                "what": f"{label} {what} ÷ default estimator {what}", "value": a / b, "target": "≤ 5",
                "met": a / b <= 5}
    core_sum = (cores["road generator"]["us_per_step"] + cores["plant"]["us_per_step"]
                + cores["default estimator"]["us_per_step"])
    rounds = sum(fmus[k]["us_per_step"] for k in ("ISORoad.fmu", "QuarterCar.fmu", "SuspensionEstimator.fmu"))
    L = loop["us_per_step"]
    res["breakdown"] = {
        "cores (road generator + plant + default estimator, plain Python)": core_sum,
        "FMI plumbing of 3 FMUs (3 × trivial round)": 3 * triv,
        "FMU adapters beyond the plumbing (3 FMU rounds − cores − 3 × trivial)": rounds - core_sum - 3 * triv,
        "  of which the estimator's variables themselves (shape yardstick − trivial)": shape - triv,
        "harness master (loop − 3 FMU rounds: recording, wiring, bookkeeping)": L - rounds,
    }
    # the entries above (but the indented one, a part of the one before) add up to the loop;
    # the ratio of the two 'overheads' is what to cut
    for r in res["ratios"].values():
        r["met"] = None if r["met"] is None else bool(r["met"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed passes per measurement (median; default 5)")
    ap.add_argument("--steps", type=int, default=20000,
                    help="1 ms steps per pass for the cores and FMU rounds (default 20000 = the loop's 20 s)")
    ap.add_argument("--loop-time", type=float, default=20.0,
                    help="simulated s per closed-loop pass (default 20, the default scenario)")
    ap.add_argument("--loop-repeat", type=int, default=None,
                    help="timed closed-loop passes (default min(--repeat, 3))")
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results.json", help="where to write JSON")
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="folder with the built FMUs")
    ap.add_argument("--profile", action="store_true", help="also print cProfile of the estimator and the loop")
    ap.add_argument("--vb-iterations", type=int, default=6,
                    help="vb_iterations of the VB-AKF rows (road_estimator 4; default 6, the paper's)")
    args = ap.parse_args(argv)
    if not 1 <= args.vb_iterations <= 50:
        ap.error("need 1 <= --vb-iterations <= 50")
    VB_ITERATIONS[0] = args.vb_iterations
    if args.repeat < 1 or args.steps < 10 or args.loop_time <= 0:
        ap.error("need --repeat >= 1, --steps >= 10, --loop-time > 0")
    loop_repeat = args.loop_repeat or min(args.repeat, 3)
    missing = [f for f in ("ISORoad", "QuarterCar", "SuspensionEstimator") if not (args.dist / f"{f}.fmu").is_file()]
    if missing:
        print(f"benchmarks/run.py: {', '.join(missing)} not in {args.dist}; run .venv/bin/python build.py",
              file=sys.stderr)
        return 1

    wall0 = time.perf_counter()
    res = {"machine": versions(), "load_average_start": os.getloadavg(),
           "settings": {"step_s": H, "speed_m_s": SPEED, "sprung_mass_kg": MASS, "road_class": ROAD_CLASS,
                        "seed": SEED, "repeat": args.repeat, "steps": args.steps, "warmup_passes": 1,
                        "loop_time_s": args.loop_time, "loop_repeat": loop_repeat, "gc_during_timing": "off",
                        "vb_iterations": args.vb_iterations},
           "stale_fmus": stale_fmus(args.dist)}
    m = res["machine"]
    print(f"# benchmarks/run.py — {time.strftime('%Y-%m-%d %H:%M:%S')}")
    print(f"machine: {m['cpu_count']} CPUs ({m['cpus_usable']} usable), {m['cpu']}; Python {m['python']}, "
          f"numpy {m['numpy']}, scipy {m['scipy']}, fmpy {m['fmpy']}, pythonfmu {m['pythonfmu']}")
    print("threads: OPENBLAS_NUM_THREADS=1, OMP_NUM_THREADS=1, MKL_NUM_THREADS=1 (set before numpy loads)")
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in res['load_average_start'])}")
    for s in res["stale_fmus"]:
        print(f"WARNING: {s}: FMU figures measure the built code, core figures the working tree "
              f"(rebuild with build.py)")
    print(f"settings: 1 ms step, ISO C, 40 km/h, 410 kg; median of {args.repeat} passes × {args.steps} steps "
          f"(closed loop: {loop_repeat} × {args.loop_time:g} s), 1 warm-up pass each, gc off while timing",
          flush=True)

    t = time.perf_counter()
    data = simulate(args.steps)
    res["settings"]["data_s"] = time.perf_counter() - t
    tmp = Path(tempfile.mkdtemp(prefix="bench-"))
    try:
        t = time.perf_counter()
        res["cores"] = bench_cores(data, args.steps, args.repeat)
        print(f"cores: {time.perf_counter() - t:.1f} s", flush=True)
        t = time.perf_counter()
        res["fmus"], info = bench_fmus(data, args.steps, args.repeat, tmp, args.dist)
        res["settings"].update(info)
        print(f"FMU rounds: {time.perf_counter() - t:.1f} s", flush=True)
        t = time.perf_counter()
        res["closed_loop"] = bench_loop(args.dist, args.loop_time, loop_repeat)
        print(f"closed loop: {time.perf_counter() - t:.1f} s", flush=True)
        analyse(res)
        if args.profile:
            res["profiles"] = profiles(data, min(args.steps, 5000), args.dist, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res["load_average_end"] = os.getloadavg()
    res["total_s"] = time.perf_counter() - wall0

    print()
    print(table(res))
    print()
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in res['load_average_end'])} "
          f"(on {m['cpu_count']} CPUs; above ~0.5 other jobs competed for the CPU: compare ratios, not absolutes)")
    for name, text in res.get("profiles", {}).items():
        print(f"\n## cProfile: {name} (sorted by own time)\n\n```\n{text}\n```")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(res, indent=2) + "\n")
    print(f"\nwrote {args.json} ({res['total_s']:.0f} s in all)")
    return 0


if __name__ == "__main__":
    try:
        status = main()
    except SystemExit as e:  # argparse: --help, usage errors
        status = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    except BaseException as e:  # noqa: BLE001 - report, then leave without the exit handlers
        import traceback

        traceback.print_exc()
        status = 130 if isinstance(e, KeyboardInterrupt) else 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
