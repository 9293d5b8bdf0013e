"""Command line: ``python -m harness run <scenario> [--out DIR] [--no-plots] [--dist DIR]``.

Prints a summary; writes ``<out>/<scenario>.csv`` and PNG plots (default ``results/<scenario>/``).
A user error (unknown scenario, bad key, an FMU refusing) prints one line to stderr and exits 1.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .cosim import SimulationError
from .runner import DIST, RESULTS, run_scenario, summary
from .scenario import ScenarioError, load_scenario


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
                e.result is not None and len(e.result)) else ""
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness", description="Co-simulate the project's FMUs.")
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scenario (a name in harness/scenarios/ or a .toml path)")
    run.add_argument("scenario", help="scenario name (e.g. default) or path to a .toml file")
    run.add_argument("--out", help="output folder (default results/<scenario>/)")
    run.add_argument("--dist", default=str(DIST), help="folder with the FMUs (default dist/)")
    run.add_argument("--no-plots", dest="plots", action="store_false", help="write no PNG plots")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    try:
        return _run(args)
    except (ScenarioError, FileNotFoundError, KeyError, ValueError, OSError) as e:
        msg = e.args[0] if isinstance(e, KeyError) and e.args else e
        print(f"error: {msg}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
