"""Command line.

``python -m suspension_estimation.harness run <scenario> [--out DIR] [--no-plots] [--dist DIR]``: prints a summary;
writes ``<out>/<scenario>.csv`` and PNG plots (default ``results/<scenario>/``).

``python -m suspension_estimation.harness paper [--study NAME ...] [--seeds N] [--duration S] [--warmup S] [--step S]
[--classes B,C,D] [--workers N] [--out DIR] [--study10ms] [--class-study N] [--dask]
[--scheduler ADDRESS] [--dist DIR] [--resume]``: the papers' studies through the FMUs (one module each in
harness/studies/, named in its registry; without ``--study``: table2 and mass; with ``--dask`` or
``--scheduler`` on Dask through the sweep runner, harness/sweep.py, each worker reusing its FMU
instances); prints the tables and targets as markdown, writes ``<out>/paper_tables.md``,
``<out>/paper_runs.json`` and PNG plots (default ``results/paper/``); each run's result is appended
to ``<out>/runs.jsonl`` as it lands, and ``--resume`` runs only those not completed there. Exits 1
if any run failed (after reporting it and finishing the others).

``python -m suspension_estimation.harness sweep <file> [--workers N] [--scheduler ADDRESS] [--out DIR] [--dist DIR]
[--skip-failed] [--limit N]``: a grid or Monte Carlo study on Dask (harness/sweep.py); one row of
metrics per run and estimator streamed to Parquet (default the file's ``output``), skipping runs
already there; prints a summary. Exits 1 if a run failed now (after recording it and finishing
the others).

A user error (unknown scenario, bad key, an FMU refusing) prints one line to stderr and exits 1.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .cosim import SimulationError
from .runner import DIST, RESULTS, run_scenario, summary
from .scenario import ScenarioError, load_scenario
from .studies import STUDIES
from .sweep import SweepError


def _run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    scenario = load_scenario(args.scenario)
    out = Path(args.out) if args.out else RESULTS / scenario.name
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

        for f in plot_result(run.result, out, scenario.name):
            print(f"  wrote {f}")
    return 0


def _paper(args: argparse.Namespace) -> int:
    from .studies.runner import parse_classes
    from .studies.suite import CHECKPOINT, PaperStudy

    study = PaperStudy(seeds=args.seeds, duration=args.duration, warmup=args.warmup, step=args.step,
                       classes=parse_classes(args.classes), workers=args.workers, study10ms=args.study10ms,
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m suspension_estimation.harness", description="Co-simulate the project's FMUs.")
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scenario (a name in harness/scenarios/ or a .toml path)")
    run.add_argument("scenario", help="scenario name (e.g. default) or path to a .toml file")
    run.add_argument("--out", help="output folder (default results/<scenario>/)")
    run.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    run.add_argument("--no-plots", dest="plots", action="store_false", help="write no PNG plots")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_run)
    paper = sub.add_parser("paper", help="the papers' tables (MME&KF Table 2, vehicle-mass case) through the FMUs")
    paper.add_argument("--study", action="append", metavar="NAME",
                       help=f"run this study (repeatable; one of {', '.join(STUDIES)}; default: table2 and mass, "
                            "plus those --study10ms and --class-study add)")
    paper.add_argument("--seeds", type=int, default=10, help="seeds per cell (default 10)")
    paper.add_argument("--duration", type=float, default=60.0, help="s per Table-2 run (default 60)")
    paper.add_argument("--warmup", type=float, default=10.0, help="s not scored at the start (default 10)")
    paper.add_argument("--step", type=float, default=0.001, help="communication step in s (default 0.001)")
    paper.add_argument("--classes", default="B,C,D", help="ISO classes of Table 2 (default B,C,D)")
    paper.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    paper.add_argument("--out", default=str(RESULTS / "paper"), help="output folder (default results/paper/)")
    paper.add_argument("--study10ms", action="store_true",
                       help="also the Table-2 study at 10 ms with acc_sampling 0 and 1")
    paper.add_argument("--class-study", type=int, default=0, metavar="N",
                       help="also the online-class study, ISO A-E at 10, 20, 30 m/s, with N seeds (default 0: off)")
    paper.add_argument("--dask", action="store_true",
                       help="run on a Dask LocalCluster of --workers processes (the sweep runner: FMUs reused per worker)")
    paper.add_argument("--scheduler", metavar="ADDRESS", help="run on the Dask cluster at ADDRESS")
    paper.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    paper.add_argument("--resume", action="store_true",
                       help="keep the completed runs in <out>/runs.jsonl (same FMUs) and run only the others")
    paper.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    paper.set_defaults(func=_paper)
    sweep = sub.add_parser("sweep", help="a grid or Monte Carlo study on Dask, rows of metrics to Parquet")
    sweep.add_argument("sweep", help="sweep name (e.g. small_grid, paper_table2) or path to a .toml file")
    sweep.add_argument("--workers", type=int, default=2,
                       help="Dask worker processes of a local cluster (default 2; 0 = in this process, no Dask)")
    sweep.add_argument("--scheduler", metavar="ADDRESS", help="use the Dask cluster at ADDRESS instead")
    sweep.add_argument("--out", help="output folder of Parquet part files (default: the file's output)")
    sweep.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    sweep.add_argument("--skip-failed", action="store_true", help="do not run again what failed before")
    sweep.add_argument("--limit", type=int, help="run at most N co-simulations now")
    sweep.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sweep.set_defaults(func=_sweep)
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
