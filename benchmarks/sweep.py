"""Throughput and memory of the sweep runner (harness/sweep.py): serial against Dask workers.

    .venv/bin/python benchmarks/sweep.py [--runs N] [--duration S] [--workers N]
                                         [--memory-runs N] [--memory-duration S] [--json PATH] [--dist DIR]

Throughput: the same ``--runs`` co-simulations (ISO C, 40 km/h, 410 kg, seeds 1..N,
``--duration`` s at 1 ms, one road + plant + the four estimator instances of the paper's
Table 2) run once in this process (``run_task`` in a loop, as ``--workers 0`` does) and once on
a Dask LocalCluster of ``--workers`` processes (``harness.sweep.execute``, as ``python -m
harness sweep`` does). Both are warm: before the clock starts, every process has extracted the
FMUs and made its CoSimulation (one 0.1 s run each), so the figures are the steady state of a
long sweep; the cluster's start-up is timed separately. Ratio = serial wall time / parallel wall
time (target: >= 1.8 with 2 workers).

Memory: ``--memory-runs`` short runs on the cluster; every row records the resident memory of
its worker after the run (``worker_rss_mb``), and the script prints, per worker, the RSS after
its 5th run and after its last one.

Also the median µs per step of a run in each phase: if a run steps as fast in a worker as in
this process, the ratio's shortfall from the number of workers is the machine's (free cores),
not the runner's. Prints the numbers and writes JSON (default benchmarks/sweep.json). The machine's load is not
controlled: other processes on its cores lower the parallel figure.
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy is imported

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

from suspension_estimation.harness.studies import runner  # noqa: E402
from suspension_estimation.harness.sweep import Sweep, close_worker, execute, failed_rows, local_cluster, run_task  # noqa: E402


def _tasks(dist: Path, n: int, duration: float, first_seed: int = 1) -> list:
    points = [{"road_class": 3, "speed": runner.SPEED, "mass": runner.NOMINAL_MASS, "seed": first_seed + i}
              for i in range(n)]
    sweep = Sweep(name="bench", points=points, estimators=runner.ESTIMATORS, duration=duration, step=1e-3,
                  warmup=min(2.0, duration / 2))
    return sweep.tasks(dist)


def _timed(tasks: list, client=None) -> tuple[float, list[dict]]:
    rows: list[dict] = []
    t0 = time.perf_counter()
    execute(tasks, run_task, lambda t, r: rows.extend(r), client, failed_rows)
    return time.perf_counter() - t0, rows


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8, help="co-simulations for the throughput (default 8)")
    ap.add_argument("--duration", type=float, default=10.0, help="s per throughput run (default 10)")
    ap.add_argument("--workers", type=int, default=2, help="Dask worker processes (default 2)")
    ap.add_argument("--memory-runs", type=int, default=80, help="short runs for the memory figure (default 80)")
    ap.add_argument("--memory-duration", type=float, default=0.5, help="s per memory run (default 0.5)")
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "sweep.json", help="where to write JSON")
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="folder with the built FMUs")
    args = ap.parse_args()
    from distributed import Client

    tasks = _tasks(args.dist, args.runs, args.duration)
    warm = [replace(t, spec=replace(t.spec, duration=0.1, warmup=0.0)) for t in _tasks(args.dist, 1, 0.1)]
    res: dict = {"runs": args.runs, "duration_s": args.duration, "workers": args.workers,
                 "estimators": [e.instance for e in runner.ESTIMATORS], "load_avg_start": os.getloadavg()}

    print(f"serial: {args.runs} runs of {args.duration:g} s in this process ...", flush=True)
    execute(warm, run_task, lambda t, r: None)
    serial_s, rows = _timed(tasks)
    close_worker()
    bad = [r["error"] for r in rows if not r["ok"]]
    res["serial"] = {"wall_s": serial_s, "runs_per_min": 60 * args.runs / serial_s, "failed": bad,
                     "us_per_step_median": _median_step(rows)}
    print(f"  {serial_s:.1f} s, {60 * args.runs / serial_s:.2f} runs/min", flush=True)

    print(f"dask: the same runs on a LocalCluster of {args.workers} workers ...", flush=True)
    t0 = time.perf_counter()
    cluster = local_cluster(args.workers)
    client = Client(cluster)
    client.wait_for_workers(args.workers)
    res["cluster_start_s"] = time.perf_counter() - t0
    try:
        for w in client.nthreads():  # every worker extracts the FMUs and makes its CoSimulation
            client.submit(run_task, warm[0], workers=[w], pure=False).result()
        res["cluster_warm_s"] = time.perf_counter() - t0
        par_s, rows = _timed(tasks, client)
        bad = [r["error"] for r in rows if not r["ok"]]
        res["parallel"] = {"wall_s": par_s, "runs_per_min": 60 * args.runs / par_s, "failed": bad,
                           "runs_per_worker": _count(rows), "us_per_step_median": _median_step(rows)}
        res["ratio"] = serial_s / par_s
        print(f"  {par_s:.1f} s, {60 * args.runs / par_s:.2f} runs/min; cluster start {res['cluster_start_s']:.1f} s "
              f"(+ warm-up {res['cluster_warm_s'] - res['cluster_start_s']:.1f} s)", flush=True)

        print(f"memory: {args.memory_runs} runs of {args.memory_duration:g} s on the cluster ...", flush=True)
        mem_tasks = _tasks(args.dist, args.memory_runs, args.memory_duration, first_seed=101)
        mem_s, rows = _timed(mem_tasks, client)
        client.run(close_worker)
    finally:
        client.close()
        cluster.close()
    per: dict = {}
    for r in rows:
        if r["ok"] and r["estimator"] == runner.ESTIMATORS[0].instance:
            per.setdefault(r["worker"], {})[r["worker_run"]] = r["worker_rss_mb"]
    res["memory"] = {"wall_s": mem_s, "per_worker": {}}
    for w, by_run in sorted(per.items()):
        runs = sorted(by_run)
        at5 = by_run.get(5 + runs[0] - 1)  # the worker's 5th run of this batch
        d = {"runs": len(runs), "rss_mb_run5": at5, "rss_mb_last": by_run[runs[-1]],
             "growth_mb": by_run[runs[-1]] - at5 if at5 is not None else None,
             "rss_mb_by_run": [round(by_run[k], 1) for k in runs]}
        res["memory"]["per_worker"][str(w)] = d
    res["load_avg_end"] = os.getloadavg()

    print()
    print(f"| measure | value |\n|---|---|")
    print(f"| serial, {args.runs} x {args.duration:g} s | {serial_s:.1f} s ({res['serial']['runs_per_min']:.2f} runs/min) |")
    print(f"| {args.workers} Dask workers, same runs | {par_s:.1f} s ({res['parallel']['runs_per_min']:.2f} runs/min) |")
    print(f"| ratio (target >= 1.8) | {res['ratio']:.2f} |")
    print(f"| µs per step of a run, median: serial / in a worker | {res['serial']['us_per_step_median']:.0f} / "
          f"{res['parallel']['us_per_step_median']:.0f} |")
    print(f"| cluster start-up | {res['cluster_start_s']:.1f} s |")
    for w, d in res["memory"]["per_worker"].items():
        print(f"| worker {w}: RSS after run 5 -> after run {d['runs']} | {d['rss_mb_run5']:.1f} -> "
              f"{d['rss_mb_last']:.1f} MiB ({d['growth_mb']:+.1f}) |")
    print(f"| load average start / end | {res['load_avg_start'][0]:.2f} / {res['load_avg_end'][0]:.2f} |")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(res, indent=2) + "\n")
    print(f"\nwrote {args.json}")
    return res


def _median_step(rows: list[dict]) -> float:
    import numpy as np

    return float(np.median([r["us_per_step"] for r in rows if r["ok"] and r["estimator"] == runner.ESTIMATORS[0].instance]))


def _count(rows: list[dict]) -> dict:
    out: dict = {}
    for r in rows:
        if r["estimator"] == runner.ESTIMATORS[0].instance:
            out[str(r["worker"])] = out.get(str(r["worker"]), 0) + 1
    return out


if __name__ == "__main__":
    code = 0
    try:
        main()
    except SystemExit as e:  # argparse: --help, usage errors
        code = e.code if isinstance(e.code, int) else 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # pythonfmu's exit handlers can abort the process (PythonFMU issue 229)
