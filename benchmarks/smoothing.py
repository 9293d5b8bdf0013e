"""The offline smoother of the default estimator (harness.smoothing.smooth_default) against the
causal default, on the cores (no FMU).

    .venv/bin/python benchmarks/smoothing.py [--classes B,C,D] [--speeds 40,80] [--plants exact,air spring]
        [--seeds 3] [--seed0 1] [--duration 60] [--workers 1] [--steady]

Plant (benchmarks/robust_cores.py's ``drive``): "exact", plant.QuarterCar with the estimator's own
nominal vehicle; "air spring", plant.NonlinearQuarterCar with the contract's air spring and
asymmetric damper (QuarterCar spring_model = damper_model = 1), the estimator told its
linearisation. ISO 8608 road seed s, sensor noise seed 1000 + s, the car at rest on the road at
t = 0, 1 ms steps. Prints one markdown row per cell, means over the seeds, scored after the 10 s
warm-up by harness.metrics.road_scores (road_height_est, the profile, against
metrics.reference_profile of the road):

- HP error % (both high-passed at 0.5 Hz) of the causal default, of the causal estimate plus
  ``reference_correction`` of its own body and road heights made a profile as smooth_default makes
  its own (``profile_of``; causal: the part of the gain that is not the smoother's), and of the
  smoothed estimate; the reduction causal -> smoothed;
- the 2-sigma coverage of the smoothed road_height_std (mean, and the lowest and highest seed) and
  of the causal one; the raw rms error (mm) of both.

``--steady``: instead, the steady-state HP error % of the smoothed output against the true profile
(frequency domain, exact vehicle, no simulation) with three choices of the model above the blend
(``steady``).
"""
from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from robust_cores import H, WARMUP, drive  # noqa: E402

from suspension_estimation.harness.metrics import road_scores  # noqa: E402
from suspension_estimation.estimators.suspension import EstimatorConfig  # noqa: E402
from suspension_estimation.harness.smoothing import profile_of, reference_correction, smooth_default  # noqa: E402

PLANTS = {"exact": "exact", "air spring": "nonlinear"}  # our names -> robust_cores' cases


def one(plant: str, cls: int, kmh: float, duration: float, seed: int) -> dict:
    t, meas, zr, told = drive(PLANTS[plant], cls, kmh / 3.6, duration, seed)
    params = {"m_s_nominal": told.m_s, "m_u": told.m_u, "k_s": told.k_s, "k_t": told.k_t, "c_s": told.c_s}
    out = smooth_default(meas[:, 0], meas[:, 1], meas[:, 2], kmh / 3.6, params, H)
    d = kmh / 3.6 * t  # m travelled at each sample
    c = road_scores(t, out["causal_road_height_est"], zr, out["causal_road_height_std"], warmup=WARMUP, distance=d)
    s = road_scores(t, out["road_height_est"], zr, out["road_height_std"], warmup=WARMUP, distance=d)
    cfg = EstimatorConfig(**params)
    rm = cfg.tuning.road_model
    fix = reference_correction(out["causal_z_s_est"], out["causal_road_height_est"], H, rm)
    corrected = out["causal_road_height_est"] + profile_of(fix, np.full(len(t), kmh / 3.6), H, cfg.profile_cutoff,
                                                           cfg.tuning.standstill_speed, (rm.f_ref, rm.zeta_ref))
    return {"causal": c["err_std_hp_pct"],
            "corrected": road_scores(t, corrected, zr, warmup=WARMUP, distance=d)["err_std_hp_pct"],
            "smoothed": s["err_std_hp_pct"], "cov": s["coverage_2sigma"], "cov_c": c["coverage_2sigma"],
            "raw_c": c["rmse_raw_mm"], "raw_s": s["rmse_raw_mm"]}


def steady(cls: int, kmh: float) -> list[float]:
    """Steady-state HP error % of the smoothed output against the true profile on the exact vehicle:
    the road through harness.smoothing._through (plant, both smoothers, blend, correction; no lag
    term), then made a profile as smooth_default makes road_height_est (the reference taken off,
    1 / reference_highpass, and the high-pass in distance, plant.profile_band.band_response at
    f / v), against that high-pass of the road, over the HP true profile's std; with the model
    above the 1 Hz blend (a) the estimator's force-error model, (b) the same with the road held over
    the step, (c) held and with the road intensity of the class (smooth_default's); below the blend
    the anchor's model, Q of class F."""
    from scipy.signal import butter, sosfreqz

    from suspension_estimation.estimators.model import DiscreteModel, ModelNoise, measurement_covariance
    from suspension_estimation.estimators.steady_state import iso_psd_time, reference_highpass
    from suspension_estimation.estimators.tuning import TUNING
    from suspension_estimation.harness.smoothing import _fixed, _through
    from suspension_estimation.plant import iso8608
    from suspension_estimation.plant.profile_band import band_response
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

    v, R, rm = kmh / 3.6, measurement_covariance(0.02, 0.2, 1e-4), TUNING.road_model
    fe = ModelNoise(q_f=TUNING.force_error_q, q_b=TUNING.force_bias_q, tau_b=TUNING.force_bias_tau)

    def fixed(q_class, noise=ModelNoise(), hold=False):
        return _fixed(DiscreteModel.build(DEFAULT_VEHICLE, v, iso8608.class_psd_n0(q_class), H, rm, noise,
                                          road_hold=hold), R)

    f = np.geomspace(1e-3, 0.999 / (2 * H), 8000)
    Sr = iso_psd_time(f, iso8608.class_psd_n0(cls), v)
    w = np.abs(sosfreqz(butter(4, 0.5, btype="highpass", fs=1 / H, output="sos"), worN=f, fs=1 / H)[1]) ** 4
    band = band_response(f / v)  # the profile's high-pass in distance, in time at v
    made = band / reference_highpass(f, rm.f_ref, rm.zeta_ref)  # smoothed road -> road_height_est
    lo, out = fixed(6), []
    for hi in (fixed(6, fe), fixed(6, fe, True), fixed(cls, fe, True)):
        o, T = _through(hi, lo, f, H, TUNING.blend_hz, rm, 0)
        noise = (np.abs(o) ** 2 * (2 * H * np.diag(R))).sum(axis=1) * np.abs(made) ** 2
        err = np.abs(made * T - band) ** 2 * Sr + noise
        out.append(float(100 * np.sqrt(np.trapezoid(w * err, f) / np.trapezoid(w * np.abs(band) ** 2 * Sr, f))))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--classes", default="B,C,D")
    ap.add_argument("--speeds", default="40,80", help="km/h")
    ap.add_argument("--plants", default=",".join(PLANTS), help=f"of {', '.join(PLANTS)}")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed0", type=int, default=1, help="first seed (default 1)")
    ap.add_argument("--duration", type=float, default=60.0, help="s (the first 10 s are not scored)")
    ap.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--steady", action="store_true", help="print the steady-state table of the models above "
                    "the blend instead (exact vehicle, no simulation)")
    a = ap.parse_args(argv)
    if a.steady:
        print("| ISO | km/h | HP % against the true profile: (a) the estimator's force-error model | "
              "(b) road held | (c) held, Q of the class |\n|---|---|---|---|---|")
        for c in a.classes.split(","):
            for v in a.speeds.split(","):
                r = steady("ABCDEFGH".index(c.strip().upper()) + 1, float(v))
                print(f"| {c.strip().upper()} | {v} | " + " | ".join(f"{x:.2f}" for x in r) + " |")
        return 0
    plants = [p.strip() for p in a.plants.split(",")]
    if any(p not in PLANTS for p in plants) or a.duration <= WARMUP or a.seeds < 1 or a.workers < 1:
        print(f"error: --plants takes {', '.join(PLANTS)}; --duration > {WARMUP} s, --seeds and --workers >= 1",
              file=sys.stderr)
        return 1
    cells = [(p, "ABCDEFGH".index(c.strip().upper()) + 1, float(v)) for c in a.classes.split(",")
             for v in a.speeds.split(",") for p in plants]
    seeds = range(a.seed0, a.seed0 + a.seeds)
    jobs = [(p, c, v, a.duration, s) for p, c, v in cells for s in seeds]
    with ProcessPoolExecutor(a.workers) as pool:
        results = list(pool.map(one, *zip(*jobs)))
    print("| ISO | km/h | plant | HP %: causal / + correction / smoothed | reduction % | coverage smoothed (seeds) | "
          "coverage causal | raw rms mm causal / smoothed |\n|---|---|---|---|---|---|---|---|")
    for i, (p, c, v) in enumerate(cells):
        r = results[i * a.seeds:(i + 1) * a.seeds]
        m = {k: float(np.mean([x[k] for x in r])) for k in r[0]}
        cov = [x["cov"] for x in r]
        print(f"| {'ABCDEFGH'[c - 1]} | {v:g} | {p} | {m['causal']:.2f} / {m['corrected']:.2f} / {m['smoothed']:.2f} | "
              f"{100 * (1 - m['smoothed'] / m['causal']):.1f} | "
              f"{m['cov']:.3f} ({min(cov):.3f}-{max(cov):.3f}) | {m['cov_c']:.3f} | "
              f"{m['raw_c']:.2f} / {m['raw_s']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
