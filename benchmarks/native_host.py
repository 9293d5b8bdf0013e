"""The FMUs in a native C host (tests/native_host.c) with the environment of tools/fmu-env:
how often the process aborts at exit, and what the BLAS thread count costs.

    .venv/bin/python benchmarks/native_host.py aborts [--fmu NAME] [--runs N] [--leave exit|dlclose]
                                                      [--quick-exit 0|1] [--steps N]
    .venv/bin/python benchmarks/native_host.py blas [--fmu NAME] [--runs N] [--steps N] [--threads T|default]
                                                    [--grid]

``aborts``: N runs of ``native_host DIR NAME GUID STEPS 0.001 <leave>`` (free the instance, then
return from main; with ``dlclose`` unload the library first, as fmusim does), counting exit status
134 / SIGABRT (pythonfmu 0.7.0's double release at exit, PythonFMU #229), with
``SUSPENSION_FMU_QUICK_EXIT`` as given (fmu_src/suspension_fmi/quick_exit.py). Whether glibc
notices the corrupted heap depends on the heap's layout: run k reaches the FMU's folder through a
link whose name is 1 + k % 64 characters long, so the runs sample 64 layouts.

``blas``: wall and CPU time of N runs with OPENBLAS_NUM_THREADS/OMP_NUM_THREADS = T (``default``:
unset), the FMU's first Real input at 0.01 (the plant's road height); ``--grid`` steps by
(k+1)*h - k*h as fmusim and libcosim do, instead of h.

Needs a C compiler (cc) and the FMUs in dist/ (build.py). Prints one line per setting.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from importlib.machinery import SourceFileLoader
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _fmu_env() -> dict[str, str]:
    """``fmu_env()`` of tools/fmu-env (a script without .py: loaded by path) for this interpreter."""
    loader = SourceFileLoader("fmu_env", str(ROOT / "tools" / "fmu-env"))
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader("fmu_env", loader))
    loader.exec_module(module)
    return module.fmu_env()


def _host(work: Path) -> Path:
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise SystemExit("native_host: no C compiler (cc, gcc)")
    exe = work / "native_host"
    subprocess.run([cc, "-O1", "-o", str(exe), str(ROOT / "tests" / "native_host.c"), "-ldl"], check=True)
    return exe


def _unzip(fmu: Path, work: Path) -> tuple[Path, str, int]:
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    out = work / fmu.stem
    with zipfile.ZipFile(fmu) as z:
        z.extractall(out)
    first_input = next(v.valueReference for v in md.modelVariables if v.causality == "input" and v.type == "Real")
    return out, md.guid, first_input


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["aborts", "blas"])
    ap.add_argument("--fmu", default=None, help="model identifier (default SuspensionEstimator for aborts, "
                                                "QuarterCar for blas)")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--steps", type=int, default=None, help="steps of 1 ms (default 100 for aborts, 5000 for blas)")
    ap.add_argument("--leave", choices=["exit", "dlclose"], default="exit")
    ap.add_argument("--quick-exit", choices=["0", "1"], default="1")
    ap.add_argument("--threads", default="1")
    ap.add_argument("--grid", action="store_true")
    ap.add_argument("--dist", type=Path, default=ROOT / "dist")
    args = ap.parse_args(argv)
    name = args.fmu or ("SuspensionEstimator" if args.what == "aborts" else "QuarterCar")
    steps = args.steps or (100 if args.what == "aborts" else 5000)
    fmu = args.dist / f"{name}.fmu"
    if not fmu.is_file():
        raise SystemExit(f"native_host: {fmu} does not exist (run build.py)")
    env = {**{k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH")},
           **_fmu_env()}
    with tempfile.TemporaryDirectory(prefix="native-host-") as tmp:
        work = Path(tmp)
        host = _host(work)
        unzipped, guid, first_input = _unzip(fmu, work)
        base = [str(host), str(unzipped), name, guid, str(steps), "0.001"]
        if args.what == "aborts":
            env["SUSPENSION_FMU_QUICK_EXIT"] = args.quick_exit
            aborts = other = 0
            for run in range(args.runs):
                # whether the corrupted heap is detected depends on its layout, which the FMU's path
                # changes: each run reaches the FMU through a link of another length (1..64)
                link = work / ("l" * (1 + run % 64))
                if not link.exists():
                    link.symlink_to(unzipped)
                args_run = [base[0], str(link)] + base[2:] + [args.leave]
                proc = subprocess.run(args_run, capture_output=True, text=True, env=env, cwd=work)
                if proc.returncode in (134, -signal.SIGABRT):
                    aborts += 1
                elif proc.returncode != 0 or len(proc.stdout.splitlines()) != steps + 1:
                    other += 1
            print(f"{name}: {args.runs} runs, leave={args.leave}, SUSPENSION_FMU_QUICK_EXIT={args.quick_exit}: "
                  f"{aborts} aborted at exit, {other} other failures")
        else:
            if args.threads == "default":
                env.pop("OPENBLAS_NUM_THREADS", None)
                env.pop("OMP_NUM_THREADS", None)
            else:
                env["OPENBLAS_NUM_THREADS"] = env["OMP_NUM_THREADS"] = args.threads
            walls, cpus = [], []
            for _ in range(args.runs):
                cpu0, t0 = _children_cpu(), time.perf_counter()
                subprocess.run(base + [f"r:{first_input}=0.01", "exit"] + (["grid"] if args.grid else []),
                               capture_output=True, env=env, cwd=work, check=True)
                walls.append(time.perf_counter() - t0)
                cpus.append(_children_cpu() - cpu0)
            print(f"{name}: {steps} steps, threads={args.threads}, {'grid' if args.grid else 'exact'} steps: "
                  f"wall {', '.join(f'{w:.2f}' for w in walls)} s; CPU {', '.join(f'{c:.2f}' for c in cpus)} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
