"""The interacting-multiple-model estimator of paper 002 (``imm``): its Fig. 6 scenario through the
built FMUs, 50 s segments A / 20 m/s / 400 kg -> B / 30 / 300 -> D / 20 / 400 -> C / 10 / 500
(paper 000's vehicle, 1 ms, sensors 0.02 / 0.2 m/s^2, 0.1 mm), and two variants: the masses
25 kg off the bank's 50 kg grid (425 -> 325 -> 425 -> 525 kg), and those with the plant's damping
20 % below what every estimator is told.

One road (a profile file of the four ISO segments, one after the other at their speeds, each
shifted to start where the previous ended), one plant, one instance of each estimator fed the
same signals: the IMM (``mass_estimator`` 2, bank 250..550 kg in 50 kg steps), the moving-bank
IMM (4), the default estimator (robust KF + RLS mass) and the KF told the true mass (one
instance per distinct mass of the schedule, each scored on its own segments). Per segment: the
steady mass error (mean |error| over its last 40 %), the settling time to ±5 % after its start,
the HP road error (100 std(HP error) / std(HP road) from 2 s after the segment start; HP as in
the other studies) and the share of samples with the right online ISO class, from one
classifier window (102.4 m) after the segment start on.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from ..metrics import highpass, reference_profile
from .runner import (CLASS_LETTERS, NOMINAL_MASS, RunSpec, Study, mean_std, noise_params, simulate,
                     vehicle_params, verdict, worst)

SEGMENT = 50.0  # s
CLASSES = (1, 2, 4, 3)  # A, B, D, C
SPEEDS = (20.0, 30.0, 20.0, 10.0)  # m/s
MASSES = {"grid": (400.0, 300.0, 400.0, 500.0),  # paper 002's Fig. 6 (kg)
          "off grid": (425.0, 325.0, 425.0, 525.0),
          "off grid, c_s -20 %": (425.0, 325.0, 425.0, 525.0)}
PLANT_DAMPING = {"grid": 1.0, "off grid": 1.0, "off grid, c_s -20 %": 0.8}  # plant c_s / told c_s
KINDS = {"imm_grid": "grid", "imm_off": "off grid", "imm_damp": "off grid, c_s -20 %"}
ESTIMATORS = {  # instance -> (label, parameters)
    "IMM": ("IMM (2)", {"road_estimator": 0, "mass_estimator": 2}),
    "IMMmov": ("moving IMM (4)", {"road_estimator": 0, "mass_estimator": 4}),
    "RLS": ("default: robust KF + RLS", {}),
}
TRUE_KF = "true-mass KF"
PROFILE_DX = 0.02  # m between the profile's samples
STEADY_FRACTION = 0.4
SETTLE_BAND = 0.05
HP_SKIP = 2.0  # s after a segment start left out of its HP error
CLASS_WINDOW = 102.4  # m, the online classifier's window (estimators/road_class.py)
TARGET_STEADY, TARGET_SETTLE, TARGET_STEADY_DAMPING = 1.0, 0.5, 2.0  # %, s, %


def write_profile(path: Path, seed: int, segment: float) -> None:
    """The four ISO segments' roads at their lengths (speed x ``segment`` s), continuous."""
    from ...plant import iso8608
    from ...plant.road import SyntheticRoad

    s_all, z_all, s0, z0 = [], [], 0.0, 0.0
    for i, (c, v) in enumerate(zip(CLASSES, SPEEDS)):
        length = v * segment
        s = np.arange(0.0, length, PROFILE_DX)
        road = SyntheticRoad(iso8608.class_psd_n0(c), seed=100 * seed + i)
        z = np.array([road.height(x) for x in s])
        s_all.append(s0 + s)
        z_all.append(z - z[0] + z0)
        s0 += length
        z0 = z_all[-1][-1] + (z[-1] - z[-2])  # the next segment starts one step on
    s_all.append([s0 + 1.0])
    z_all.append([z0])
    np.savetxt(path, np.column_stack([np.concatenate(s_all), np.concatenate(z_all)]), delimiter=",",
               header="distance_m,elevation_m", fmt="%.6f,%.9e")


def _run(spec: RunSpec, variant: str) -> dict:
    from ..cosim import System
    from ..scenario import Profile

    seg = spec.duration / len(CLASSES)
    masses = MASSES[variant]
    starts = np.arange(len(CLASSES)) * seg
    true_kfs = {m: f"KFtrue{int(m)}" for m in sorted(set(masses))}
    names = list(ESTIMATORS) + list(true_kfs.values())
    comps = {"ISORoad": Path(spec.dist) / "ISORoad.fmu", "QuarterCar": Path(spec.dist) / "QuarterCar.fmu"}
    conns = [("vehicle_speed", "ISORoad.vehicle_speed"), ("ISORoad.road_height", "QuarterCar.road_height")]
    for n in names:
        comps[n] = Path(spec.dist) / "SuspensionEstimator.fmu"
        conns.append(("vehicle_speed", f"{n}.vehicle_speed"))
        conns += [(f"QuarterCar.{v}", f"{n}.{v}") for v in ("acc_sprung", "acc_unsprung", "susp_deflection")]
    veh = vehicle_params(spec)
    with tempfile.TemporaryDirectory() as tmp:
        prof = Path(tmp) / "fig6_road.csv"
        write_profile(prof, spec.seed, seg)
        params = {"ISORoad.profile_file": str(prof), "ISORoad.profile_end": 1,
                  "QuarterCar.noise_seed": 1000 + spec.seed}
        params.update({f"QuarterCar.{k}": v for k, v in {**veh, **noise_params(spec)}.items()})
        params["QuarterCar.c_s"] = veh["c_s"] * PLANT_DAMPING[variant]
        common = {**veh, **noise_params(spec), "road_class": 0, "m_s_nominal": NOMINAL_MASS}
        for n, (_, p) in ESTIMATORS.items():
            params.update({f"{n}.{k}": v for k, v in {**common, **p}.items()})
        for m, n in true_kfs.items():
            params.update({f"{n}.{k}": v for k, v in {**common, "road_estimator": 0, "mass_estimator": 0,
                                                      "m_s_nominal": m}.items()})
        record = ["ISORoad.road_height", "ISORoad.distance", "QuarterCar.sprung_mass"] + [
            f"{n}.{v}" for n in names for v in ("road_height_est", "sprung_mass_est", "road_class_est")]
        inputs = {"vehicle_speed": Profile(starts, np.array(SPEEDS), "step"),
                  "QuarterCar.sprung_mass": Profile(starts, np.array(masses), "step")}
        r, timing = simulate(System(comps, conns, name="imm"), params, inputs, record, spec, spec.duration)
    t = r["time"]
    truth_hp = highpass(reference_profile(r["ISORoad.distance"], r["ISORoad.road_height"]), spec.step)
    out: dict = {"timing": timing, "variant": variant, "segment_s": seg, "estimators": {}}
    rows = {n: (lab, n) for n, (lab, _) in ESTIMATORS.items()}
    for n, (label, inst) in {**rows, TRUE_KF: (TRUE_KF, None)}.items():
        segs = []
        for i, a in enumerate(starts):
            b = a + seg
            inst_i = inst or true_kfs[masses[i]]
            sel = (t > a + 1e-9) & (t <= b + 1e-9)
            m_true = masses[i]
            err = 100 * (r[f"{inst_i}.sprung_mass_est"][sel] - m_true) / m_true
            ts = t[sel]
            bad = np.nonzero(np.abs(err) > 100 * SETTLE_BAND)[0]
            hp = sel & (t > a + min(HP_SKIP, 0.25 * seg))
            e_hp = highpass(r[f"{inst_i}.road_height_est"], spec.step)[hp] - truth_hp[hp]
            cls = r[f"{inst_i}.road_class_est"]
            after = sel & (t > a + CLASS_WINDOW / SPEEDS[i])
            segs.append({"steady_pct": float(np.mean(np.abs(err[ts > b - STEADY_FRACTION * seg]))),
                         "settle_s": float(ts[bad[-1]] - a) if len(bad) else 0.0,
                         "hp_pct": float(100 * np.std(e_hp) / np.std(truth_hp[hp])),
                         "class_right": float(np.mean(cls[after] == CLASSES[i])) if after.any() else float("nan")})
        out["estimators"][label] = segs
    return out


def run_grid(spec: RunSpec) -> dict:
    return _run(spec, "grid")


def run_off(spec: RunSpec) -> dict:
    return _run(spec, "off grid")


def run_damp(spec: RunSpec) -> dict:
    return _run(spec, "off grid, c_s -20 %")


class IMMStudy(Study):
    name = "imm"
    runs = {"imm_grid": run_grid, "imm_off": run_off, "imm_damp": run_damp}

    def specs(self, suite) -> list[RunSpec]:
        d = str(Path(suite.dist).resolve())
        return [RunSpec(kind, 3, s, SEGMENT * len(CLASSES), 0.0, suite.step, d)
                for kind in KINDS for s in range(1, suite.seeds + 1)]

    def _by(self, suite, kind):
        return suite.ok(kind)

    def markdown(self, suite) -> list[str]:
        lines = ["## IMM of paper 002: its Fig. 6 scenario, on and off the bank's grid", "",
                 f"{SEGMENT:g} s segments " + " → ".join(
                     f"{CLASS_LETTERS[c - 1]} / {v:g} m/s" for c, v in zip(CLASSES, SPEEDS))
                 + f", seeds 1..{suite.seeds}, {1e3 * suite.step:g} ms; the estimators start at {NOMINAL_MASS:g} kg. "
                 "Steady = mean |mass error| over the last 40 % of a segment; settling = last time outside ±5 % "
                 "after its start (the first segment's from the start of the run at 410 kg); "
                 f"HP = 100 std(HP road error) / std(HP road) from {HP_SKIP:g} s after its start; class = share of "
                 "samples at the segment's class from one classifier window after its start. Mean over seeds "
                 "(worst in brackets).", ""]
        for kind, variant in KINDS.items():
            runs = self._by(suite, kind)
            if not runs:
                continue
            masses = MASSES[variant]
            lines += [f"### {variant}: " + " → ".join(f"{m:g} kg" for m in masses), "",
                      "| segment | estimator | steady mass error % | settling s | HP road error % | class right % |",
                      "|---|---|---|---|---|---|"]
            labels = list(runs[0]["estimators"])
            for i in range(len(CLASSES)):
                for lab in labels:
                    v = np.array([[r["estimators"][lab][i][k] for k in ("steady_pct", "settle_s", "hp_pct",
                                                                         "class_right")] for r in runs], float)
                    mass_cols = ("–", "–") if lab == TRUE_KF else (
                        f"{v[:, 0].mean():.2f} ({v[:, 0].max():.2f})", f"{v[:, 1].mean():.2f} ({v[:, 1].max():.2f})")
                    cr = v[:, 3][np.isfinite(v[:, 3])]
                    cls = f"{100 * cr.mean():.1f} ({100 * cr.min():.1f})" if len(cr) else "–"
                    lines.append(f"| {CLASS_LETTERS[CLASSES[i] - 1]} / {SPEEDS[i]:g} m/s / {masses[i]:g} kg | {lab} | "
                                 f"{mass_cols[0]} | {mass_cols[1]} | {v[:, 2].mean():.2f} ({v[:, 2].max():.2f}) | {cls} |")
            lines.append("")
        return lines

    def targets(self, suite) -> list[tuple[str, str, str]]:
        out = []
        for kind, variant in KINDS.items():
            runs = self._by(suite, kind)
            target = TARGET_STEADY_DAMPING if "c_s" in variant else TARGET_STEADY
            for lab in ("IMM (2)", "moving IMM (4)", "default: robust KF + RLS"):
                segs = [s for r in runs for s in r["estimators"].get(lab, [])]
                if not segs:
                    continue
                st = np.array([s["steady_pct"] for s in segs])
                # settling after each payload step: the first segment starts the run (its
                # settling from m_s_nominal is in the table, not a target)
                se = np.array([s["settle_s"] for r in runs for s in r["estimators"][lab][1:]])
                ok = bool(np.all(st <= target) and np.all(se <= TARGET_SETTLE))
                out.append((f"{lab}, {variant}: steady mass error ≤ {target:g} % in every segment and settling "
                            f"≤ {TARGET_SETTLE:g} s after each step", verdict(ok),
                            f"steady {mean_std(st)} %, worst {worst(st)} %; settling after the steps worst "
                            f"{worst(se)} s ({len(segs)} segments)"))
        return out


IMM = IMMStudy()
