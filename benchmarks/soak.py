"""Soak test: a long road -> plant -> estimator co-simulation through the built FMUs.

    .venv/bin/python benchmarks/soak.py [--duration S] [--step H] [--dist DIR] [--json PATH]
                                        [--road-class N] [--seed N] [--speed V]

Runs ``--duration`` s of simulated time (default 3600 s at 1 ms = 3.6 M steps) of ISORoad ->
QuarterCar -> SuspensionEstimator (default estimator parameters: KF, RLS mass with feedback,
online ISO class) in ``harness.streaming.Stepper``, which keeps only the last window of samples
in memory, and checks

- no divergence: every output finite at every step, no re-initialisation (``status`` = 2), and
  the estimator's covariance P at the end symmetric (|P - P^T| <= 1e-9 max|P|) and positive
  definite (smallest eigenvalue > 0), read from the serialized FMU state (plain data, see
  ``fmu_src/suspension_fmi/state.py``);
- stable accuracy: the HP road error-STD % (``harness.metrics.road_scores``: road_height_est, the
  profile, against metrics.reference_profile of the road) of the last window (default the last
  60 s) within 10 % (relative) of that of the first window after the warm-up (default 10 s to
  70 s). Each window is scored like any run of the project: its samples from ``MARGIN`` s before
  its start, the true profile and the high-pass over all of them, the margin cut afterwards (the
  true profile starts from rest there; its transient, below the 0.5 Hz high-pass, changes the
  HP error by ~1e-4 points at 5-11 m/s);
- no leak: resident memory (VmRSS) growth < 10 MB from the end of the first scored window
  (every code path, scoring included, has run once by then) to the end.

It prints a summary, writes JSON (default benchmarks/soak.json) with the per-window HP errors
and RSS samples, and exits with status 1 if a check failed. BLAS threads are pinned to 1, and
the script leaves with ``os._exit`` (pythonfmu exit abort, PythonFMU issue 229).
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported, here or in the FMUs

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from suspension_estimation.estimators.state_classes import STATE_CLASSES  # noqa: E402
from suspension_estimation.harness.cosim import System  # noqa: E402
from suspension_estimation.harness.metrics import road_scores  # noqa: E402
from suspension_estimation.harness.streaming import Stepper  # noqa: E402
from suspension_estimation.suspension_fmi import state as fmu_state  # noqa: E402

MARGIN = 5.0  # s of samples before a scored window, for the high-pass edge transient
CHUNK = 1.0  # s simulated per Stepper.advance call
HP_DRIFT_TOL = 0.10  # last-window HP error within 10 % of the first window's
RSS_GROWTH_MB = 10.0
WIRES = ("acc_sprung", "acc_unsprung", "susp_deflection")
RECORD = ["road.road_height", "road.distance", "e.road_height_est", "e.road_height_std", "e.sprung_mass_est",
          "e.nis", "e.status", "e.road_class_est"]


def rss_mb() -> float:
    """Resident set size of this process in MB (VmRSS of /proc/self/status; Linux)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("VmRSS not found in /proc/self/status")


def estimator_covariance(sim: Stepper, instance: str = "e") -> np.ndarray:
    """The road filter's covariance P, from the serialized FMU state of ``instance``."""
    fmu = sim.instance(instance)
    state = fmu.getFMUstate()
    try:
        blob = fmu.serializeFMUstate(state)
    finally:
        fmu.freeFMUstate(state)
    return np.array(fmu_state.load(bytes(blob), STATE_CLASSES)["core"].kf.P, dtype=float)


def _windows(duration: float, warmup: float, window: float) -> list[tuple[float, float]]:
    """Scored windows (start, end) in s: back to back from the warm-up, plus the last ``window``
    s of the run if they do not end it already."""
    out = []
    start = warmup
    while start + window <= duration + 1e-9:
        out.append((start, start + window))
        start += window
    if not out:
        raise ValueError(f"duration {duration} s leaves no {window} s window after a {warmup} s warm-up")
    if out[-1][1] < duration - 1e-9:
        out.append((duration - window, duration))
    return out


def soak(duration: float = 3600.0, h: float = 1e-3, dist: Path | str | None = None,
         warmup: float = 10.0, window: float = 60.0, road_class: int = 3, seed: int = 1,
         speed: float = 11.1111, progress: bool = False) -> dict:
    """Run the soak (times in s, speed in m/s) and return its figures and checks.

    Keys: steps, wall_s, us_per_step, windows (list of {start, end, err_std_hp_pct, gain_hp}),
    hp_first_pct, hp_last_pct, hp_change_rel, rss_mb (list of [t, MB]), rss_growth_mb,
    rejected_samples, reinit_samples, P_asymmetry, P_min_eig, mass_last_mean_kg, checks
    ({name: bool}) and ok (all checks passed).
    """
    dist = Path(dist) if dist is not None else ROOT / "dist"
    n_chunk = int(round(CHUNK / h))
    for name, value in (("duration", duration), ("warmup", warmup), ("window", window)):
        if abs(value / CHUNK - round(value / CHUNK)) > 1e-9 or value < 0:
            raise ValueError(f"{name} = {value} s must be a whole number of {CHUNK} s chunks")
    if warmup < MARGIN:
        raise ValueError(f"warmup = {warmup} s must be at least the high-pass margin {MARGIN} s")
    windows = _windows(duration, warmup, window)
    n_chunks = int(round(duration / CHUNK))
    keep = int(round((window + MARGIN) / CHUNK))  # chunks buffered for the next window

    components = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu",
                  "e": dist / "SuspensionEstimator.fmu"}
    connections = ([("vehicle_speed", "road.vehicle_speed"), ("vehicle_speed", "e.vehicle_speed"),
                    ("road.road_height", "plant.road_height")] + [(f"plant.{w}", f"e.{w}") for w in WIRES])
    parameters = {"road.road_class": road_class, "road.seed": seed, "plant.noise_seed": seed}
    col = {name: j for j, name in enumerate(RECORD)}
    buffer: list[tuple[np.ndarray, np.ndarray]] = []  # (times, rows) of the last chunks
    scored: list[dict] = []
    rss: list[list[float]] = []
    rss_base = None
    rejected = reinit = 0
    finite = True
    wall0 = time.perf_counter()
    with Stepper(System(components, connections), parameters=parameters,
                 inputs={"vehicle_speed": speed}, record=RECORD) as sim:
        sim.initialize()
        pending = list(windows)
        for c in range(n_chunks):
            rows = sim.advance(n_chunk, h)
            t = (c * n_chunk + 1 + np.arange(n_chunk)) * h
            finite = finite and bool(np.isfinite(rows).all())
            status = rows[:, col["e.status"]]
            rejected += int(np.count_nonzero(status == 1))
            reinit += int(np.count_nonzero(status == 2))
            buffer.append((t, rows))
            del buffer[:-keep]
            now = (c + 1) * CHUNK
            while pending and pending[0][1] <= now + 1e-9:
                start, end = pending.pop(0)
                tt = np.concatenate([b[0] for b in buffer])
                rr = np.concatenate([b[1] for b in buffer])
                sel = (tt > start - MARGIN - 1e-9) & (tt <= end + 1e-9)
                sc = road_scores(tt[sel], rr[sel, col["e.road_height_est"]], rr[sel, col["road.road_height"]],
                                 warmup=MARGIN, distance=rr[sel, col["road.distance"]])
                scored.append({"start": start, "end": end, "err_std_hp_pct": sc["err_std_hp_pct"],
                               "gain_hp": sc["gain_hp"]})
                if rss_base is None:
                    rss_base = rss_mb()
                    rss.append([now, rss_base])
                if progress:
                    print(f"  t = {now:7.0f} s  HP error {sc['err_std_hp_pct']:.3f} %  RSS {rss_mb():.1f} MB  "
                          f"wall {time.perf_counter() - wall0:.0f} s", file=sys.stderr, flush=True)
            if rss_base is not None and (c + 1) % int(round(window / CHUNK)) == 0:
                rss.append([now, rss_mb()])
        rss_end = rss_mb()
        rss.append([duration, rss_end])
        P = estimator_covariance(sim)
        last = np.concatenate([b[1] for b in buffer])[-int(round(window / h)):]
    wall = time.perf_counter() - wall0

    eig = np.linalg.eigvalsh(0.5 * (P + P.T))
    asym = float(np.abs(P - P.T).max() / np.abs(P).max())
    first, final = scored[0]["err_std_hp_pct"], scored[-1]["err_std_hp_pct"]
    change = (final - first) / first
    growth = rss_end - rss_base
    checks = {
        "outputs_finite": finite,
        "no_reinit": reinit == 0,
        "P_symmetric": asym <= 1e-9,
        "P_positive_definite": bool(eig.min() > 0),
        "hp_error_stable": abs(change) <= HP_DRIFT_TOL,
        "rss_growth_below_10MB": growth < RSS_GROWTH_MB,
    }
    return {
        "duration_s": duration, "step_s": h, "road_class": road_class, "seed": seed, "speed_m_s": speed,
        "steps": sim.steps_done, "wall_s": wall, "us_per_step": 1e6 * wall / max(sim.steps_done, 1),
        "windows": scored, "hp_first_pct": first, "hp_last_pct": final, "hp_change_rel": change,
        "rss_mb": rss, "rss_growth_mb": growth, "rejected_samples": rejected, "reinit_samples": reinit,
        "P_asymmetry": asym, "P_min_eig": float(eig.min()), "P_max_eig": float(eig.max()),
        "mass_last_mean_kg": float(np.mean(last[:, col["e.sprung_mass_est"]])),
        "road_class_last": int(last[-1, col["e.road_class_est"]]),
        "checks": checks, "ok": all(checks.values()),
    }


def summary(res: dict) -> str:
    """A few lines for the terminal."""
    lines = [
        f"soak: {res['duration_s']:.0f} s at {1e3 * res['step_s']:g} ms = {res['steps']} steps, "
        f"wall {res['wall_s']:.0f} s ({res['us_per_step']:.0f} us/step)",
        f"  HP road error: first window {res['hp_first_pct']:.3f} %, last {res['hp_last_pct']:.3f} % "
        f"(change {100 * res['hp_change_rel']:+.1f} %, limit +-{100 * HP_DRIFT_TOL:.0f} %)",
        f"  RSS growth {res['rss_growth_mb']:+.2f} MB (limit {RSS_GROWTH_MB:g} MB); "
        f"P: asymmetry {res['P_asymmetry']:.2g}, eigenvalues {res['P_min_eig']:.3g} .. {res['P_max_eig']:.3g}",
        f"  rejected samples {res['rejected_samples']}, re-initialisations {res['reinit_samples']}, "
        f"mass (last window) {res['mass_last_mean_kg']:.2f} kg, class {res['road_class_last']}",
    ]
    lines += [f"  {'PASS' if ok else 'FAIL'} {name}" for name, ok in res["checks"].items()]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="simulated time, s (default 3600)")
    ap.add_argument("--step", type=float, default=1e-3, help="communication step, s (default 0.001)")
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="folder of the built FMUs")
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "soak.json", help="where to write JSON")
    ap.add_argument("--road-class", type=int, default=3, help="ISO 8608 class of the road, 1..8 (default 3 = C)")
    ap.add_argument("--seed", type=int, default=1, help="road and sensor-noise seed")
    ap.add_argument("--speed", type=float, default=11.1111, help="vehicle speed, m/s (default 40 km/h)")
    args = ap.parse_args(argv)
    res = soak(args.duration, args.step, args.dist, road_class=args.road_class, seed=args.seed,
               speed=args.speed, progress=True)
    print(summary(res))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(res, indent=1) + "\n")
    print(f"wrote {args.json}")
    return 0 if res["ok"] else 1


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
