"""Road estimate, its 2-sigma coverage and the IRI on the test roads, through the built FMUs.

    .venv/bin/python benchmarks/real_roads.py [--roads sag,curves,...] [--speeds 40,72] [--seeds 1-3]
        [--cases exact,"all -",nonlinear,...] [--acc-sampling 0] [--dist dist] [--workers 2]

ISORoad (the road of harness.testroads.make_road written as a profile file) -> QuarterCar (410 kg,
its sensor noise with ``noise_seed``) -> the default SuspensionEstimator told the contract's default
vehicle, 1 ms steps, the whole road. The plant is that vehicle ("exact"), or a case of the robustness
study (harness/studies/robust.py ``CASES``: c_s, k_s, k_t, m_u off alone or all together), or its
air-spring plant with the asymmetric damper ("nonlinear", the estimator then told the linearisation
at the static point). Per case, road and speed, means over the noise seeds
(the road is the same): HP road error std % (harness.metrics.road_scores), the raw error rms of
road_height_est (the profile) against ``metrics.reference_profile`` of the road and the rms
road_height_std after the 10 s warm-up, their ratio (pooled over the seeds: sqrt(mean rms^2 /
mean std^2)), the 2-sigma coverage of that error (mean over the seeds, and its range), the largest
|error| within 5 m of a bump or pothole, the IRI error per completed 100 m segment after the first
(mean and worst %), and the sprung-mass error and mass_std at the end. ``--acc-sampling 1``: the
plant reports, and the estimator is told, accelerations averaged over each step instead of
sampled at its end.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EVENT_AT = 300.0  # m, where harness.testroads puts the bump and the pothole
H = 1e-3


def run(road: str, kmh: float, seed: int, dist: str, case: str = "exact", acc_sampling: int = 0) -> dict:
    """One run through the FMUs; the scores of the module doc."""
    from suspension_estimation.harness import metrics
    from suspension_estimation.harness.cosim import CoSimulation, System
    from suspension_estimation.harness.studies import robust
    from suspension_estimation.harness.studies.runner import VEHICLE_KEYS
    from suspension_estimation.harness.testroads import make_road, write_profile

    params = {f"plant.{k}": v for k, v in zip(VEHICLE_KEYS, robust.plant_vehicle(case))}
    if acc_sampling:
        params["plant.acc_sampling"] = params["e.acc_sampling"] = int(acc_sampling)
    if case == robust.NONLINEAR:
        params["plant.spring_model"], params["plant.damper_model"] = robust.NONLINEAR_MODELS
        params.update({f"e.{k}": v for k, v in robust.linearisation().items()})

    s, h = make_road(road)
    d = Path(dist)
    with tempfile.TemporaryDirectory() as tmp:
        f = write_profile(Path(tmp) / f"{road}.csv", s, h)
        wires = ("acc_sprung", "acc_unsprung", "susp_deflection")
        comps = {"road": d / "ISORoad.fmu", "plant": d / "QuarterCar.fmu", "e": d / "SuspensionEstimator.fmu"}
        conn = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height"),
                ("vehicle_speed", "e.vehicle_speed")] + [(f"plant.{w}", f"e.{w}") for w in wires]
        v = kmh / 3.6
        rec_names = ["road.road_height", "road.distance", "road.iri", "e.road_height_est", "e.road_height_std",
                     "e.iri_est", "e.sprung_mass_est", "e.mass_std"]
        with CoSimulation(System(comps, conn), parameters={"road.profile_file": str(f), "plant.noise_seed": seed, **params},
                          inputs={"vehicle_speed": v, "plant.sprung_mass": 410.0}, record=rec_names) as sim:
            rec = sim.run(round((s[-1] - 1.0) / v / H) * H, H)
    t = rec["time"]
    est, std, zr = rec["e.road_height_est"], rec["e.road_height_std"], rec["road.road_height"]
    d = rec["road.distance"]
    sc = metrics.road_scores(t, est, zr, std, warmup=metrics.warmup_for(t), distance=d)
    truth = metrics.reference_profile(d, zr)
    keep = t >= t[0] + metrics.warmup_for(t)
    near = np.abs(d - EVENT_AT) < 5.0
    segs = metrics.iri_segments(d, rec["road.iri"], rec["e.iri_est"])[1:]
    iri = np.array([x[3] for x in segs]) if segs else np.array([np.nan])
    return {"case": case, "road": road, "kmh": kmh, "seed": seed, "hp": sc["err_std_hp_pct"], "cov": sc["coverage_2sigma"],
            "rms": sc["rmse_raw_mm"], "std": float(1e3 * np.sqrt(np.mean(std[keep] ** 2))),
            "event": float(1e3 * np.max(np.abs(est - truth)[near])) if road in ("bump", "pothole") else np.nan,
            "iri_mean": float(np.mean(iri)), "iri_worst": float(iri[np.argmax(np.abs(iri))]),
            "mass": float(100 * (rec["e.sprung_mass_est"][-1] / 410.0 - 1)),
            "mass_std": float(100 * rec["e.mass_std"][-1] / 410.0)}


def _seeds(text: str) -> range:
    lo, _, hi = text.partition("-")
    return range(int(lo), int(hi or lo) + 1)


def main(argv: list[str] | None = None) -> int:
    from suspension_estimation.harness.studies.robust import ALL_CASES
    from suspension_estimation.harness.testroads import TEST_ROADS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--roads", default=",".join(TEST_ROADS))
    ap.add_argument("--speeds", default="40,72", help="km/h")
    ap.add_argument("--seeds", default="1-3", help="sensor-noise seeds, a range like 1-3")
    ap.add_argument("--cases", default="exact", help="plants, comma-separated, of: " + ", ".join(ALL_CASES).replace("%", "%%"))
    ap.add_argument("--acc-sampling", type=int, choices=(0, 1), default=0,
                    help="accelerations of plant and estimator: 0 at the end of each step, 1 averaged over it")
    ap.add_argument("--dist", default=str(ROOT / "dist"))
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    roads = [r.strip() for r in a.roads.split(",")]
    cases = [c.strip() for c in a.cases.split(",")]
    if any(r not in TEST_ROADS for r in roads) or any(c not in ALL_CASES for c in cases) or a.workers < 1:
        print(f"real_roads: --roads takes names of {', '.join(TEST_ROADS)}, --cases of {', '.join(ALL_CASES)}; "
              "--workers >= 1", file=sys.stderr)
        return 2
    speeds = [float(x) for x in a.speeds.split(",")]
    jobs = [(r, k, s, a.dist, c, a.acc_sampling) for c in cases for r in roads for k in speeds
            for s in _seeds(a.seeds)]
    with ProcessPoolExecutor(a.workers) as pool:
        res = list(pool.map(run, *zip(*jobs)))
    print(f"through the FMUs, noise seeds {a.seeds}, acc_sampling {a.acc_sampling} "
          "(means; IRI worst over seeds and segments)")
    print("| plant | road | km/h | HP % | raw rms mm | std rms mm | rms err / rms std | 2σ coverage % | coverage range % | "
          "max err near event mm | IRI err mean % | IRI err worst % | mass err % | mass_std % |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for c, r, k in ((c, r, k) for c in cases for r in roads for k in speeds):
        x = [y for y in res if y["case"] == c and y["road"] == r and y["kmh"] == k]
        m = {key: float(np.mean([y[key] for y in x])) for key in x[0] if key not in ("case", "road", "kmh", "seed")}
        worst = max((y["iri_worst"] for y in x), key=abs)
        ev = "" if np.isnan(m["event"]) else f"{m['event']:.1f}"
        ratio = np.sqrt(np.mean([y["rms"] ** 2 for y in x]) / np.mean([y["std"] ** 2 for y in x]))
        cov = [100 * y["cov"] for y in x]
        print(f"| {c} | {r} | {k:g} | {m['hp']:.2f} | {m['rms']:.2f} | {m['std']:.2f} | {ratio:.2f} | "
              f"{100 * m['cov']:.1f} | {min(cov):.0f}-{max(cov):.0f} | {ev} | "
              f"{m['iri_mean']:+.2f} | {worst:+.2f} | {m['mass']:+.2f} | {m['mass_std']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
