"""Command line.

``python -m suspension_estimation.harness run <scenario> [--out DIR] [--no-plots] [--dist DIR]``: prints the vehicle's
and the estimator's parameters (``runner.parameter_lines``), then a summary; writes ``<out>/<scenario>.csv``
and PNG plots (default ``results/<scenario>/``).

``python -m suspension_estimation.harness paper [--study NAME ...] [--seeds N] [--duration S] [--warmup S] [--step S]
[--classes B,C,D] [--speeds 40,80] [--workers N] [--out DIR] [--study10ms] [--class-study N] [--dask]
[--scheduler ADDRESS] [--dist DIR] [--resume]``: the papers' studies through the FMUs (one module each in
harness/studies/, named in its registry; without ``--study``: table2 and mass; with ``--dask`` or
``--scheduler`` on Dask through the sweep runner, harness/sweep.py, each worker reusing its FMU
instances); prints the tables and targets as markdown, writes ``<out>/paper_tables.md``,
``<out>/paper_runs.json`` and PNG plots (default ``results/paper/``); each run's result is appended
to ``<out>/runs.jsonl`` as it lands, and ``--resume`` runs only those not completed there. Exits 1
if any run failed (after reporting it and finishing the others). ``--seeds``, ``--duration``,
``--classes`` and ``--speeds`` (km/h, the sensors study's) not given take the study's own defaults
(``Study.defaults``) when ``--study`` names one study alone: ``--study sensors`` runs ISO C at
40 km/h, 2 seeds of 30 s.

``python -m suspension_estimation.harness sweep <file> [--workers N] [--scheduler ADDRESS] [--out DIR] [--dist DIR]
[--skip-failed] [--limit N]``: a grid or Monte Carlo study on Dask (harness/sweep.py); one row of
metrics per run and estimator streamed to Parquet (default the file's ``output``), skipping runs
already there; prints a summary. Exits 1 if a run failed now (after recording it and finishing
the others).

``python -m suspension_estimation.harness calibrate LOG --profile REF --mass KG --out FILE [--offset M]
[--search M] [--noise A_S,A_U,D] [--settle S] [--profile-units U] [--map ...] [--unit ...]``: fits m_u, k_s, k_t, c_s of
the linear quarter car to a log (read as ``estimate`` reads it) driven over a section of known profile
(harness/calibrate.py); prints them with their
1-sigma and writes the estimator's vehicle file (TOML). A section too short or too smooth to identify
them: a warning line on stderr, exit 0.

``python -m suspension_estimation.harness estimate LOG --out DIR [--map CHANNEL=COLUMN ...] [--unit CHANNEL=UNIT ...]
[--vehicle FILE] [--segment M] [--dist DIR]``: the estimator FMU over a log of your own, CSV or MDF4
(harness/estimate.py); writes ``DIR/estimates.csv``, ``DIR/iri.csv`` and ``DIR/report.png``, prints a summary.

A user error (unknown scenario, bad key, an FMU refusing) prints one line to stderr and exits 1.
Each command's ``--help`` lists what it can run: the shipped scenarios and sweeps with the
``description`` of their files, the studies with their line in ``harness.studies.STUDIES``.
"""
from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

from . import estimate
from .cosim import SimulationError
from .runner import DIST, RESULTS, choose_system, parameter_lines, run_scenario, summary
from .scenario import SCENARIOS, ScenarioError, load_scenario
from .studies import STUDIES
from .studies.suite import DEFAULT_STUDIES
from .sweep import SWEEPS, SweepError


def _listing(rows: dict[str, str]) -> str:
    """``name  text`` lines, the texts aligned (an epilog of --help)."""
    width = max(map(len, rows), default=0)
    return "\n".join(f"  {name:<{width}}  {text}" for name, text in rows.items())


def _shipped(folder: Path) -> dict[str, str]:
    """Name -> ``description`` of each TOML file in ``folder`` (the scenarios, the sweeps)."""
    out = {}
    for f in sorted(folder.glob("*.toml")):
        try:
            with open(f, "rb") as fh:
                out[f.stem] = str(tomllib.load(fh).get("description", ""))
        except (OSError, tomllib.TOMLDecodeError) as e:  # --help must not fail on one bad file
            out[f.stem] = f"(unreadable: {e})"
    return out


def _run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    scenario = load_scenario(args.scenario)
    out = Path(args.out) if args.out else RESULTS / scenario.name
    print(f"{scenario.name}: {scenario.description or scenario.path}")
    for line in parameter_lines(scenario, choose_system(scenario, Path(args.dist))):
        print(line)
    n = round(scenario.duration / scenario.step)
    with tqdm(total=n, unit="step", desc=scenario.name, disable=args.quiet or None, leave=False) as bar:
        try:
            run = run_scenario(scenario, dist=Path(args.dist), out=out, progress=bar.update)
        except SimulationError as e:
            bar.close()
            where = f"; partial results up to t = {e.result['time'][-1]:.6g} s in {out}" if (
                e.result is not None and len(e.result)) else "; no result file written"
            print(f"error: {e}{where}", file=sys.stderr)
            return 1
    for line in summary(run):
        print(line)
    print(f"  wrote {run.csv}")
    if args.plots and scenario.plots:
        from .plots import plot_result

        for f in plot_result(run.result, out, scenario.name, cutoff=scenario.profile_cutoff):
            print(f"  wrote {f}")
    return 0


def _paper(args: argparse.Namespace) -> int:
    from .studies import load
    from .studies.runner import parse_classes, parse_speeds
    from .studies.suite import CHECKPOINT, PaperStudy

    # an option not given: the study's own default (``Study.defaults``) when --study names one study
    # alone and no flag adds another, else the common one
    named = set(args.study or ())
    own = dict(load(next(iter(named))).defaults) if len(named) == 1 and not (args.study10ms or args.class_study) \
        else {}
    given = {"seeds": args.seeds, "duration": args.duration,
             "classes": None if args.classes is None else parse_classes(args.classes),
             "speeds": None if args.speeds is None else parse_speeds(args.speeds)}
    common = {"seeds": 10, "duration": 60.0, "classes": parse_classes("B,C,D"), "speeds": ()}
    opt = {k: v if v is not None else own.get(k, common[k]) for k, v in given.items()}
    study = PaperStudy(seeds=opt["seeds"], duration=opt["duration"], warmup=args.warmup, step=args.step,
                       classes=opt["classes"], speeds=opt["speeds"], workers=args.workers, study10ms=args.study10ms,
                       class_seeds=args.class_study, dask=args.dask, scheduler=args.scheduler,
                       dist=Path(args.dist), out=Path(args.out), studies=tuple(args.study or ()),
                       resume=args.resume)
    study.run(progress=not args.quiet)
    files = study.write()
    print(study.markdown(), end="")
    for f in files:
        print(f"wrote {f}")
    print(f"{study.ran} runs co-simulated now, {study.reused} taken from {Path(args.out) / CHECKPOINT}")
    return 1 if study.failures() else 0


def _sweep(args: argparse.Namespace) -> int:
    from .sweep import load_sweep, run_sweep, summary

    sweep = load_sweep(args.sweep)
    if args.limit is not None and args.limit < 0:
        raise ValueError(f"--limit = {args.limit} must be >= 0")
    rep = run_sweep(sweep, dist=Path(args.dist), out=Path(args.out) if args.out else None, workers=args.workers,
                    scheduler=args.scheduler, skip_failed=args.skip_failed, limit=args.limit,
                    progress=not args.quiet)
    where = f"on {rep.workers} Dask workers" if rep.workers else "in this process"
    print(f"{sweep.name}: {rep.rows} rows; {rep.done_before} done before; {rep.runs} runs now, {rep.written} rows "
          f"({rep.failed} failed) in {rep.wall_s:.1f} s {where}")
    lines = summary(rep.output)
    if len(lines) <= 102:
        print("\n".join(lines))
    print(f"wrote {rep.output} ({len(rep.files)} new part files)")
    return 1 if rep.failed else 0


def _calibrate(args: argparse.Namespace) -> int:
    from ..plant.quarter_car import SensorNoise
    from .calibrate import run, summary_lines

    try:
        stds = [float(x) for x in args.noise.split(",")] if args.noise else None
    except ValueError:
        stds = []
    if stds is not None and len(stds) != 3:
        raise ValueError(f"--noise takes three stds A_S,A_U,D (m/s2, m/s2, m), not {args.noise!r}")
    keys = ("time", *estimate.CHANNELS)
    cal = run(args.log, args.profile, args.mass, args.out, offset=args.offset, search=args.search,
              noise=SensorNoise(*stds) if stds else SensorNoise(), settle=args.settle,
              profile_units=args.profile_units, names=estimate.parse_pairs(args.map, "--map", keys),
              units=estimate.parse_pairs(args.unit, "--unit", keys))
    print("\n".join(summary_lines(cal)))
    print(f"wrote {args.out}")
    for w in cal.warnings:
        print(f"warning: {w}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    raw = argparse.RawDescriptionHelpFormatter
    scenarios, sweeps = _shipped(SCENARIOS), _shipped(SWEEPS)
    ap = argparse.ArgumentParser(prog="python -m suspension_estimation.harness", description="Co-simulate the project's FMUs.",
                                 epilog="A user error (unknown scenario, bad key, an FMU refusing) prints one line "
                                        "to stderr and exits 1. Each command's --help lists what it can run.")
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", formatter_class=raw,
                         help=f"co-simulate a scenario ({', '.join(scenarios)}, or a .toml file)",
                         description="Co-simulate a scenario: road -> plant (-> estimator when its FMU is in "
                                     "--dist).\nPrints the vehicle's and the estimator's parameters, then the "
                                     "scores;\nwrites <out>/<scenario>.csv and PNG plots.",
                         epilog=f"scenarios (harness/scenarios/; keys: harness/scenario.py):\n{_listing(scenarios)}")
    run.add_argument("scenario", help="scenario name (one of those below) or path to a .toml file")
    run.add_argument("--out", help="output folder (default results/<scenario>/)")
    run.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    run.add_argument("--no-plots", dest="plots", action="store_false", help="write no PNG plots")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_run)
    studies = {name: text for name, (_, text) in STUDIES.items()}
    paper = sub.add_parser("paper", formatter_class=raw,
                           help=f"the papers' and robustness studies through the FMUs ({len(STUDIES)} studies: paper --help)",
                           description="The papers' and robustness studies through the FMUs, in worker processes "
                                       "(or on Dask).\nPrints the tables and targets as markdown; writes "
                                       "<out>/paper_tables.md, paper_runs.json,\nruns.jsonl and PNG plots. "
                                       "Exits 1 if a run failed (after finishing the others).",
                           epilog=f"studies (--study NAME; without it: {' and '.join(DEFAULT_STUDIES)}):\n"
                                  f"{_listing(studies)}")
    paper.add_argument("--study", action="append", metavar="NAME",
                       help=f"run this study (repeatable; one of those below; default: {' and '.join(DEFAULT_STUDIES)}, "
                            "plus those --study10ms and --class-study add)")
    paper.add_argument("--seeds", type=int, help="seeds per cell (default 10; --study sensors alone: 2)")
    paper.add_argument("--duration", type=float,
                       help="s per run of table2, 10ms, class, robust, paper003 and sensors (default 60; --study "
                            "sensors alone: 30; the others have their own)")
    paper.add_argument("--warmup", type=float, default=10.0,
                       help="s not scored at the start of those runs (default 10)")
    paper.add_argument("--step", type=float, default=0.001,
                       help="communication step in s (default 0.001; 10ms and vb have their own; the sensors "
                            "study's logging cases step their estimators every 1, 5 and 10 ms on it)")
    paper.add_argument("--classes", help="ISO classes of table2, 10ms, robust and sensors (default B,C,D; --study "
                                         "sensors alone: C)")
    paper.add_argument("--speeds", help="km/h of the sensors study (default 40,80; --study sensors alone: 40)")
    paper.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    paper.add_argument("--out", default=str(RESULTS / "paper"), help="output folder (default results/paper/)")
    paper.add_argument("--study10ms", action="store_true", help="also the 10ms study")
    paper.add_argument("--class-study", type=int, default=0, metavar="N",
                       help="also the class study, with N seeds (default 0: off; --study class: --seeds)")
    paper.add_argument("--dask", action="store_true",
                       help="run on a Dask LocalCluster of --workers processes (the sweep runner: FMUs reused per worker)")
    paper.add_argument("--scheduler", metavar="ADDRESS", help="run on the Dask cluster at ADDRESS")
    paper.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    paper.add_argument("--resume", action="store_true",
                       help="keep the completed runs in <out>/runs.jsonl (same FMUs) and run only the others")
    paper.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    paper.set_defaults(func=_paper)
    sweep = sub.add_parser("sweep", formatter_class=raw,
                           help="a grid or Monte Carlo study on Dask, rows of metrics to Parquet",
                           description="A grid or Monte Carlo study on Dask (extra 'sweep'): one row of metrics per "
                                       "run and\nestimator streamed to Parquet, skipping the runs already there; "
                                       "prints a summary.\nExits 1 if a run failed now.",
                           epilog=f"sweeps (harness/sweeps/; keys: harness/sweep.py):\n{_listing(sweeps)}")
    sweep.add_argument("sweep", help="sweep name (one of those below) or path to a .toml file")
    sweep.add_argument("--workers", type=int, default=2,
                       help="Dask worker processes of a local cluster (default 2; 0 = in this process, no Dask)")
    sweep.add_argument("--scheduler", metavar="ADDRESS", help="use the Dask cluster at ADDRESS instead")
    sweep.add_argument("--out", help="output folder of Parquet part files (default: the file's output)")
    sweep.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    sweep.add_argument("--skip-failed", action="store_true", help="do not run again what failed before")
    sweep.add_argument("--limit", type=int, help="run at most N co-simulations now")
    sweep.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sweep.set_defaults(func=_sweep)
    cal = sub.add_parser("calibrate", help="fit the vehicle (m_u, k_s, k_t, c_s) on a section of known profile",
                         description="Fit m_u, k_s, k_t, c_s of the linear quarter car, with the sprung mass given, to "
                                     "a log driven over a section whose profile is known (the log's start at --offset "
                                     "of the profile, refined by the fit); write the estimator's vehicle file (TOML).")
    cal.add_argument("log", help="the log, read as estimate reads it (CSV or MDF4): time (s), acc_sprung, "
                                 "acc_unsprung (m/s2), susp_deflection (m), vehicle_speed (m/s)")
    cal.add_argument("--profile", required=True, help="the section's profile (CSV, ERD or OpenCRG, as ISORoad plays)")
    cal.add_argument("--mass", type=float, required=True,
                     help="sprung mass m_s in kg (the response fixes only ratios: every value scales with it)")
    cal.add_argument("--out", required=True, help="vehicle file to write (TOML)")
    cal.add_argument("--offset", type=float, default=0.0,
                     help="profile distance (m) at the log's first sample (default 0); the fit refines it")
    cal.add_argument("--search", type=float, default=2.0,
                     help="m either side of --offset searched for the placement's start value (default 2)")
    cal.add_argument("--noise", help="sensor noise stds A_S,A_U,D in m/s2, m/s2, m (default: the contract's, "
                                     "0.02,0.2,0.0001)")
    cal.add_argument("--settle", type=float, default=2.0, help="s at the start not scored (default 2)")
    cal.add_argument("--profile-units", default="",
                     help="units of the profile, as ISORoad's profile_units ('mm', 'ft,in')")
    cal.add_argument("--map", action="append", metavar="CHANNEL=COLUMN", help="a column of the log, as for estimate")
    cal.add_argument("--unit", action="append", metavar="CHANNEL=UNIT", help="a unit of the log, as for estimate")
    cal.set_defaults(func=_calibrate)
    estimate.add_parser(sub)
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except (ScenarioError, SweepError, FileNotFoundError, KeyError, ValueError, OSError) as e:
        msg = e.args[0] if isinstance(e, KeyError) and e.args else e
        print(f"error: {msg}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
