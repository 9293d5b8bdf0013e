"""Sweeps: grid or Monte Carlo studies of the estimators through the FMUs, on Dask distributed.

``python -m suspension_estimation.harness sweep <file>`` runs every point of a sweep (ISO class x speed x true sprung
mass x seed, from a grid and/or seeded Monte Carlo draws) with every estimator configuration of
the file, and streams one row of metrics per run of an estimator to Parquet. Each point is one
co-simulation, the table-2 run of ``harness.studies.runner``: one road and one plant feeding one
SuspensionEstimator instance per configuration, so the estimators are compared on the very same
signals and the road and plant are paid once (the numbers are those of ``python -m suspension_estimation.harness
paper``: it is the same function).

Sweep files are TOML, looked up by name in ``harness/sweeps/`` (``small_grid`` ->
``small_grid.toml``) or given as a path. Keys (units in brackets; only ``[estimators]`` is
required):

    description = "..."
    duration = 60.0            # [s] per run
    step = 0.001               # [s] communication step
    warmup = 10.0              # [s] at the start that is not scored
    output = "results/sweeps/NAME"  # folder of Parquet part files, relative to the current
                               # directory (default results/sweeps/<file name>)
    nominal_mass = 410.0       # [kg] the estimators' m_s_nominal, unless they set their own
    acc_sampling = 0           # the plant's accelerations: 0 sampled at the end of the step,
                               # 1 averaged over it; the estimators are told the same

    [vehicle]                  # plant and estimators (default: the MME&KF paper's Table 1)
    m_u = 39.0                 # [kg]; also k_s [N/m], k_t [N/m], c_s [N.s/m]

    [noise]                    # plant's sensor noise, also what the estimators assume
    acc_sprung_std = 0.02      # [m/s2]; also acc_unsprung_std [m/s2] (0.2), defl_std [m] (1e-4)

    [grid]                     # axes: every combination is run (a scalar is a one-value axis)
    road_class = ["B", "C"]    # ISO 8608 "A".."H" or 1..8             default "C"
    speed = [11.1111]          # [m/s]                                  default 11.1111 (40 km/h)
    mass = [410.0, 590.0]      # [kg] true sprung mass                  default 410
    seed = [1, 2, 3]           # road seed; the sensor noise uses 1000 + seed; default 1

    [monte_carlo]              # seeded draws, crossed with the grid (the same draws at every point)
    runs = 20                  # number of draws
    seed = 1                   # seed of the draws (numpy default_rng)
    mass = {uniform = [230.0, 590.0]}  # an axis not in [grid]: {uniform = [lo, hi]},
    speed = {normal = [20.0, 2.0]}     # {normal = [mean, std]} or a list to choose from;
    road_class = ["B", "C", "D"]       # draw i (0-based) has seed i + 1 unless [grid] sets seed

    [estimators.KF]            # one estimator configuration per table, named by it (the FMU
    road_estimator = 0         # instance name and the ``estimator`` column): SuspensionEstimator
    mass_estimator = 0         # parameters by name; the vehicle, noise, acc_sampling, road_class = 0
    [estimators.KF_true]       # (online class) and m_s_nominal come from above unless set here
    m_s_nominal = "true"       # "true": the run's true sprung mass

Every row has a ``key``, a hash of everything its numbers depend on (the point, duration, step,
warm-up, vehicle, noise, nominal mass, acc_sampling, the estimator's name and parameters; not
the FMU folder: write to a new output after rebuilding the FMUs with other code). Re-running a
sweep skips every key already in the output with ``ok`` true; a failed run (an FMU refusing,
with its message naming the variable, or a worker that died) is recorded with ``ok`` false and
its ``error``, the sweep goes on, and a re-run tries it again (``skip_failed`` / ``--skip-failed``
to leave it). When one estimator instance refuses, it alone is marked failed and the point is run
again without it. ``read_results`` keeps the latest row of each key.

The output folder is a Parquet dataset of part files ``part-*.parquet``, each written whole
under a temporary name and then renamed, at least every ``FLUSH_S`` seconds and at the end (also
on Ctrl-C): an interrupted sweep leaves only complete files, and its finished runs count as done.
Columns: ``key``, ``run`` (hash of the point; the rows of one co-simulation share it),
``estimator``, ``parameters`` (JSON), ``ok``, ``error``, ``road_class``, ``speed`` [m/s], ``mass``
[kg], ``seed``, ``draw`` (Monte Carlo index or -1), ``duration``, ``step``, ``warmup`` [s],
``nominal_mass`` [kg], ``acc_sampling``, ``wall_s`` [s] and ``us_per_step`` [µs] of the
co-simulation, ``worker`` (process id), ``worker_run`` (runs done by that process so far),
``worker_rss_mb`` [MiB, after the run], then the metrics of the table-2 run
(``err_std_raw_pct``, ``err_std_hp_pct``, ``gain_hp``, ``rmse_raw_mm``, ``rmse_hp_mm``,
``coverage_2sigma``, ``mass_err_end_pct``, ``mass_err_mean_pct``, ``class_first_s``,
``class_right``, ``status_nonzero``; see ``harness.metrics``).

Execution follows FMPy's parameter-variation example: each worker process extracts the FMUs
once (into its Dask worker directory, which Dask removes) and keeps one CoSimulation
(``harness.studies.runner.Simulations``), resetting it (``fmi2Reset``) between runs, with a garbage
collection after each run so that its memory stays flat. The workers are separate processes with one thread each (all FMUs of a process
share one Python interpreter), by default a Dask ``LocalCluster``; ``scheduler`` uses an existing
cluster, whose workers must see the FMU folder and have the project installed. ``workers = 0``
runs in this process, without Dask.
"""
from __future__ import annotations

import gc
import hashlib
import importlib.util
import itertools
import json
import math
import os
import re
import tempfile
import threading
import time
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from .studies import runner
from .studies.runner import Estimator, RunSpec

SWEEPS = Path(__file__).resolve().parent / "sweeps"
FLUSH_S = 10.0  # s between Parquet part files at most (while runs complete)
FLUSH_ROWS = 2000

_TOP = {"description", "duration", "step", "warmup", "output", "nominal_mass", "acc_sampling", "vehicle",
        "noise", "grid", "monte_carlo", "estimators"}
AXES = ("road_class", "speed", "mass", "seed")
DEFAULTS = {"road_class": 3, "speed": runner.SPEED, "mass": runner.NOMINAL_MASS, "seed": 1}
_NOISE = {"acc_sprung_std": "acc_sprung_noise_std", "acc_unsprung_std": "acc_unsprung_noise_std",
          "defl_std": "defl_noise_std"}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
# column types that must not depend on the rows of one part file (e.g. an all-null error column)
_TYPES = {"key": "string", "run": "string", "estimator": "string", "parameters": "string", "ok": "bool",
          "error": "string", "road_class": "int64", "seed": "int64", "draw": "int64", "acc_sampling": "int64",
          "worker": "int64", "worker_run": "int64"}


class SweepError(ValueError):
    """A sweep file that cannot be used; the message is one line naming the file and key."""


def require_extra(*modules: str) -> None:
    """Raise ``SweepError`` naming the optional extra ``sweep`` when one of ``modules`` (Dask's
    ``distributed``, ``pyarrow``: what only the sweeps need) is not installed."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise SweepError(f"{' and '.join(missing)} {'is' if len(missing) == 1 else 'are'} not installed: the "
                         "sweeps need the optional extra 'sweep' (pip install -e \".[sweep]\")")


# --------------------------------------------------------------------------------------------------
# the sweep file
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Task:
    """One co-simulation: a point of the sweep and the estimators still to run there, with the
    row key of each."""

    spec: RunSpec
    estimators: tuple[Estimator, ...]
    keys: tuple[str, ...]
    run: str  # hash of the point
    draw: int = -1


@dataclass
class Sweep:
    """A loaded sweep file: its settings, its points and its estimator configurations."""

    name: str
    points: list[dict]  # {"road_class", "speed", "mass", "seed", "draw"}
    estimators: tuple[Estimator, ...]
    duration: float = 60.0
    step: float = 1e-3
    warmup: float = 10.0
    output: Path | None = None
    nominal_mass: float = runner.NOMINAL_MASS
    acc_sampling: int = 0
    vehicle: tuple[float, float, float, float] = runner.PAPER000_VEHICLE
    noise: tuple[float, float, float] = tuple(runner.NOISE.values())
    description: str = ""
    source: str = ""

    def tasks(self, dist: Path | str) -> list[Task]:
        """Every co-simulation of the sweep, with all its estimators."""
        d = str(Path(dist).resolve())
        out = []
        for p in self.points:
            spec = RunSpec("table2", p["road_class"], p["seed"], self.duration, self.warmup, self.step, d,
                           mass=p["mass"], acc_sampling=self.acc_sampling, vehicle=self.vehicle,
                           speed=p["speed"], noise=self.noise, nominal_mass=self.nominal_mass)
            out.append(Task(spec, self.estimators, tuple(run_key(spec, e) for e in self.estimators),
                            run_key(spec), p.get("draw", -1)))
        return out

    def check(self, dist: Path | str) -> None:
        """Raise ``SweepError`` / ``FileNotFoundError`` for what would fail every run: missing
        FMUs, a parameter the estimator FMU does not have."""
        from fmpy import read_model_description

        for f in ("ISORoad.fmu", "QuarterCar.fmu", "SuspensionEstimator.fmu"):
            if not (Path(dist) / f).is_file():
                raise FileNotFoundError(f"{Path(dist) / f} does not exist (build it: python build.py)")
        md = read_model_description(str(Path(dist) / "SuspensionEstimator.fmu"), validate=False)
        params = {v.name for v in md.modelVariables if v.causality == "parameter"}
        for e in self.estimators:
            for k in e.parameters:
                if k not in params:
                    raise SweepError(f"{self.source}: estimators.{e.instance}.{k}: SuspensionEstimator has no "
                                     f"parameter {k!r}")


def run_key(spec: RunSpec, estimator: Estimator | None = None) -> str:
    """A stable hash (16 hex digits) of everything the numbers of a run depend on (not the FMU
    folder, nor whether traces are kept); with ``estimator``, of that estimator's row."""
    d = {k: v for k, v in asdict(spec).items() if k not in ("dist", "traces")}
    if not d.get("sensor_errors"):  # none: the key of a run from before RunSpec had the field
        d.pop("sensor_errors", None)
    if estimator is not None:
        d["estimator"] = asdict(estimator)
    text = json.dumps(d, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def find_sweep(name: str | Path) -> Path:
    """A sweep file by path, or by name in ``harness/sweeps/``."""
    p = Path(name)
    if p.is_file():
        return p
    q = SWEEPS / f"{name}.toml"
    if q.is_file():
        return q
    known = ", ".join(sorted(f.stem for f in SWEEPS.glob("*.toml")))
    raise SweepError(f"no sweep {str(name)!r}: not a file, nor one of harness/sweeps/ ({known})")


def load_sweep(name: str | Path) -> Sweep:
    """Read and check a sweep file (see the module docstring for its keys)."""
    path = find_sweep(name)
    src = str(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise SweepError(f"{src}: {e}") from None
    _keys(src, "", data, _TOP)

    def num(key: str, default: float, table: dict = data, where: str = "") -> float:
        v = table.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise SweepError(f"{src}: {where}{key} = {v!r} must be a number")
        return float(v)

    duration, step, warmup = num("duration", 60.0), num("step", 1e-3), num("warmup", 10.0)
    if not (duration > 0 and step > 0):
        raise SweepError(f"{src}: duration and step must be > 0")
    if abs(round(duration / step) * step - duration) > 1e-9 * duration:
        raise SweepError(f"{src}: duration = {duration} s is not a whole number of step = {step} s")
    if not 0 <= warmup < duration:
        raise SweepError(f"{src}: warmup = {warmup} s must be in [0, duration = {duration} s)")
    acc = data.get("acc_sampling", 0)
    if acc not in (0, 1) or isinstance(acc, bool):
        raise SweepError(f"{src}: acc_sampling = {acc!r} must be 0 or 1")
    veh = _table(src, data, "vehicle", set(runner.VEHICLE_KEYS))
    vehicle = tuple(num(k, d, veh, "vehicle.") for k, d in zip(runner.VEHICLE_KEYS, runner.PAPER000_VEHICLE))
    noi = _table(src, data, "noise", set(_NOISE))
    noise = tuple(num(k, runner.NOISE[v], noi, "noise.") for k, v in _NOISE.items())
    out = data.get("output")
    if out is not None and not isinstance(out, str):
        raise SweepError(f"{src}: output = {out!r} must be a string (a folder)")
    return Sweep(name=path.stem, points=_points(src, data), estimators=_estimators(src, data), duration=duration,
                 step=step, warmup=warmup, output=Path(out) if out else None,
                 nominal_mass=num("nominal_mass", runner.NOMINAL_MASS), acc_sampling=int(acc), vehicle=vehicle,
                 noise=noise, description=str(data.get("description", "")), source=src)


def _keys(src: str, where: str, table: dict, allowed: set) -> None:
    for k in table:
        if k not in allowed:
            raise SweepError(f"{src}: unknown key {where}{k} (allowed: {', '.join(sorted(allowed))})")


def _table(src: str, data: dict, name: str, allowed: set | None = None) -> dict:
    t = data.get(name, {})
    if not isinstance(t, dict):
        raise SweepError(f"{src}: {name} must be a table")
    if allowed is not None:
        _keys(src, name + ".", t, allowed)
    return t


def _axis_value(src: str, where: str, axis: str, v):
    """One value of an axis, checked and converted (road class letters to 1..8)."""
    if axis == "road_class":
        if isinstance(v, str) and len(v) == 1 and v.upper() in runner.CLASS_LETTERS:
            return runner.CLASS_LETTERS.index(v.upper()) + 1
        if isinstance(v, int) and not isinstance(v, bool):
            return v  # out of range: the road FMU refuses it, and the run is recorded as failed
        raise SweepError(f"{src}: {where}road_class value {v!r} must be 'A'..'H' or an integer")
    if axis == "seed":
        if isinstance(v, int) and not isinstance(v, bool):
            return v
        raise SweepError(f"{src}: {where}seed value {v!r} must be an integer")
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise SweepError(f"{src}: {where}{axis} value {v!r} must be a number")
    return float(v)


def _points(src: str, data: dict) -> list[dict]:
    grid = _table(src, data, "grid", set(AXES))
    mc = _table(src, data, "monte_carlo", set(AXES) | {"runs", "seed"})
    axes = {a: [_axis_value(src, "grid.", a, v) for v in (grid[a] if isinstance(grid[a], list) else [grid[a]])]
            for a in AXES if a in grid}
    if any(not v for v in axes.values()):
        raise SweepError(f"{src}: an axis of [grid] is empty")
    for a in AXES:
        if a not in axes and (a not in mc or a == "seed"):
            axes[a] = [DEFAULTS[a]]
    draws: list[dict] = [{"draw": -1}]
    if mc:
        runs, seed = mc.get("runs"), mc.get("seed", 0)
        if not isinstance(runs, int) or isinstance(runs, bool) or runs < 1:
            raise SweepError(f"{src}: monte_carlo.runs = {runs!r} must be an integer >= 1")
        if not isinstance(seed, int) or isinstance(seed, bool):
            raise SweepError(f"{src}: monte_carlo.seed = {seed!r} must be an integer")
        drawn = [a for a in AXES if a in mc and a != "seed"]
        for a in drawn:
            if a in grid:
                raise SweepError(f"{src}: {a} is both a [grid] axis and a [monte_carlo] draw")
        rng = np.random.default_rng(seed)
        draws = []
        for i in range(runs):
            d: dict = {"draw": i}
            for a in drawn:
                d[a] = _draw(src, a, mc[a], rng)
            if "seed" not in grid:
                d["seed"] = i + 1
            draws.append(d)
    points = []
    for combo in itertools.product(*(axes[a] for a in AXES if a in axes)):
        base = dict(zip([a for a in AXES if a in axes], combo))
        for d in draws:
            points.append({**base, **d})
    return points


def _draw(src: str, axis: str, spec, rng: np.random.Generator):
    where = f"monte_carlo.{axis}"
    if isinstance(spec, list):
        if not spec:
            raise SweepError(f"{src}: {where} is an empty list")
        return _axis_value(src, "monte_carlo.", axis, spec[int(rng.integers(len(spec)))])
    if isinstance(spec, dict) and len(spec) == 1 and axis != "road_class":
        (kind, args), = spec.items()
        if kind in ("uniform", "normal") and isinstance(args, list) and len(args) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in args):
            return float(rng.uniform(*args) if kind == "uniform" else rng.normal(*args))
    raise SweepError(f"{src}: {where} = {spec!r} must be a list to choose from"
                     + ("" if axis == "road_class" else ", {uniform = [lo, hi]} or {normal = [mean, std]}"))


def _estimators(src: str, data: dict) -> tuple[Estimator, ...]:
    table = _table(src, data, "estimators")
    if not table:
        raise SweepError(f"{src}: no [estimators.NAME] table")
    out = []
    for name, params in table.items():
        if not _NAME.match(name) or name in ("ISORoad", "QuarterCar"):
            raise SweepError(f"{src}: estimators.{name}: the name must be an identifier other than ISORoad, QuarterCar")
        if not isinstance(params, dict):
            raise SweepError(f"{src}: estimators.{name} must be a table of parameters")
        params = dict(params)
        true_mass = params.get("m_s_nominal") == "true"
        if true_mass:
            del params["m_s_nominal"]
        for k, v in params.items():
            if not isinstance(v, (bool, int, float, str)):
                raise SweepError(f"{src}: estimators.{name}.{k} = {v!r} must be a number, boolean or string")
        out.append(Estimator(name, name, params, true_mass=true_mass))
    return tuple(out)


# --------------------------------------------------------------------------------------------------
# one run (in a worker process)
# --------------------------------------------------------------------------------------------------
_LOCAL = threading.local()  # per worker thread: its CoSimulations and the number of runs done
_KEPT: list[runner.Simulations] = []  # every thread's, so that close_worker (run in any thread) finds them


def _in_dask_worker_dir() -> None:
    """In a Dask worker, extract the FMUs into the worker's own directory, which Dask removes
    even when the worker is killed mid-run (else they would be left in the system's temp folder)."""
    try:
        from distributed import get_worker

        tempfile.tempdir = get_worker().local_directory
    except (ImportError, ValueError, AttributeError):
        pass  # not in a Dask worker


def _kept(name: str, instrument: bool) -> runner.Simulations:
    sims = getattr(_LOCAL, name, None)
    if sims is None or not any(s is sims for s in _KEPT):  # none yet, or closed by close_worker
        _in_dask_worker_dir()
        sims = runner.Simulations(instrument=instrument)
        setattr(_LOCAL, name, sims)
        _KEPT.append(sims)
    return sims


def close_worker() -> None:
    """Close this process's kept CoSimulations (every thread's), removing their extracted FMUs.
    Call it when no run is going on in the process."""
    while _KEPT:
        _KEPT.pop().close()
    _LOCAL.__dict__.clear()


def _run_spec(item: tuple[int, RunSpec, Callable | None]) -> tuple[int, dict]:
    """``runner.run_one`` in a worker, on the worker's kept CoSimulations (timed per instance)."""
    res = runner.run_one(item[1], sims=_kept("paper_sims", True), run=item[2])
    gc.collect()
    return item[0], res


def run_specs(specs: Sequence[RunSpec], workers: int = 2, scheduler: str | None = None,
              progress: bool = True, log: Callable[[str], None] | None = None,
              runs: Mapping[str, Callable[[RunSpec], dict]] | None = None,
              done: Callable[[dict], None] | None = None) -> list[dict]:
    """The studies' runs (``runner.run_one`` results, in the order of ``specs``; ``runs`` and
    ``done`` as for ``runner.run_all``) on Dask: a LocalCluster of ``workers`` processes or the cluster at
    ``scheduler``; each worker reuses its CoSimulations. What ``python -m suspension_estimation.harness paper --dask``
    runs."""
    require_extra("distributed")
    from distributed import Client
    from tqdm import tqdm

    results: list[dict | None] = [None] * len(specs)
    cluster = None if scheduler else local_cluster(max(1, min(workers, len(specs))))
    client = Client(scheduler or cluster)
    finished = False
    try:
        with tqdm(total=len(specs), unit="run", desc="paper", disable=not progress or None) as bar:
            say = log or bar.write

            def on_result(item, value) -> None:
                i, res = value
                results[i] = res
                if done is not None:
                    done(res)
                if not res["ok"]:
                    say(f"failed: {res['name']}: {res['error']}")
                bar.update(1)

            def on_error(item, message: str) -> tuple[int, dict]:
                i, spec, _ = item
                return i, {"spec": asdict(spec), "name": spec.name, "ok": False, "wall_s": 0.0, "error": message}

            execute([(i, s, (runs or {}).get(s.study)) for i, s in enumerate(specs)], _run_spec, on_result, client,
                    on_error)
        finished = True
    finally:
        if finished:
            try:
                client.run(close_worker)
            except Exception:  # noqa: BLE001 - workers gone: nothing left to close
                pass
        client.close()
        if cluster is not None:
            cluster.close()
    return results


def run_task(task: Task) -> list[dict]:
    """Co-simulate one point with its estimators and return one row per estimator; never raises.
    An estimator instance that refuses is recorded as failed and the point run again without it."""
    import psutil

    sims = _kept("sims", False)
    failed: dict[str, str] = {}
    todo = list(task.estimators)
    res: dict = {}
    while todo:
        res = runner.run_one(task.spec, tuple(todo), sims)
        if res["ok"] or len(todo) == 1 or res.get("instance") not in {e.instance for e in todo}:
            break
        failed[res["instance"]] = res["error"]
        todo = [e for e in todo if e.instance != res["instance"]]
    # What a run leaves in reference cycles (e.g. the slave objects an fmi2Reset replaces) is
    # freed now rather than when the collector's object-count thresholds next trigger: without
    # this the resident memory of a worker wanders upwards by megabytes per run.
    gc.collect()
    _LOCAL.runs = getattr(_LOCAL, "runs", 0) + 1
    timing = res.get("timing", {})
    extra = {"wall_s": res.get("wall_s", math.nan), "us_per_step": timing.get("us_per_step", math.nan),
             "worker": os.getpid(), "worker_run": _LOCAL.runs,
             "worker_rss_mb": psutil.Process().memory_info().rss / 2**20}
    rows = []
    for e, key in zip(task.estimators, task.keys):
        if e.instance in failed:
            row = _row(task, e, key, failed[e.instance])
        elif res.get("ok"):
            row = _row(task, e, key, None)
            row.update(res["estimators"][e.instance])
        else:
            row = _row(task, e, key, res.get("error", "not run"))
        row.update(extra)
        rows.append(row)
    return rows


def _row(task: Task, e: Estimator, key: str, error: str | None) -> dict:
    s = task.spec
    return {"key": key, "run": task.run, "estimator": e.instance,
            "parameters": json.dumps({**e.parameters, **({"m_s_nominal": "true"} if e.true_mass else {})},
                                     sort_keys=True),
            "ok": error is None, "error": error, "road_class": s.road_class, "speed": s.speed, "mass": s.mass,
            "seed": s.seed, "draw": task.draw, "duration": s.duration, "step": s.step, "warmup": s.warmup,
            "nominal_mass": s.nominal_mass, "acc_sampling": s.acc_sampling}


def failed_rows(task: Task, error: str) -> list[dict]:
    """Rows for a task whose worker never returned (e.g. the process died)."""
    rows = [_row(task, e, k, error) for e, k in zip(task.estimators, task.keys)]
    for r in rows:
        r.update({"wall_s": math.nan, "us_per_step": math.nan, "worker": -1, "worker_run": -1,
                  "worker_rss_mb": math.nan})
    return rows


# --------------------------------------------------------------------------------------------------
# Parquet output
# --------------------------------------------------------------------------------------------------
class PartWriter:
    """Rows to Parquet part files in ``folder``: buffered, and written (each file whole, under a
    temporary name, then renamed) when ``every_s`` seconds have passed since the last file or
    ``every_rows`` rows are waiting, and on ``flush()``/``close()``."""

    def __init__(self, folder: Path | str, every_s: float = FLUSH_S, every_rows: int = FLUSH_ROWS):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.every_s, self.every_rows = every_s, every_rows
        self.rows: list[dict] = []
        self.files: list[Path] = []
        self._last = time.monotonic()
        # names sort in the order written (read_results keeps the last row of a key)
        self._stamp = f"{time.strftime('%Y%m%dT%H%M%S')}{time.time_ns() % 10**9:09d}-{os.getpid()}"

    def add(self, rows: Sequence[dict]) -> None:
        self.rows.extend(rows)
        if len(self.rows) >= self.every_rows or time.monotonic() - self._last >= self.every_s:
            self.flush()

    def flush(self) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._last = time.monotonic()
        if not self.rows:
            return
        names = list(dict.fromkeys(k for r in self.rows for k in r))
        fields = []
        for n in names:
            if n in _TYPES:
                t = pa.type_for_alias(_TYPES[n])
            else:
                vals = [r.get(n) for r in self.rows if r.get(n) is not None]
                t = pa.float64() if any(isinstance(v, float) for v in vals) or not vals else \
                    pa.array(vals).type
            fields.append(pa.field(n, t))
        table = pa.Table.from_pylist([{n: r.get(n) for n in names} for r in self.rows], schema=pa.schema(fields))
        path = self.folder / f"part-{self._stamp}-{len(self.files):05d}.parquet"
        if path.exists():
            raise FileExistsError(f"{path} exists already")
        tmp = path.with_name(path.name + ".tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, path)
        self.files.append(path)
        self.rows = []

    def close(self) -> None:
        self.flush()


def _parts(folder: Path | str) -> list[Path]:
    return sorted(Path(folder).glob("part-*.parquet"))


def read_results(folder: Path | str, latest: bool = True):
    """All rows of a sweep's output folder as a ``pyarrow.Table`` (the part files' schemas
    unified). With ``latest``, only the last row written of each key (a failed run that
    succeeded on a re-run shows as succeeded)."""
    import pyarrow as pa
    import pyarrow.dataset as ds
    import pyarrow.parquet as pq

    files = _parts(folder)
    if not files:
        return pa.table({k: pa.array([], type=pa.type_for_alias(t)) for k, t in _TYPES.items()})
    schema = pa.unify_schemas([pq.read_schema(f) for f in files], promote_options="permissive")
    table = ds.dataset([str(f) for f in files], schema=schema, format="parquet").to_table()
    if latest and table.num_rows:
        keys = table.column("key").to_pylist()
        last = {k: i for i, k in enumerate(keys)}
        table = table.take(sorted(last.values()))
    return table


def done_keys(folder: Path | str, skip_failed: bool = False) -> set[str]:
    """Keys of the rows already in ``folder``: those that succeeded (and, with ``skip_failed``,
    those that failed)."""
    t = read_results(folder, latest=True)
    if not t.num_rows:
        return set()
    return {k for k, ok in zip(t.column("key").to_pylist(), t.column("ok").to_pylist()) if ok or skip_failed}


# --------------------------------------------------------------------------------------------------
# running
# --------------------------------------------------------------------------------------------------
@dataclass
class SweepReport:
    """What a call of ``run_sweep`` did: rows of the sweep, rows already done, co-simulations
    run and rows written now (failed among them), wall time (s), output folder and files."""

    rows: int
    done_before: int
    runs: int
    written: int
    failed: int
    wall_s: float
    output: Path
    files: list[Path] = field(default_factory=list)
    workers: int = 0
    failures: list[str] = field(default_factory=list)


def pending_tasks(sweep: Sweep, dist: Path | str, done: set[str]) -> list[Task]:
    """The sweep's co-simulations with only their estimators whose rows are not ``done``."""
    out = []
    for t in sweep.tasks(dist):
        keep = [(e, k) for e, k in zip(t.estimators, t.keys) if k not in done]
        if keep:
            out.append(replace(t, estimators=tuple(e for e, _ in keep), keys=tuple(k for _, k in keep)))
    return out


def local_cluster(workers: int):
    """A Dask LocalCluster of ``workers`` processes with one thread each (and one thread for
    the numerical libraries), without a dashboard (its HTTP server on a free port, so that
    several clusters can run side by side)."""
    from distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, env=dict(runner.THREAD_ENV),
                        dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"})  # any free port


def execute(tasks: Sequence, fn: Callable, on_result: Callable, client=None,
            on_error: Callable | None = None) -> None:
    """Run ``fn(task)`` for every task and call ``on_result(task, value)`` as each finishes, in
    this process (``client`` None) or on a Dask ``client``, keeping about two tasks per worker
    thread in flight. A task whose future fails (its worker died) gives
    ``on_result(task, on_error(task, message))``."""
    if client is None:
        for t in tasks:
            on_result(t, fn(t))
        return
    from distributed import as_completed

    width = 2 * max(1, sum(client.nthreads().values()))
    it = iter(tasks)
    owner = {}

    def submit(t):
        f = client.submit(fn, t, pure=False)
        owner[f.key] = t
        return f

    ac = as_completed([submit(t) for t in itertools.islice(it, width)])
    for f in ac:
        t = owner.pop(f.key)
        try:
            value = f.result()
        except Exception as e:  # noqa: BLE001 - e.g. KilledWorker: recorded, the sweep goes on
            if on_error is None:
                raise
            value = on_error(t, f"{type(e).__name__}: {e}")
        f.release()
        on_result(t, value)
        nxt = next(it, None)
        if nxt is not None:
            ac.add(submit(nxt))


def run_sweep(sweep: Sweep, dist: Path | str, out: Path | str | None = None, workers: int = 2,
              scheduler: str | None = None, skip_failed: bool = False, limit: int | None = None,
              progress: bool = True, log: Callable[[str], None] | None = None) -> SweepReport:
    """Run the runs of ``sweep`` not yet in ``out`` (default: the file's ``output``, else
    ``results/sweeps/<name>``) and append their rows there.

    ``workers`` Dask worker processes on a LocalCluster (0: in this process, without Dask), or
    the cluster at ``scheduler`` (an address such as ``tcp://host:8786``). ``limit`` runs at most
    that many co-simulations. ``log`` gets one line per failed row (default: printed above the
    progress bar)."""
    from tqdm import tqdm

    require_extra("pyarrow", *(("distributed",) if workers > 0 or scheduler else ()))
    sweep.check(dist)
    out = Path(out or sweep.output or Path("results") / "sweeps" / sweep.name)
    if workers < 0:
        raise ValueError(f"workers = {workers} must be >= 0")
    t0 = time.perf_counter()
    done = done_keys(out, skip_failed)
    all_keys = [k for t in sweep.tasks(dist) for k in t.keys]
    tasks = pending_tasks(sweep, dist, done)
    if limit is not None:
        tasks = tasks[:max(0, limit)]
    report = SweepReport(rows=len(all_keys), done_before=sum(k in done for k in all_keys), runs=len(tasks),
                         written=0, failed=0, wall_s=0.0, output=out)
    writer = PartWriter(out)
    client = cluster = None
    finished = False
    with tqdm(total=len(tasks), unit="run", desc=sweep.name, disable=not progress or None) as bar:
        say = log or bar.write

        def on_result(task: Task, rows: list[dict]) -> None:
            writer.add(rows)
            report.written += len(rows)
            for r in rows:
                if not r["ok"]:
                    report.failed += 1
                    line = f"failed: {task.spec.name} {r['estimator']}: {r['error']}"
                    report.failures.append(line)
                    say(line)
            bar.update(1)

        try:
            if tasks and (workers > 0 or scheduler):
                from distributed import Client

                if scheduler:
                    client = Client(scheduler)
                else:
                    cluster = local_cluster(min(workers, len(tasks)))
                    client = Client(cluster)
                report.workers = len(client.nthreads())
            execute(tasks, run_task, on_result, client, failed_rows)
            finished = True
        finally:
            writer.close()
            if client is not None:
                if finished:  # (not while a run may still go on: interrupted, the workers are closed)
                    try:
                        client.run(close_worker)
                    except Exception:  # noqa: BLE001 - workers gone: nothing left to close
                        pass
                client.close()
            else:
                close_worker()
            if cluster is not None:
                cluster.close()
    report.files = writer.files
    report.wall_s = time.perf_counter() - t0
    return report


def summary(folder: Path | str, metric: str = "err_std_hp_pct") -> list[str]:
    """Markdown table of ``metric`` by class, speed, mass and estimator: mean ± std over the
    rows that succeeded, and how many did and failed."""
    import pyarrow.compute as pc

    t = read_results(folder)
    if not t.num_rows:
        return ["(no rows)"]
    by = ["road_class", "speed", "mass", "estimator"]
    ok = t.filter(pc.field("ok"))
    lines = [f"| ISO | speed m/s | mass kg | estimator | {metric} mean ± std | ok | failed |", "|---|---|---|---|---|---|---|"]
    groups: dict[tuple, list] = {}
    for row in t.select(by + ["ok"]).to_pylist():
        g = groups.setdefault(tuple(row[k] for k in by), [[], 0])
        g[1] += 0 if row["ok"] else 1
    if metric in ok.column_names:
        for row in ok.select(by + [metric]).to_pylist():
            groups[tuple(row[k] for k in by)][0].append(row[metric])
    for (c, u, m, e), (vals, bad) in sorted(groups.items(), key=lambda kv: tuple(str(x) for x in kv[0])):
        v = np.array([x for x in vals if x is not None], float)
        cell = "–" if not len(v) else f"{np.mean(v):.2f} ± {np.std(v, ddof=1) if len(v) > 1 else 0.0:.2f}"
        letter = runner.CLASS_LETTERS[c - 1] if 1 <= c <= 8 else str(c)
        lines.append(f"| {letter} | {u:g} | {m:g} | {e} | {cell} | {len(v)} | {bad} |")
    return lines
