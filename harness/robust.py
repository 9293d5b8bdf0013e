"""Robustness study (``python -m harness paper --study robust``): road and mass estimates when the
plant is NOT the estimators' model.

The plant (QuarterCar FMU) gets the contract's default vehicle with one parameter off (c_s +-30 %,
k_s +-15 %, k_t +-10 %, m_u +-15 %), all four together (both signs), or nothing; every estimator
instance is told the default vehicle, except ``KF_exact``, the exact-model KF told the plant's own
vehicle and sprung mass (the reference of what a perfectly known vehicle gives). ISO classes B, C,
D at 40 and 80 km/h, one road and one plant per run feeding all estimators. Scores per cell (mean
over seeds): HP and raw road error std %, in-band gain, 2-sigma coverage of the raw error, mean
sprung-mass error % after the warm-up. Targets (``TARGETS``) are marked PASS/MISS for the default.
"""
from __future__ import annotations

import json
import time
from concurrent.futures import as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .paper import (DIST, NOMINAL_MASS, PAPER000_VEHICLE, ROOT, VEHICLE_KEYS, Estimator, RunSpec, process_pool,
                    run_one)

OUT = ROOT / "results" / "robust"
NOMINAL = dict(zip(VEHICLE_KEYS, PAPER000_VEHICLE))  # what the estimators are told
# case name -> plant factors on the nominal vehicle
CASES: dict[str, dict[str, float]] = {
    "exact": {},
    "c_s -30%": {"c_s": 0.7}, "c_s +30%": {"c_s": 1.3},
    "k_s -15%": {"k_s": 0.85}, "k_s +15%": {"k_s": 1.15},
    "k_t -10%": {"k_t": 0.9}, "k_t +10%": {"k_t": 1.1},
    "m_u -15%": {"m_u": 0.85}, "m_u +15%": {"m_u": 1.15},
    "all +": {"c_s": 1.3, "k_s": 1.15, "k_t": 1.1, "m_u": 1.15},
    "all -": {"c_s": 0.7, "k_s": 0.85, "k_t": 0.9, "m_u": 0.85},
}
ESTIMATORS = (
    Estimator("default", "default", dict(NOMINAL)),
    Estimator("KF_nominal", "KF (road_estimator 0)", {**NOMINAL, "road_estimator": 0}),
    Estimator("KF_exact", "KF told the exact vehicle", {"road_estimator": 0, "mass_estimator": 0}, true_mass=True),
)
SPEEDS = (40 / 3.6, 80 / 3.6)  # m/s
METRICS = ("err_std_hp_pct", "err_std_raw_pct", "gain_hp", "coverage_2sigma", "mass_err_mean_pct")
# issue 11 point 3
HP_RATIO = 1.5  # HP error within this factor of the default's own on the exact vehicle
HP_MAX_C40 = 4.0  # %, ISO C at 40 km/h
GAIN = (0.9, 1.1)
COVERAGE = (0.90, 0.99)
MASS_OK = 2.0  # %, k_s right
MASS_SLACK = 1.0  # %, added to the k_s error
EXACT_LOSS = 1.10  # the default against the exact-model KF on the exact vehicle


def plant_vehicle(case: str) -> tuple[float, float, float, float]:
    """(m_u, k_s, k_t, c_s) of the plant in ``case``."""
    f = CASES[case]
    return tuple(NOMINAL[k] * f.get(k, 1.0) for k in VEHICLE_KEYS)


def mass_bound(case: str) -> float:
    """Allowed |mass error| (%): the estimate is only as right as k_s (the body equation gives
    k_s / m_s), so a model k_s that is off by x % relative to the plant's allows x % + 1 %."""
    f = CASES[case].get("k_s", 1.0)
    return MASS_OK if f == 1.0 else 100 * abs(1.0 / f - 1.0) + MASS_SLACK


@dataclass
class RobustStudy:
    seeds: int = 10
    duration: float = 60.0
    warmup: float = 10.0
    step: float = 1e-3
    classes: tuple[int, ...] = (2, 3, 4)
    speeds: tuple[float, ...] = SPEEDS
    cases: tuple[str, ...] = tuple(CASES)
    workers: int = 2
    dist: Path = DIST
    out: Path = OUT

    def check(self) -> None:
        if self.seeds < 1 or self.workers < 1:
            raise ValueError("--seeds and --workers must be >= 1")
        if not 0 <= self.warmup < self.duration:
            raise ValueError(f"--warmup = {self.warmup} s must be in [0, --duration = {self.duration} s)")
        unknown = [c for c in self.cases if c not in CASES]
        if unknown:
            raise ValueError(f"unknown robustness cases {unknown}; known: {list(CASES)}")
        for f in ("ISORoad.fmu", "QuarterCar.fmu", "SuspensionEstimator.fmu"):
            if not (Path(self.dist) / f).is_file():
                raise FileNotFoundError(f"{Path(self.dist) / f} does not exist (build it: .venv/bin/python build.py)")

    def specs(self) -> list[tuple[str, RunSpec]]:
        d = str(Path(self.dist).resolve())
        return [(case, RunSpec(f"robust {case} {3.6 * u:g} km/h", c, s, self.duration, self.warmup, self.step, d,
                               vehicle=plant_vehicle(case), speed=u, mass=NOMINAL_MASS))
                for case in self.cases for c in self.classes for u in self.speeds
                for s in range(1, self.seeds + 1)]

    def run(self, progress: bool = True) -> list[dict]:
        """Every run in ``workers`` processes; rows of (case, class, speed, seed, estimator, metrics)."""
        self.check()
        specs = self.specs()
        rows, t0 = [], time.perf_counter()
        with process_pool(self.workers) as ex:
            futs = {ex.submit(run_one, spec, ESTIMATORS): (case, spec) for case, spec in specs}
            for i, f in enumerate(as_completed(futs), 1):
                case, spec = futs[f]
                res = f.result()
                if progress:
                    print(f"[{i}/{len(specs)}] {spec.name} ISO {'ABCDEFGH'[spec.road_class - 1]} seed {spec.seed}"
                          f"{'' if res['ok'] else ': FAILED ' + res['error']}", flush=True)
                for inst, sc in (res.get("estimators") or {}).items():
                    rows.append({"case": case, "class": spec.road_class, "speed_kmh": round(3.6 * spec.speed),
                                 "seed": spec.seed, "estimator": inst, **{m: sc[m] for m in METRICS}})
                if not res["ok"]:
                    rows.append({"case": case, "class": spec.road_class, "speed_kmh": round(3.6 * spec.speed),
                                 "seed": spec.seed, "estimator": None, "error": res["error"]})
        self.wall_s = time.perf_counter() - t0
        self.rows = rows
        return rows

    def cell(self, case: str, cls: int, kmh: int, inst: str, metric: str) -> float:
        v = [r[metric] for r in self.rows if r.get("estimator") == inst and r["case"] == case
             and r["class"] == cls and r["speed_kmh"] == kmh]
        return float(np.mean(v)) if v else float("nan")

    def verdicts(self, case: str, cls: int, kmh: int) -> dict[str, bool]:
        """PASS (True) / MISS per target of the default in one cell."""
        c = lambda inst, m, k=case: self.cell(k, cls, kmh, inst, m)  # noqa: E731
        hp, hp0 = c("default", "err_std_hp_pct"), c("default", "err_std_hp_pct", "exact")
        v = {"hp": hp <= HP_RATIO * hp0 and (hp <= HP_MAX_C40 or (cls, kmh) != (3, 40)),
             "gain": GAIN[0] <= c("default", "gain_hp") <= GAIN[1],
             "coverage": COVERAGE[0] <= c("default", "coverage_2sigma") <= COVERAGE[1],
             "mass": abs(c("default", "mass_err_mean_pct")) <= mass_bound(case)}
        if case == "exact":
            v["vs exact KF"] = hp <= EXACT_LOSS * c("KF_exact", "err_std_hp_pct")
        return v

    def markdown(self) -> str:
        lines = [f"Robustness: {self.seeds} seed(s), {self.duration:g} s runs, {self.warmup:g} s warm-up, "
                 f"step {self.step:g} s; mean over seeds. HP / raw road error std %, in-band gain, 2-sigma "
                 f"coverage, mean sprung-mass error %. Targets of the default: HP <= {HP_RATIO} x its exact-vehicle "
                 f"HP (and <= {HP_MAX_C40} % on ISO C at 40 km/h), gain {GAIN[0]}-{GAIN[1]}, coverage "
                 f"{COVERAGE[0]}-{COVERAGE[1]}, |mass error| <= {MASS_OK} % (k_s right) or the k_s error + "
                 f"{MASS_SLACK} %; on the exact vehicle HP <= {EXACT_LOSS} x the exact KF's.", "",
                 "| ISO | km/h | plant | default HP | raw | gain | cov | mass % | KF(0) HP | KF(0) mass % "
                 "| KF exact HP | MISS |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for cls in self.classes:
            for u in self.speeds:
                kmh = round(3.6 * u)
                for case in self.cases:
                    c = lambda inst, m: self.cell(case, cls, kmh, inst, m)  # noqa: E731
                    miss = [k for k, ok in self.verdicts(case, cls, kmh).items() if not ok]
                    lines.append(
                        f"| {'ABCDEFGH'[cls - 1]} | {kmh} | {case} | {c('default', 'err_std_hp_pct'):.2f} | "
                        f"{c('default', 'err_std_raw_pct'):.1f} | {c('default', 'gain_hp'):.3f} | "
                        f"{c('default', 'coverage_2sigma'):.3f} | {c('default', 'mass_err_mean_pct'):+.2f} | "
                        f"{c('KF_nominal', 'err_std_hp_pct'):.2f} | {c('KF_nominal', 'mass_err_mean_pct'):+.2f} | "
                        f"{c('KF_exact', 'err_std_hp_pct'):.2f} | {', '.join(miss) or 'PASS'} |")
        return "\n".join(lines) + "\n"

    def plot(self, path: Path) -> Path:
        """HP road error against the plant's parameter offset (single-parameter cases, ISO C where
        run, else the first class; each speed), default and KF (road_estimator 0)."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        cls = 3 if 3 in self.classes else self.classes[0]
        fig, axes = plt.subplots(1, len(self.speeds), figsize=(5 * len(self.speeds), 3.8), squeeze=False)
        for ax, u in zip(axes[0], self.speeds):
            kmh = round(3.6 * u)
            for par, color in zip(VEHICLE_KEYS, ("C0", "C1", "C2", "C3")):
                pts = sorted((100 * (f[par] - 1), case) for case, f in CASES.items()
                             if list(f) == [par] and case in self.cases)
                pts = [(0.0, "exact")] + pts if "exact" in self.cases else pts
                pts.sort()
                x = [p for p, _ in pts]
                for inst, ls in (("default", "-"), ("KF_nominal", ":")):
                    ax.plot(x, [self.cell(k, cls, kmh, inst, "err_std_hp_pct") for _, k in pts], ls, color=color,
                            marker="o", label=f"{par} {'default' if inst == 'default' else 'KF (0)'}")
            ax.set(title=f"ISO {'ABCDEFGH'[cls - 1]}, {kmh} km/h", xlabel="plant parameter offset from the model, %",
                   ylabel="HP road error std, %", yscale="log")
            ax.grid(True, which="both", alpha=0.3)
        axes[0][0].legend(fontsize=7, ncol=2)
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return path

    def write(self) -> list[Path]:
        out = Path(self.out)
        out.mkdir(parents=True, exist_ok=True)
        files = [out / "robust.json", out / "robust.md"]
        files[0].write_text(json.dumps({"study": {k: (str(v) if isinstance(v, Path) else v)
                                                  for k, v in asdict(self).items()}, "rows": self.rows}, indent=1))
        files[1].write_text(self.markdown())
        files.append(self.plot(out / "robust_hp_vs_offset.png"))
        return files

    def failures(self) -> list[dict]:
        return [r for r in self.rows if r.get("estimator") is None]
