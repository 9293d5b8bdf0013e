"""The shared runner of the studies of ``python -m suspension_estimation.harness paper`` (one module per study in
``harness.studies``; ``harness.sweep`` runs the same table-2 run on Dask).

A run is one independent co-simulation through the built FMUs, described by a ``RunSpec``. The
table-2 run (``run_estimators``: one road and one plant feeding one SuspensionEstimator instance
per ``Estimator``, so that the estimators compare on the very same signals) is the runner's own;
a study with another kind of run gives its function in ``Study.runs``. Seed index i drives the
road (``ISORoad.seed`` = i) and the sensor noise (``QuarterCar.noise_seed`` = 1000 + i). Runs go
to a pool of ``spawn`` worker processes (``run_all``), each building its own ``CoSimulation``; a
run that fails (an FMU refusing, or anything else) is reported with its reason and the study goes
on. The estimators' row after ``doStep(t, h)`` and the road's row of the same time stamp both
describe the instant t + h.

The FMUs bundle their own copies of ``plant`` and ``estimators`` under a package name private to
their build (build.py), so a worker may import the installed ones too: what runs in an FMU is
what ``--dist`` holds.

This module imports nothing of ``harness.studies`` nor ``harness.sweep``.
"""
from __future__ import annotations

import math
import multiprocessing
import os
import time
import traceback
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from ...plant.sensors import SensorErrors
from ..cosim import CoSimulation, SimulationError, System
from ..metrics import highpass, mass_error_pct, reference_profile, road_scores

ROOT = Path(__file__).resolve().parents[2]
DIST = ROOT / "dist"
OUT = ROOT / "results" / "paper"

# Numerical libraries in the workers: one thread each (the workers are the parallelism).
THREAD_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

CLASS_LETTERS = "ABCDEFGH"
SPEED = 11.1111  # m/s, 40 km/h
# Table 1 of the MME&KF paper (also the contract's defaults; spelled out so that the studies do not
# move if a default does; not read from ``plant``, see the module docstring): m_u kg, k_s N/m,
# k_t N/m, c_s N.s/m. The default vehicle of a run, of plant and estimators alike.
PAPER000_VEHICLE = (39.0, 20000.0, 183000.0, 2000.0)
VEHICLE_KEYS = ("m_u", "k_s", "k_t", "c_s")
NOMINAL_MASS = 410.0  # kg, what the estimators of a table-2 run assume by default
NOISE = {"acc_sprung_noise_std": 0.02, "acc_unsprung_noise_std": 0.2, "defl_noise_std": 1e-4}  # m/s2, m/s2, m
NOISE_SEED_OFFSET = 1000
# The sensor errors of a plant (plant/sensors.py), the QuarterCar and SuspensionEstimator parameters
# of these names (spelled out, as VEHICLE_KEYS): m, m/s2, m/s2, 1, 1, s, s, s. ``RunSpec.sensor_errors``
# holds their values in this order.
SENSOR_ERROR_KEYS = tuple(f.name for f in fields(SensorErrors))  # the plant's sensor-error parameters
TRACE_WINDOW = 3.0  # s of road kept for plots, from the end of the warm-up


@dataclass(frozen=True)
class Estimator:
    instance: str  # FMU instance name in the system
    label: str  # name in the tables
    parameters: dict  # SuspensionEstimator parameters beyond the common ones
    true_mass: bool = False  # m_s_nominal = the plant's true sprung mass


# The estimators of a table-2 run unless told otherwise (those of the MME&KF paper's Table 2).
ESTIMATORS = (
    Estimator("KF", "KF", {"road_estimator": 0, "mass_estimator": 0}),
    Estimator("MMEKF", "MME&KF", {"road_estimator": 1, "mass_estimator": 0}),
    Estimator("KF_true", "KF true mass", {"road_estimator": 0, "mass_estimator": 0}, true_mass=True),
    Estimator("joint", "joint road+mass", {"road_estimator": 0, "mass_estimator": 1, "mass_feedback": True}),
)
LABELS = {e.instance: e.label for e in ESTIMATORS}
TABLE2_KINDS = ("table2", "table2_10ms")  # RunSpec.study of the runs ``run_estimators`` does


# --------------------------------------------------------------------------------------------------
# one run (in a worker process)
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunSpec:
    """One independent co-simulation. ``study`` is the kind of run: "table2" (1 ms or --step),
    "table2_10ms", or that of a study's own run function (e.g. "mass", "class"); ``mass`` is the
    true sprung mass (kg)."""

    study: str
    road_class: int
    seed: int
    duration: float
    warmup: float
    step: float
    dist: str
    mass: float = NOMINAL_MASS
    acc_sampling: int = 0
    traces: bool = False
    vehicle: tuple[float, float, float, float] = PAPER000_VEHICLE  # m_u, k_s, k_t, c_s of plant and estimators
    speed: float = SPEED  # m/s
    noise: tuple[float, float, float] = tuple(NOISE.values())  # m/s2, m/s2, m: plant's sensors, estimators' model
    nominal_mass: float = NOMINAL_MASS  # kg, what the estimators of a table-2 run assume (unless true_mass)
    # the plant's suspension laws (QuarterCar spring_model, damper_model): (0, 0) the linear k_s and
    # c_s of ``vehicle``; 1 = the air spring / the asymmetric damper with the contract's defaults
    plant_models: tuple[int, int] = (0, 0)
    # the plant's sensor errors, values of SENSOR_ERROR_KEYS in that order; () = none (the contract's
    # defaults: no offset, bias or delay, unit gains). Only the plant gets them: what an estimator is
    # told is its own parameters' business.
    sensor_errors: tuple[float, ...] = ()
    # the estimators step every ``log_every`` steps, on the plant's outputs then (a logger sampling
    # at 1 / (log_every step) beside a plant stepped at ``step``: CoSimulation ``rates``); the
    # plant's ``road_input`` (0 held over the step, 1 moving linearly)
    log_every: int = 1
    road_input: int = 0

    @property
    def name(self) -> str:
        c = CLASS_LETTERS[self.road_class - 1] if 1 <= self.road_class <= 8 else str(self.road_class)
        if self.study == "mass":
            return f"mass ISO {c} seed {self.seed}"
        if self.study == "class":
            return f"class ISO {c} {self.speed:g} m/s seed {self.seed}"
        if self.study == "vb_loose":
            return f"vb loosening mount ISO {c} seed {self.seed}"
        return (f"{self.study} ISO {c} {self.mass:g} kg seed {self.seed}"
                + (f" acc_sampling {self.acc_sampling}" if self.study == "table2_10ms" else "")
                + (f" plant models {self.plant_models[0]},{self.plant_models[1]}"
                   if tuple(self.plant_models) != (0, 0) else "")
                + (f" {3.6 * self.speed:.0f} km/h {1e3 * self.step:g} ms acc_sampling {self.acc_sampling}"
                   if self.study == "sensors" else "")
                + (f" logged every {self.log_every} steps" if self.log_every != 1 else "")
                + (" road linear over the step" if self.road_input else "")
                + (f" sensor errors {tuple(self.sensor_errors)}" if self.sensor_errors else ""))


def build_system(dist: Path, estimators: Sequence[str]) -> System:
    """Road -> plant -> several SuspensionEstimator instances (FMU instance names ``estimators``),
    all fed by the same plant outputs, the FMUs taken from ``dist``."""
    comps = {"ISORoad": dist / "ISORoad.fmu", "QuarterCar": dist / "QuarterCar.fmu"}
    conns = [("vehicle_speed", "ISORoad.vehicle_speed"), ("ISORoad.road_height", "QuarterCar.road_height")]
    for name in estimators:
        comps[name] = dist / "SuspensionEstimator.fmu"
        conns.append(("vehicle_speed", f"{name}.vehicle_speed"))
        conns += [(f"QuarterCar.{v}", f"{name}.{v}") for v in ("acc_sprung", "acc_unsprung", "susp_deflection")]
    return System(components=comps, connections=conns, name="paper")


def vehicle_params(spec: RunSpec) -> dict:
    """m_u, k_s, k_t, c_s of the run by name."""
    return dict(zip(VEHICLE_KEYS, map(float, spec.vehicle)))


def noise_params(spec: RunSpec) -> dict:
    """The sensor noise standard deviations of the run by parameter name."""
    return dict(zip(NOISE, map(float, spec.noise)))


def plant_params(spec: RunSpec) -> dict:
    """Parameters of the road and plant instances of ``system``."""
    p = {"ISORoad.road_class": spec.road_class, "ISORoad.seed": spec.seed,
         "QuarterCar.noise_seed": NOISE_SEED_OFFSET + spec.seed, "QuarterCar.acc_sampling": spec.acc_sampling,
         "QuarterCar.road_input": spec.road_input}
    p.update({f"QuarterCar.{k}": v for k, v in {**vehicle_params(spec), **noise_params(spec)}.items()})
    p["QuarterCar.spring_model"], p["QuarterCar.damper_model"] = map(int, spec.plant_models)
    if spec.sensor_errors:
        if len(spec.sensor_errors) != len(SENSOR_ERROR_KEYS):
            raise ValueError(f"sensor_errors {tuple(spec.sensor_errors)}: {len(SENSOR_ERROR_KEYS)} values, "
                             f"those of {', '.join(SENSOR_ERROR_KEYS)}")
        p.update({f"QuarterCar.{k}": float(v) for k, v in zip(SENSOR_ERROR_KEYS, spec.sensor_errors)})
    return p


class Simulations:
    """CoSimulations kept for reuse across runs, one per system and record (at most ``size``): a
    run of an already seen system resets its instances (``CoSimulation.reset``) instead of
    extracting and instantiating the FMUs again. Each process keeps its own (a sweep worker keeps
    one for its lifetime). ``instrument``: time every instance's calls (``timing`` of a run gets
    ``do_step_us``, ``set_get_us``, ``master_us``), at the cost of a wrapper around each call."""

    def __init__(self, size: int = 2, instrument: bool = True):
        self.size, self.instrument = size, instrument
        self._sims: dict[tuple, CoSimulation] = {}

    @staticmethod
    def _key(system: System, record: Sequence[str], rates: dict | None) -> tuple:
        return (tuple((k, str(v)) for k, v in system.components.items()), tuple(system.connections),
                tuple(system.order), tuple(record), tuple(sorted((rates or {}).items())))

    def get(self, system: System, parameters: dict, inputs: dict, record: list[str],
            rates: dict | None = None) -> CoSimulation:
        """A CoSimulation of ``system`` ready to run with these parameters, inputs and rates."""
        key = self._key(system, record, rates)
        sim = self._sims.pop(key, None)
        if sim is not None:
            sim.reset(parameters, inputs)
        else:
            while len(self._sims) >= max(1, self.size):
                self._sims.pop(next(iter(self._sims))).close()
            sim = CoSimulation(system, parameters=parameters, inputs=inputs, record=record, rates=rates)
        self._sims[key] = sim  # most recently used last
        return sim

    def discard(self, sim: CoSimulation) -> None:
        """Close ``sim`` and forget it (after a failure its instances may be unusable)."""
        for key, s in list(self._sims.items()):
            if s is sim:
                del self._sims[key]
        sim.close()

    def close(self) -> None:
        for sim in self._sims.values():
            sim.close()
        self._sims = {}


def _instrument(sim: CoSimulation) -> tuple[dict[str, list[float]] | None, Callable[[], None]]:
    """Time every instance's doStep and its set/get calls (s, summed), by wrapping the callables
    the master uses. Returns the sums (None if the master's internals are not as expected) and a
    function that removes the wrappers again."""
    saved = [(inst, inst.do_step, inst.sets, inst.gets) for inst in sim.instances.values()]

    def undo() -> None:
        for inst, do_step, sets, gets in saved:
            inst.do_step, inst.sets, inst.gets = do_step, sets, gets

    try:
        acc: dict[str, list[float]] = {}
        for name, inst in sim.instances.items():
            a = acc[name] = [0.0, 0.0]  # doStep, set + get

            def timed(f: Callable, a=a, j: int = 0) -> Callable:
                def g(*args, **kw):
                    t0 = time.perf_counter()
                    try:
                        return f(*args, **kw)
                    finally:
                        a[j] += time.perf_counter() - t0
                return g

            inst.do_step = timed(inst.do_step, a, 0)
            inst.sets = [(timed(s, a, 1), vrs, idx) for s, vrs, idx in inst.sets]
            inst.gets = [(timed(g, a, 1), vrs, idx) for g, vrs, idx in inst.gets]
        return acc, undo
    except (AttributeError, TypeError, ValueError):
        undo()
        return None, undo


def simulate(system: System, parameters: dict, inputs: dict, record: list[str], spec: RunSpec,
             duration: float, sims: Simulations | None = None, rates: dict | None = None) -> tuple[np.ndarray, dict]:
    """Run and return the record and where the time went (µs per step). With ``sims`` the
    CoSimulation is taken from (and left in) that cache, else made and closed here. ``rates``:
    CoSimulation's."""
    sim = sims.get(system, parameters, inputs, record, rates) if sims is not None else \
        CoSimulation(system, parameters=parameters, inputs=inputs, record=record, rates=rates)
    try:
        acc, undo = _instrument(sim) if sims is None or sims.instrument else (None, lambda: None)
        try:
            t0 = time.perf_counter()
            result = sim.run(duration, spec.step)
            wall = time.perf_counter() - t0
        finally:
            undo()
    except BaseException:
        if sims is not None:
            sims.discard(sim)
        raise
    finally:
        if sims is None:
            sim.close()
    n = max(len(result) - 1, 1)
    timing = {"run_s": wall, "steps": n, "us_per_step": 1e6 * wall / n}
    if acc is not None:
        timing["do_step_us"] = {k: 1e6 * v[0] / n for k, v in acc.items()}
        timing["set_get_us"] = {k: 1e6 * v[1] / n for k, v in acc.items()}
        timing["master_us"] = 1e6 * (wall - sum(v[0] + v[1] for v in acc.values())) / n
    return result, timing


def run_estimators(spec: RunSpec, estimators: Sequence[Estimator] = ESTIMATORS,
                   sims: Simulations | None = None) -> dict:
    """One table-2 run: one road and one plant feeding an instance of every estimator; scores
    per estimator instance in ``["estimators"]`` (those of ``harness.metrics`` after the warm-up,
    plus the sprung-mass error at the end and on average, the first and the share of right online
    ISO classes, and the number of non-zero status samples)."""
    dist = Path(spec.dist)
    names = [e.instance for e in estimators]
    params = plant_params(spec)
    for e in estimators:
        # every estimator is told how the sensor samples (acc_sampling), as a user would set it
        p = {**vehicle_params(spec), **noise_params(spec), "road_class": 0, "acc_sampling": spec.acc_sampling,
             "m_s_nominal": spec.mass if e.true_mass else spec.nominal_mass, **e.parameters}
        params.update({f"{e.instance}.{k}": v for k, v in p.items()})
    record = ["ISORoad.road_height", "ISORoad.distance"] + [f"{n}.{v}" for n in names for v in (
        "road_height_est", "road_height_std", "sprung_mass_est", "road_class_est", "status")]
    r, timing = simulate(build_system(dist, names), params,
                         {"vehicle_speed": spec.speed, "QuarterCar.sprung_mass": spec.mass},
                         record, spec, spec.duration, sims)
    t, truth = r["time"], r["ISORoad.road_height"]
    scored = t >= t[0] + spec.warmup
    out: dict = {"timing": timing, "estimators": {}}
    for n in names:
        est = r[f"{n}.road_height_est"]
        s = road_scores(t, est, truth, r[f"{n}.road_height_std"], warmup=spec.warmup, distance=r["ISORoad.distance"])
        m = r[f"{n}.sprung_mass_est"]
        s["mass_err_end_pct"] = float(mass_error_pct(m[-1], spec.mass))
        s["mass_err_mean_pct"] = float(np.mean(mass_error_pct(m[scored], spec.mass)))
        cls = r[f"{n}.road_class_est"]
        seen = np.nonzero(cls > 0)[0]
        s["class_first_s"] = float(t[seen[0]]) if len(seen) else math.inf
        s["class_right"] = float(np.mean(cls[seen[0]:] == spec.road_class)) if len(seen) else math.nan
        s["status_nonzero"] = int(np.count_nonzero(r[f"{n}.status"][1:]))
        out["estimators"][n] = s
    if spec.traces:
        w = (t >= t[0] + spec.warmup) & (t <= t[0] + spec.warmup + TRACE_WINDOW)
        ref = reference_profile(r["ISORoad.distance"], truth)
        tr = {"time": t[w], "truth": ref[w], "truth_hp": highpass(ref, spec.step)[w]}
        for n in names:
            est = r[f"{n}.road_height_est"]
            tr[n] = est[w]
            tr[f"{n}_hp"] = highpass(est, spec.step)[w]
        out["traces"] = tr
    return out


def run_one(spec: RunSpec, estimators: Sequence[Estimator] = ESTIMATORS, sims: Simulations | None = None,
            run: Callable[[RunSpec], dict] | None = None) -> dict:
    """Co-simulate one run; never raises: a failure is returned as ``ok = False`` with its reason
    (and, when an FMU refused, the name of its ``instance``). ``run`` is the study's function for
    this kind of run (``Study.runs``); without it the run is a table-2 run (``run_estimators``) of
    ``estimators``, with ``sims`` a cache of CoSimulations to reuse."""
    t0 = time.perf_counter()
    res: dict = {"spec": asdict(spec), "name": spec.name, "ok": False}
    try:
        if run is not None:
            res.update(run(spec))
        elif spec.study in TABLE2_KINDS:
            res.update(run_estimators(spec, estimators, sims))
        else:
            raise ValueError(f"no run function given for a run of kind {spec.study!r}")
        res["ok"] = True
    except SimulationError as e:
        res["error"] = str(e)
        res["instance"] = e.instance
    except Exception as e:  # noqa: BLE001 - one broken run must not end the study
        res["error"] = f"{type(e).__name__}: {e}"
        res["traceback"] = traceback.format_exc(limit=4)
    res["wall_s"] = time.perf_counter() - t0
    return res


# --------------------------------------------------------------------------------------------------
# the pool
# --------------------------------------------------------------------------------------------------
def _exit_with_parent(parent: int) -> None:
    """Pool-worker initializer: leave (os._exit) within a second once the parent process is gone.
    Without it a worker whose parent was killed finishes its run and then blocks for good on
    the result pipe nobody reads, holding its memory (seen: two workers left for 90 min)."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def process_pool(workers: int) -> ProcessPoolExecutor:
    """``workers`` spawned processes that end with this process, however it ends."""
    return ProcessPoolExecutor(max_workers=max(1, workers), mp_context=multiprocessing.get_context("spawn"),
                               initializer=_exit_with_parent, initargs=(os.getpid(),))


def run_all(specs: Sequence[RunSpec], workers: int = 2, progress: bool = True,
            log: Callable[[str], None] | None = None,
            runs: Mapping[str, Callable[[RunSpec], dict]] | None = None,
            done: Callable[[dict], None] | None = None) -> list[dict]:
    """Run the specs in ``workers`` spawned processes (results in the order of ``specs``); a spec
    whose kind (``RunSpec.study``) is in ``runs`` is run by that function (it must be a module's
    top-level function, to reach the workers), any other as a table-2 run. ``done(result)`` is
    called in this process as each run's result lands (a checkpoint). A worker that dies takes its
    pending runs with it: they are retried once in a fresh pool, then reported as failed."""
    from tqdm import tqdm

    os.environ.update(THREAD_ENV)  # inherited by the spawned workers before they import numpy
    results: dict[int, dict] = {}
    tries: dict[int, int] = defaultdict(int)
    pending = list(range(len(specs)))
    with tqdm(total=len(specs), unit="run", desc="paper", disable=not progress or None) as bar:
        say = log or bar.write
        while pending:
            broken: list[int] = []
            ex = process_pool(workers)
            try:
                futures = {ex.submit(run_one, specs[i], ESTIMATORS, None, (runs or {}).get(specs[i].study)): i
                           for i in pending}
                for f in as_completed(futures):
                    i = futures[f]
                    try:
                        results[i] = f.result()
                    except BrokenProcessPool:
                        broken.append(i)
                        continue
                    bar.update(1)
                    if done is not None:
                        done(results[i])
                    if not results[i]["ok"]:
                        say(f"failed: {specs[i].name}: {results[i]['error']}")
            finally:
                ex.shutdown(wait=True, cancel_futures=True)
            pending = []
            for i in broken:
                tries[i] += 1
                if tries[i] >= 2:
                    results[i] = {"spec": asdict(specs[i]), "name": specs[i].name, "ok": False, "wall_s": 0.0,
                                  "error": "its worker process died (twice)"}
                    bar.update(1)
                    if done is not None:
                        done(results[i])
                    say(f"failed: {specs[i].name}: {results[i]['error']}")
                else:
                    pending.append(i)
    return [results[i] for i in range(len(specs))]


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------
def mean_std(v: np.ndarray, fmt: str = ".2f") -> str:
    v = np.asarray(v, float)
    if len(v) == 0:
        return "failed"
    if not np.all(np.isfinite(v)):
        fin = v[np.isfinite(v)]
        bad = len(v) - len(fin)
        return (f"{np.mean(fin):{fmt}} ± {np.std(fin, ddof=1) if len(fin) > 1 else 0.0:{fmt}} "
                f"({bad} non-finite)") if len(fin) else f"{v[0]:g}"
    return f"{np.mean(v):{fmt}} ± {np.std(v, ddof=1) if len(v) > 1 else 0.0:{fmt}}"


def worst(v: np.ndarray, fmt: str = ".2f", signed: bool = False) -> str:
    v = np.asarray(v, float)
    if len(v) == 0:
        return "–"
    x = v[np.argmax(np.abs(v))] if signed else np.max(v)
    return f"{x:{fmt}}"


def save_figure(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    for ax in fig.axes:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize="small")
    fig.axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def jsonable(x):
    """JSON-safe copy: numpy to Python, non-finite floats to the strings "inf", "-inf", "nan"."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [jsonable(v) for v in x.tolist()]
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if math.isfinite(x) else ("nan" if math.isnan(x) else ("inf" if x > 0 else "-inf"))
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, Path):
        return str(x)
    return x


def parse_classes(text: str) -> tuple[int, ...]:
    """"B,C,D" -> (2, 3, 4)."""
    out = []
    for part in text.split(","):
        p = part.strip().upper()
        if len(p) != 1 or p not in CLASS_LETTERS:
            raise ValueError(f"--classes: {part.strip()!r} is not an ISO 8608 class A..H")
        out.append(CLASS_LETTERS.index(p) + 1)
    return tuple(dict.fromkeys(out))


def parse_speeds(text: str) -> tuple[float, ...]:
    """"40,80" (km/h) -> (40.0, 80.0)."""
    out = []
    for part in text.split(","):
        try:
            v = float(part)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"--speeds: {part.strip()!r} is not a speed in km/h > 0")
        out.append(v)
    return tuple(dict.fromkeys(out))


def verdict(ok: bool | None) -> str:
    """PASS / MISS, or n/a when there is nothing to judge (``None``)."""
    return "n/a" if ok is None else "PASS" if ok else "MISS"


def whole_steps(duration: float, step: float) -> bool:
    """Whether ``duration`` is a whole number of ``step`` (both s)."""
    return abs(round(duration / step) * step - duration) <= 1e-9 * duration


# --------------------------------------------------------------------------------------------------
# a study
# --------------------------------------------------------------------------------------------------
class Study:
    """One study of ``python -m suspension_estimation.harness paper``: a module of ``harness.studies`` holds it and the
    registry ``harness.studies.STUDIES`` names it. Every method gets the ``PaperStudy`` that runs
    it (``suite``: the command's options ``seeds``, ``duration``, ``warmup``, ``step``,
    ``classes``, ``class_seeds``, ``dist``, and after the runs ``results`` with ``ok``, ``cell``
    and ``failures``) and by default adds nothing."""

    name = ""  # as in --study
    # RunSpec.study -> the top-level function that co-simulates one such spec and returns its
    # results (run by ``run_one``); kinds not here are table-2 runs (``run_estimators``)
    runs: Mapping[str, Callable[[RunSpec], dict]] = {}
    # options of ``paper`` (PaperStudy fields: seeds, duration, classes, speeds) this study runs with
    # when it is the only study chosen on the command line and the option is not given: a small
    # grid where the common defaults would take hours
    defaults: Mapping[str, object] = {}

    def check(self, suite) -> None:
        """Raise ``ValueError`` (one line naming the option) for options the study cannot run with."""

    def specs(self, suite) -> list[RunSpec]:
        """The study's runs."""
        return []

    def markdown(self, suite) -> list[str]:
        """Its section of paper_tables.md (from its ``## `` heading on)."""
        return []

    def targets(self, suite) -> list[tuple[str, str, str]]:
        """(target, PASS / MISS / n/a, the numbers) of each target it checks."""
        return []

    def plots(self, suite, out: Path) -> list[Path]:
        """Figures written to ``out``."""
        return []

    def config(self, suite) -> dict:
        """Entries of the ``config`` of paper_runs.json."""
        return {}

    def json(self, suite) -> dict:
        """Top-level entries of paper_runs.json (e.g. the paper's own numbers)."""
        return {}
