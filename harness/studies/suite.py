"""``python -m suspension_estimation.harness paper``: run the chosen studies of ``harness.studies`` through the built
FMUs and write one report (paper_tables.md, paper_runs.json, figures).

The runs of all chosen studies go to one pool of ``spawn`` worker processes (``runner.run_all``;
with ``dask`` or ``scheduler``: to Dask workers through ``harness.sweep.run_specs``, each keeping
its CoSimulations and resetting them between runs). A run that fails is reported with its reason
and the study goes on. Means ± standard deviations (ddof 1) are over the seeds that completed.
The command reports, it never tunes: each study marks its targets PASS/MISS.

Each run's result is appended to ``<out>/runs.jsonl`` as it lands (first line: the SHA-256 of the
FMUs). With ``resume`` the completed runs found there are kept and only the others run, so a study
of many hours survives a stop; the FMUs must be the same files, else the resume is refused.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import STUDIES, load
from .runner import (CLASS_LETTERS, DIST, NOISE_SEED_OFFSET, OUT, RunSpec, Study, jsonable, run_all, whole_steps)

DEFAULT_STUDIES = ("table2", "mass")  # without --study; --study10ms and --class-study N add theirs
CHECKPOINT = "runs.jsonl"  # in ``out``: one JSON line per finished run
FMUS = ("ISORoad.fmu", "QuarterCar.fmu", "SuspensionEstimator.fmu", "HalfCar.fmu", "HalfCarEstimator.fmu",
        "SuspensionController.fmu")


def spec_key(spec: dict) -> str:
    """A run's identity in the checkpoint: its spec (``asdict(RunSpec)``) as canonical JSON, without
    the FMU folder (the FMUs themselves are checked by their digests)."""
    return json.dumps(jsonable({k: v for k, v in spec.items() if k != "dist"}), sort_keys=True)


def _plain(x):
    """json.dumps ``default``: numpy arrays and scalars as Python lists and numbers. Not
    ``jsonable``, which writes NaN as the string "nan": a resumed result must read back as the
    float the run returned."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


def fmu_digests(dist: Path) -> dict[str, str]:
    """SHA-256 of each FMU the studies run."""
    return {f: hashlib.sha256((Path(dist) / f).read_bytes()).hexdigest() for f in FMUS}


def read_checkpoint(path: Path, dist: Path) -> dict[str, dict]:
    """spec_key -> the completed runs (``ok``) in the checkpoint ``path``; the last line of a spec
    wins and a torn last line (the process killed mid-write) is skipped. Raises ValueError if the
    checkpoint was written with other FMUs than those in ``dist``."""
    lines = Path(path).read_text().splitlines()
    try:
        head = json.loads(lines[0]) if lines else {}
    except json.JSONDecodeError:
        head = {}
    if head.get("fmus") != fmu_digests(dist):
        raise ValueError(f"{path} was written with other FMUs than those in {dist}: run without --resume")
    kept: dict[str, dict] = {}
    for line in lines[1:]:
        try:
            r = json.loads(line)
        except json.JSONDecodeError:
            continue
        if r.get("ok"):
            if "traces" in r:
                r["traces"] = {k: np.asarray(v, float) for k, v in r["traces"].items()}
            kept[spec_key(r["spec"])] = r
    return kept


@dataclass
class PaperStudy:
    seeds: int = 10
    duration: float = 60.0
    warmup: float = 10.0
    step: float = 1e-3
    classes: tuple[int, ...] = (2, 3, 4)
    speeds: tuple[float, ...] = ()  # km/h of the studies that take them (sensors); () = each study's own
    workers: int = 2
    study10ms: bool = False  # also the "10ms" study
    class_seeds: int = 0  # seeds of the "class" study; 0 = not run unless named in ``studies`` (then ``seeds``)
    dask: bool = False  # run on Dask (harness.sweep.run_specs): a LocalCluster of ``workers`` or ``scheduler``
    scheduler: str | None = None
    dist: Path = DIST
    out: Path = OUT
    results: list[dict] = field(default_factory=list)
    wall_s: float = 0.0
    studies: tuple[str, ...] = ()  # names in harness.studies.STUDIES; () = DEFAULT_STUDIES
    resume: bool = False  # keep the completed runs of ``out``/runs.jsonl, run only the others
    ran: int = 0  # runs co-simulated by the last ``run``
    reused: int = 0  # runs the last ``run`` took from the checkpoint

    def __post_init__(self) -> None:
        if "class" in self.studies and not self.class_seeds:
            self.class_seeds = self.seeds

    @property
    def names(self) -> tuple[str, ...]:
        """The studies that run, in the order of the registry."""
        chosen = set(self.studies or DEFAULT_STUDIES)
        chosen |= {"10ms"} if self.study10ms else set()
        chosen |= {"class"} if self.class_seeds else set()
        return tuple(n for n in STUDIES if n in chosen)

    def chosen(self) -> list[Study]:
        return [load(n) for n in self.names]

    def check(self) -> None:
        for n in self.studies:
            load(n)  # ValueError naming the known studies
        if self.seeds < 1:
            raise ValueError(f"--seeds = {self.seeds} must be >= 1")
        if self.workers < 1:
            raise ValueError(f"--workers = {self.workers} must be >= 1")
        if not self.step > 0 or not self.duration > 0:
            raise ValueError("--step and --duration must be > 0")
        if not 0 <= self.warmup < self.duration:
            raise ValueError(f"--warmup = {self.warmup} s must be in [0, --duration = {self.duration} s)")
        if not whole_steps(self.duration, self.step):
            raise ValueError(f"--duration = {self.duration} s is not a whole number of --step = {self.step} s steps")
        if any(not (math.isfinite(u) and u > 0) for u in self.speeds):
            raise ValueError(f"speeds {self.speeds} must be km/h > 0")
        if not self.classes or any(not 1 <= c <= 8 for c in self.classes):
            raise ValueError(f"classes {self.classes} must be ISO classes A..H")
        for s in self.chosen():
            s.check(self)
        for f in FMUS:
            if not (Path(self.dist) / f).is_file():
                raise FileNotFoundError(f"{Path(self.dist) / f} does not exist (build it: .venv/bin/python build.py)")

    def specs(self) -> list[RunSpec]:
        return [spec for s in self.chosen() for spec in s.specs(self)]

    def runs(self) -> dict:
        """RunSpec.study -> the function that runs it, of every chosen study."""
        return {kind: fn for s in self.chosen() for kind, fn in s.runs.items()}

    def run(self, progress: bool = True) -> PaperStudy:
        self.check()
        t0 = time.perf_counter()
        specs = self.specs()
        path = Path(self.out) / CHECKPOINT
        kept = read_checkpoint(path, self.dist) if self.resume and path.is_file() else {}
        pending = [s for s in specs if spec_key(asdict(s)) not in kept]
        if self.dask or self.scheduler:
            from ..sweep import require_extra, run_specs

            require_extra("distributed")  # before anything is written
        path.parent.mkdir(parents=True, exist_ok=True)
        if not kept:
            path.write_text(json.dumps({"fmus": fmu_digests(self.dist)}) + "\n")
        with path.open("a") as f:
            def done(res: dict) -> None:
                f.write(json.dumps(res, default=_plain) + "\n")
                f.flush()

            if self.dask or self.scheduler:
                new = run_specs(pending, self.workers, self.scheduler, progress, runs=self.runs(), done=done)
            else:
                new = run_all(pending, self.workers, progress, runs=self.runs(), done=done) if pending else []
        kept.update((spec_key(r["spec"]), r) for r in new)
        self.results = []
        for s in specs:
            r = kept[spec_key(asdict(s))]
            r["spec"] = asdict(s)  # tuples again where JSON made lists, so ``ok(**match)`` finds it
            self.results.append(r)
        self.ran, self.reused = len(pending), len(specs) - len(pending)
        self.wall_s = time.perf_counter() - t0
        return self

    # -- what the studies read --------------------------------------------------------------------
    def ok(self, study: str, **match) -> list[dict]:
        """The completed runs of kind ``study`` whose spec has the values ``match``."""
        return [r for r in self.results if r["ok"] and r["spec"]["study"] == study
                and all(r["spec"][k] == v for k, v in match.items())]

    def cell(self, study: str, cls: int, mass: float, inst: str, metric: str, **match) -> np.ndarray:
        """Per-seed values of one metric of one estimator in one cell of table-2 runs."""
        return np.array([r["estimators"][inst][metric]
                         for r in self.ok(study, road_class=cls, mass=mass, **match)], float)

    def failures(self) -> list[dict]:
        return [r for r in self.results if not r["ok"]]

    def targets(self) -> list[tuple[str, str, str]]:
        """(target, PASS / MISS / n/a, the numbers) of every chosen study."""
        return [t for s in self.chosen() for t in s.targets(self)]

    # -- report -----------------------------------------------------------------------------------
    def timing_markdown(self) -> list[str]:
        lines = [f"Wall time of the study: {self.wall_s:.0f} s ({self.wall_s / 60:.1f} min) with {self.workers} "
                 f"worker process(es), {len(self.results)} runs.", "",
                 "| runs | count | wall per run (s) | µs per step | master overhead µs/step | doStep µs/step by instance | "
                 "set+get µs/step by instance |", "|---|---|---|---|---|---|---|"]
        # one row per study and step (the sensors study's logging runs are at 5 and 10 ms)
        for kind, h in dict.fromkeys((r["spec"]["study"], r["spec"]["step"]) for r in self.results):
            rs = [r for r in self.ok(kind) if r["spec"]["step"] == h]
            if not rs:
                continue
            wall = np.array([r["wall_s"] for r in rs])
            us = np.array([r["timing"]["us_per_step"] for r in rs])
            if all("do_step_us" in r["timing"] for r in rs):
                insts = list(rs[0]["timing"]["do_step_us"])
                ds = ", ".join(f"{i} {np.mean([r['timing']['do_step_us'][i] for r in rs]):.0f}" for i in insts)
                sg = ", ".join(f"{i} {np.mean([r['timing']['set_get_us'][i] for r in rs]):.0f}" for i in insts)
                master = f"{np.mean([r['timing']['master_us'] for r in rs]):.0f}"
            else:
                ds = sg = master = "–"
            lines.append(f"| {kind} ({1e3 * h:g} ms) | {len(rs)} | {wall.mean():.1f} | {us.mean():.0f} | {master} | "
                         f"{ds} | {sg} |")
        return lines

    def markdown(self) -> str:
        L = [f"# Paper tables through the FMUs ({self.dist})", "",
             f"Seeds 1..{self.seeds} (road seed i, noise seed {NOISE_SEED_OFFSET}+i); {self.duration:g} s runs at "
             f"{1e3 * self.step:g} ms, scored after a {self.warmup:g} s warm-up; mean ± std (ddof 1) over "
             "seeds. HP = estimate and truth through the same zero-phase 0.5 Hz high-pass first.", ""]
        sections = [m for m in (s.markdown(self) for s in self.chosen()) if m]
        for i, m in enumerate(sections):
            L += ([""] if i else []) + m
        L += ["", "## Targets (reported, never tuned)", "", "| target | result | numbers |", "|---|---|---|"]
        L += [f"| {t} | {v} | {d} |" for t, v, d in self.targets()]
        fails = self.failures()
        L += ["", "## Failed runs", ""]
        L += [f"- {r['name']}: {r['error']}" for r in fails] if fails else ["none"]
        L += ["", "## Where the time goes", ""]
        L += self.timing_markdown()
        return "\n".join(L) + "\n"

    def to_json(self) -> dict:
        config = {"seeds": self.seeds, "duration_s": self.duration, "warmup_s": self.warmup, "step_s": self.step,
                  "classes": [CLASS_LETTERS[c - 1] for c in self.classes], "speeds_kmh": list(self.speeds),
                  "studies": list(self.names),
                  "study10ms": "10ms" in self.names, "class_seeds": self.class_seeds, "workers": self.workers,
                  "dist": str(self.dist)}
        out: dict = {"config": config}
        for s in self.chosen():
            config.update(s.config(self))
            out.update(s.json(self))
        out["wall_time_s"] = self.wall_s
        out["targets"] = [{"target": t, "result": v, "numbers": d} for t, v, d in self.targets()]
        out["runs"] = [{k: v for k, v in r.items() if k != "traces"} for r in self.results]
        return jsonable(out)

    def plots(self, out: Path) -> list[Path]:
        return [f for s in self.chosen() for f in s.plots(self, out)]

    def write(self, out: Path | None = None) -> list[Path]:
        out = Path(out or self.out)
        out.mkdir(parents=True, exist_ok=True)
        md = out / "paper_tables.md"
        md.write_text(self.markdown())
        js = out / "paper_runs.json"
        js.write_text(json.dumps(self.to_json(), indent=1))
        return [md, js] + self.plots(out)
