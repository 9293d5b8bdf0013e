"""The FMI surface fuzzed long: random FMI call sequences through FMPy against each built FMU.

    .venv/bin/python benchmarks/fmi_fuzz.py [--sequences N] [--dist DIR] [--seed N]

Runs ``--sequences`` (default 10 000) sequences of 1 to 40 calls per FMU, drawn by hypothesis
(tests/fmi_fuzz.py says what is drawn and what must hold), each FMU in a process of its own so
that a crash of the host is seen and counted rather than ending the run. Prints per FMU the
sequences and calls tried, the calls refused with a logged reason, failures and crashes; exits
1 if any sequence failed or any process died. The suite runs 25 sequences per FMU
(tests/test_fmi_fuzz.py).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("ISORoad", "QuarterCar", "SuspensionEstimator", "HalfCar")


def worker(fmu: Path, n: int, seed: int) -> dict:
    """Run n sequences on one FMU in this process; the counts (and the first failure)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from hypothesis import HealthCheck, given, seed as hseed, settings

    from fmi_fuzz import Unpacked, check, sequences

    u = Unpacked(fmu)
    total = {"sequences": 0, "calls": 0, "refused": 0, "errors logged": 0}

    @hseed(seed)
    @settings(max_examples=n, database=None, deadline=None, suppress_health_check=list(HealthCheck))
    @given(seq=sequences(u))
    def run(seq):
        counts = check(u, *seq)
        total["sequences"] += 1
        for k, v in counts.items():
            total[k] += v

    try:
        run()
        total["failure"] = None
    except Exception as e:  # noqa: BLE001 - reported, the falsifying example printed by hypothesis
        total["failure"] = f"{type(e).__name__}: {str(e)[:2000]}"
    finally:
        u.close()
    return total


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequences", type=int, default=10_000, help="sequences per FMU (default 10000)")
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="folder of the built FMUs (default dist/)")
    ap.add_argument("--seed", type=int, default=1, help="hypothesis seed (default 1)")
    ap.add_argument("--worker", nargs=3, metavar=("FMU", "N", "SEED"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        fmu, n, seed = args.worker
        print(json.dumps(worker(Path(fmu), int(n), int(seed))))
        return 0
    bad = 0
    for model in MODELS:
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, __file__, "--worker", str(args.dist / f"{model}.fmu"),
                               str(args.sequences), str(args.seed)], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        lines = proc.stdout.strip().splitlines()
        try:
            res = json.loads(lines[-1])
        except (IndexError, ValueError):
            res = None
        if res is None:
            bad += 1
            print(f"{model}: the process died (exit {proc.returncode}) after {wall:.0f} s: "
                  f"{proc.stderr.strip()[-500:]}")
            continue
        bad += res["failure"] is not None
        print(f"{model}: {res['sequences']} sequences, {res['calls']} calls, {res['refused']} refused "
              f"(fmi2Discard/Error), {res['errors logged']} with a logged reason checked, "
              f"failures {0 if res['failure'] is None else 1}, crashes 0, {wall:.0f} s")
        if res["failure"]:
            print(f"  {res['failure']}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
