"""Real sensors (``python -m suspension_estimation.harness paper --study sensors``): road and mass estimates when
the plant's sensors have the errors of plant/sensors.py, and when the log is sampled at 200 or 100 Hz.

The plant (QuarterCar FMU) gets one sensor error at the end of its range (``ERRORS``: deflection
offset +-5 mm, body (sprung) accelerometer bias +-0.1 m/s2, wheel (unsprung) accelerometer bias
+-0.5 m/s2, either accelerometer's gain 1.03 and 0.97, the wheel acceleration or the deflection
2 ms late), all of them together, or none (``ideal``). One road and one plant per run feed two
SuspensionEstimator instances: ``default`` (road_estimator 2, the contract's defaults otherwise),
not told the errors, and ``told``, the same told the plant's eight sensor-error values as the
known calibration it removes (what a user who measured them would set). On ideal sensors the two
are the same estimator and run once (``default``).

Logging rate (``LOGGING``): ideal sensors, road and plant stepped at ``--step`` (1 ms by default)
with the road moving linearly over the step (QuarterCar ``road_input`` 1: a held road is a
staircase whose steps the tyre reads as impulses), the estimators stepped every 1, 5 or 10 ms on
the plant's outputs then (CoSimulation ``rates``: point samples, as a logger at 1 kHz, 200 or 100
Hz without an anti-alias filter gives) and scored at their own steps; 200 and 100 Hz against
``1 kHz logging``, their reference. (Stepping the whole co-simulation at the logging step with
the accelerations averaged over it would measure the averaged-sensor model on a plant that is
that model: a road held over each step.) The sensor-error cases run at ``--step`` with the road
held.

Plants (``PLANTS``): the contract's linear vehicle, told exactly, and the air spring with the
asymmetric damper (QuarterCar ``spring_model`` = ``damper_model`` = 1), the estimators told its
linearisation at the static point as in the robust study (``robust.linearisation``). ISO classes
(--classes) at 40 and 80 km/h (--speeds), seeds 1..--seeds (road seed i, noise seed 1000 + i).

Scores per run and estimator after the warm-up (``harness.metrics.road_scores``): HP road error
std %, the rms error (mm) of road_height_est against ``harness.metrics.reference_profile`` and the
coverage of +-2 road_height_std; the sprung-mass error % (mean, and the largest |error| at
any instant); the largest status seen over the run. Estimates of a told delay refer to the time
of the largest lag ago (the contract); they are scored, as every run, against the truth at the
step's time.

Targets (reported, never tuned): HP and mass judged on every seed of a cell (the cell's worst seed,
as each compares a run with the same seed's reference run), the coverage over the cell's seeds
together (one seed's realised band error alone is 0.6-1.35x its std: ten roads,
docs/real-sensors.md):

- HP road error <= ``HP_RATIO`` x that of the same run (plant, class, speed, seed) on ideal
  sensors; at 200 / 100 Hz <= the ratio of ``LOGGING`` x that of the ``1 kHz logging`` run;
- coverage of the profile's error by +-2 road_height_std in ``COVERAGE`` (the error in the
  distance band);
- the sprung-mass estimate (its mean after the warm-up) within ``MASS_OK`` % of that of the ideal
  run (the 1 kHz logging run at 200 / 100 Hz); where the body accelerometer's gain is off and the
  estimator is not told (``default``), within that error + ``MASS_SLACK`` %: the body equation
  gives the mass as force over acceleration.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ...plant.sensors import SensorErrors
from ..metrics import mass_error_pct, road_scores
from .runner import (CLASS_LETTERS, NOMINAL_MASS, PAPER000_VEHICLE, SENSOR_ERROR_KEYS, Estimator, RunSpec, Study,
                     build_system, noise_params, plant_params, simulate, vehicle_params, verdict, whole_steps)

KIND = "sensors"  # RunSpec.study of its runs
IDEAL = "ideal"
ONE_KHZ = "1 kHz logging"
NONE = asdict(SensorErrors())  # no error: the plant's defaults
# case -> the plant's sensor errors (m, m/s2, 1, s; the others none)
ERRORS: dict[str, dict[str, float]] = {
    IDEAL: {},
    "deflection +5 mm": {"deflection_offset": 0.005},
    "deflection -5 mm": {"deflection_offset": -0.005},
    "body acc bias +0.1 m/s2": {"acc_sprung_bias": 0.1},
    "body acc bias -0.1 m/s2": {"acc_sprung_bias": -0.1},
    "wheel acc bias +0.5 m/s2": {"acc_unsprung_bias": 0.5},
    "wheel acc bias -0.5 m/s2": {"acc_unsprung_bias": -0.5},
    "body acc scale 1.03": {"acc_sprung_scale": 1.03},
    "body acc scale 0.97": {"acc_sprung_scale": 0.97},
    "wheel acc scale 1.03": {"acc_unsprung_scale": 1.03},
    "wheel acc scale 0.97": {"acc_unsprung_scale": 0.97},
    "wheel acc 2 ms late": {"acc_unsprung_delay": 0.002},
    "deflection 2 ms late": {"deflection_delay": 0.002},
    "all together": {"deflection_offset": 0.005, "acc_sprung_bias": 0.1, "acc_unsprung_bias": 0.5,
                     "acc_sprung_scale": 1.03, "acc_unsprung_scale": 1.03, "acc_unsprung_delay": 0.002},
}
# case -> (the estimators' step s, HP ratio allowed against ONE_KHZ; None: judged against IDEAL);
# ideal sensors, the plant at --step with the road moving linearly over it
LOGGING: dict[str, tuple[float, float | None]] = {
    ONE_KHZ: (0.001, None),
    "200 Hz logging": (0.005, 1.1),
    "100 Hz logging": (0.010, 1.5),
}
CASES = (*ERRORS, *LOGGING)
PLANTS: dict[str, tuple[int, int]] = {"linear": (0, 0), "air spring": (1, 1)}  # QuarterCar spring_model, damper_model
SPEEDS_KMH = (40.0, 80.0)
DEFAULT = {"road_estimator": 2}  # the contract's defaults otherwise (mass_estimator 1, mass feedback)
# targets
HP_RATIO = 1.2
COVERAGE = (0.90, 0.99)
MASS_OK = 1.0  # %
MASS_SLACK = 0.5  # %, added to the body accelerometer's gain error when the estimator is not told it
METRICS = ("err_std_hp_pct", "rmse_raw_mm", "coverage_2sigma", "mass_err_mean_pct", "mass_err_max_abs_pct", "status_max")


def errors_of(case: str) -> tuple[float, ...]:
    """RunSpec.sensor_errors of ``case``: () without errors, else all eight values of
    SENSOR_ERROR_KEYS."""
    e = ERRORS.get(case, {})
    return tuple(float({**NONE, **e}[k]) for k in SENSOR_ERROR_KEYS) if e else ()


def log_every(case: str, step: float) -> int:
    """The estimators' steps in plant steps of ``step`` s in ``case`` (1 outside ``LOGGING``)."""
    return round(LOGGING[case][0] / step) if case in LOGGING else 1


def case_of(spec: dict) -> str:
    """The case of a run's spec (``asdict(RunSpec)``)."""
    if spec.get("road_input", 0):
        return next(c for c, (h, _) in LOGGING.items()
                    if math.isclose(spec["step"] * spec.get("log_every", 1), h, rel_tol=1e-9))
    errs = tuple(map(float, spec["sensor_errors"]))
    return next(c for c in ERRORS if errors_of(c) == errs)


def plant_of(spec: dict) -> str:
    return next(p for p, m in PLANTS.items() if tuple(spec["plant_models"]) == m)


def estimators_for(spec: RunSpec) -> tuple[Estimator, ...]:
    """``default`` (told the linearisation on the air-spring plant) and, when the plant's sensors
    have errors, ``told``: the same told them, and so with no allowance for calibration errors
    in its std (calibration_gain_std = calibration_delay_std = 0)."""
    told_vehicle = {}
    if tuple(spec.plant_models) != PLANTS["linear"]:
        from .robust import linearisation

        told_vehicle = linearisation()
    default = Estimator("default", "default", {**DEFAULT, **told_vehicle})
    if not spec.sensor_errors:
        return (default,)
    calibration = dict(zip(SENSOR_ERROR_KEYS, map(float, spec.sensor_errors)))
    calibration.update(calibration_gain_std=0.0, calibration_delay_std=0.0)
    return default, Estimator("told", "told", {**default.parameters, **calibration})


def told_lag(e: Estimator) -> float:
    """s: the largest delay ``e`` is told, the age of its estimates (the contract)."""
    return max(float(e.parameters.get(k, 0.0)) for k in ("acc_sprung_delay", "acc_unsprung_delay", "deflection_delay"))


def run(spec: RunSpec) -> dict:
    """One run: one road and one plant (its sensor errors from ``spec``) feeding the estimators of
    ``estimators_for``; scores per instance in ``["estimators"]``: those of ``road_scores``, the
    mean and the largest |sprung-mass error| % after the warm-up, the largest status over the run
    and the number of non-zero ones; for an instance told a delay also ``err_std_hp_pct_at_lag``,
    its HP error against the truth of the largest told delay ago (for information: the targets
    score every estimate against the truth at the step's time)."""
    estimators = estimators_for(spec)
    names = [e.instance for e in estimators]
    params = plant_params(spec)
    for e in estimators:
        p = {**vehicle_params(spec), **noise_params(spec), "road_class": 0, "acc_sampling": spec.acc_sampling,
             "m_s_nominal": spec.nominal_mass, **e.parameters}
        params.update({f"{e.instance}.{k}": v for k, v in p.items()})
    record = ["ISORoad.road_height", "ISORoad.distance"] + [f"{n}.{v}" for n in names for v in (
        "road_height_est", "road_height_std", "sprung_mass_est", "status")]
    r, timing = simulate(build_system(Path(spec.dist), names), params,
                         {"vehicle_speed": spec.speed, "QuarterCar.sprung_mass": spec.mass}, record, spec,
                         spec.duration, rates={n: spec.log_every for n in names})
    r = r[::spec.log_every]  # the estimators' own steps (their outputs hold in between)
    t, truth = r["time"], r["ISORoad.road_height"]
    scored = t >= t[0] + spec.warmup
    out: dict = {"timing": timing, "estimators": {}}
    for n in names:
        # at the contract's default profile_cutoff
        s = road_scores(t, r[f"{n}.road_height_est"], truth, r[f"{n}.road_height_std"], warmup=spec.warmup,
                        distance=r["ISORoad.distance"])
        m = mass_error_pct(r[f"{n}.sprung_mass_est"][scored], spec.mass)
        s["mass_err_mean_pct"] = float(np.mean(m))
        s["mass_err_max_abs_pct"] = float(np.max(np.abs(m)))
        status = r[f"{n}.status"][1:]
        s["status_max"] = int(np.max(status)) if len(status) else 0
        s["status_nonzero"] = int(np.count_nonzero(status))
        lag = told_lag(estimators[names.index(n)])
        if lag > 0:  # for information: against the truth of the time the estimates refer to
            at_lag = np.interp(t - lag, t, truth)
            s["err_std_hp_pct_at_lag"] = road_scores(t, r[f"{n}.road_height_est"], at_lag, warmup=spec.warmup,
                                                     distance=r["ISORoad.distance"])["err_std_hp_pct"]
        out["estimators"][n] = s
    return out


def _mass_off_pct(e: float, e_ref: float) -> float:
    """The mass estimate against the reference's (%), from their errors against the truth (%)."""
    return 100 * ((1 + e / 100) / (1 + e_ref / 100) - 1)


def _worst(v: np.ndarray, metric: str) -> float:
    """The worst seed's value: the largest, the farthest from the middle of the coverage band, the
    largest in magnitude (signed) for the mean mass error."""
    if metric == "coverage_2sigma":
        return float(v[np.argmax(np.abs(v - sum(COVERAGE) / 2))])
    if metric == "mass_err_mean_pct":
        return float(v[np.argmax(np.abs(v))])
    return float(np.max(v))


class Sensors(Study):
    """The study over ``cases`` and ``plants`` (all by default; a test may take fewer)."""

    name = KIND
    runs = {KIND: run}
    defaults = {"seeds": 2, "duration": 30.0, "classes": (3,), "speeds": (40.0,)}

    def __init__(self, cases: Sequence[str] = CASES, plants: Sequence[str] = tuple(PLANTS)):
        unknown = [c for c in cases if c not in CASES] + [p for p in plants if p not in PLANTS]
        if unknown:
            raise ValueError(f"sensors: unknown case or plant {unknown}")
        self.cases, self.plants = tuple(cases), tuple(plants)

    @staticmethod
    def kmh(suite) -> tuple[float, ...]:
        """km/h of the runs."""
        return tuple(getattr(suite, "speeds", ()) or SPEEDS_KMH)

    def check(self, suite) -> None:
        for c in self.cases:
            h = LOGGING[c][0] if c in LOGGING else suite.step
            if c in LOGGING and not whole_steps(h, suite.step):
                raise ValueError(f"--step = {suite.step} s does not divide the {1e3 * h:g} ms of the sensors study's "
                                 f"case {c!r}")
            if not whole_steps(suite.duration, h):
                raise ValueError(f"--duration = {suite.duration} s is not a whole number of the {1e3 * h:g} ms steps "
                                 f"of the sensors study's case {c!r}")

    def specs(self, suite) -> list[RunSpec]:
        d = str(Path(suite.dist).resolve())
        return [RunSpec(KIND, c, s, suite.duration, suite.warmup, suite.step, d, mass=NOMINAL_MASS,
                        vehicle=PAPER000_VEHICLE, speed=u / 3.6, plant_models=PLANTS[plant],
                        sensor_errors=errors_of(case), log_every=log_every(case, suite.step),
                        road_input=int(case in LOGGING))
                for plant in self.plants for c in suite.classes for u in self.kmh(suite) for case in self.cases
                for s in range(1, suite.seeds + 1)]

    # -- cells ------------------------------------------------------------------------------------
    @staticmethod
    def runs_by_cell(suite) -> dict[tuple, dict[int, dict]]:
        """(plant, class, km/h, case) -> seed -> the estimators' scores of that run."""
        out: dict[tuple, dict[int, dict]] = {}
        for r in suite.ok(KIND):
            s = r["spec"]
            key = (plant_of(s), s["road_class"], round(3.6 * s["speed"]), case_of(s))
            out.setdefault(key, {})[s["seed"]] = r["estimators"]
        return out

    @staticmethod
    def rows(case: str) -> tuple[str, ...]:
        """The estimator instances of a case's rows."""
        return ("default", "told") if errors_of(case) else ("default",)

    @staticmethod
    def reference(case: str) -> str:
        """The case the targets of ``case`` compare with."""
        return ONE_KHZ if case in LOGGING and case != ONE_KHZ else IDEAL

    @staticmethod
    def mass_bound(case: str, inst: str) -> float:
        """Allowed |mass off its reference| (%) of ``inst`` in ``case``."""
        scale = {**NONE, **ERRORS.get(case, {})}["acc_sprung_scale"]
        return MASS_OK if inst == "told" or scale == 1.0 else 100 * abs(scale - 1) + MASS_SLACK

    def verdicts(self, cells: dict, plant: str, cls: int, kmh: int, case: str, inst: str) -> dict[str, bool | None]:
        """PASS (True) / MISS / None (nothing to judge) per target of ``inst`` in one cell, on every
        seed that has its reference run."""
        runs, ref = cells.get((plant, cls, kmh, case), {}), cells.get((plant, cls, kmh, self.reference(case)), {})
        pairs = [(runs[s][inst], ref[s]["default"]) for s in runs if s in ref and inst in runs[s]]
        ratio = LOGGING[case][1] if case in LOGGING and case != ONE_KHZ else HP_RATIO
        hp = [e["err_std_hp_pct"] <= ratio * r["err_std_hp_pct"] for e, r in pairs]
        mass = [abs(_mass_off_pct(e["mass_err_mean_pct"], r["mass_err_mean_pct"])) <= self.mass_bound(case, inst)
                for e, r in pairs]
        seeds = [runs[s][inst]["coverage_2sigma"] for s in runs if inst in runs[s]]
        cov = [COVERAGE[0] <= float(np.mean(seeds)) <= COVERAGE[1]] if seeds else []
        return {k: (all(v) if v else None) for k, v in (("hp", hp), ("coverage", cov), ("mass", mass))}

    def values(self, cells: dict, plant: str, cls: int, kmh: int, case: str, inst: str) -> dict[str, tuple]:
        """metric -> (mean over seeds, the worst seed) of ``inst`` in one cell; also ``hp_ratio``,
        the HP error over that of the reference run of the same seed."""
        runs, ref = cells.get((plant, cls, kmh, case), {}), cells.get((plant, cls, kmh, self.reference(case)), {})
        out = {}
        for m in (*METRICS, "hp_ratio"):
            if m == "hp_ratio":
                v = [runs[s][inst]["err_std_hp_pct"] / ref[s]["default"]["err_std_hp_pct"]
                     for s in runs if s in ref and inst in runs[s]]
            else:
                v = [runs[s][inst][m] for s in runs if inst in runs[s]]
            v = np.asarray(v, float)
            out[m] = (float(np.mean(v)), _worst(v, m)) if len(v) else (math.nan, math.nan)
        return out

    def grid(self, suite) -> list[tuple[str, int, int, str, str]]:
        """(plant, class, km/h, case, instance) of every row, in the table's order."""
        return [(p, c, round(u), case, inst) for p in self.plants for c in suite.classes for u in self.kmh(suite)
                for case in self.cases for inst in self.rows(case)]

    # -- report -----------------------------------------------------------------------------------
    def markdown(self, suite) -> list[str]:
        cells = self.runs_by_cell(suite)
        L = ["## Real sensors: offsets, biases, gains, delays, logging rate", "",
             f"Plant: the contract's linear vehicle, or its air spring and asymmetric damper (the estimators told "
             f"its linearisation); its sensors with the case's error (plant/sensors.py). 'default' = road_estimator 2 "
             f"not told the errors; 'told' = the same told the plant's sensor-error values (its known calibration); "
             f"on ideal sensors and in the logging cases the two are one estimator. Logging cases: ideal sensors, "
             f"road and plant at {1e3 * suite.step:g} ms with the road moving linearly over the step, the estimator "
             f"stepped every 1, 5 or 10 ms on the plant's outputs then (point samples) and scored at its steps; "
             f"200 and 100 Hz against '1 kHz logging'. Seeds "
             f"1..{suite.seeds}, {suite.duration:g} s runs, {suite.warmup:g} s warm-up; the sensor-error cases at "
             f"{1e3 * suite.step:g} ms. Each value: mean over seeds (worst seed). HP: HP road error std %; xref: HP "
             f"over that of the same seed's reference run (ideal sensors; at 200 / 100 Hz the 1 kHz logging run); "
             f"profile: rms error mm of road_height_est against metrics.reference_profile; pcov: share of those "
             f"within +-2 road_height_std (the coverage target); mass: sprung-mass error % (mean "
             f"after the warm-up); max|mass|: the largest |error| % at any instant after the warm-up; status: the "
             f"largest seen. Targets: HP and mass on every seed, the coverage over the seeds together: HP <= "
             f"{HP_RATIO} x ideal (200 Hz <= {LOGGING['200 Hz logging'][1]} x, 100 Hz <= "
             f"{LOGGING['100 Hz logging'][1]} x the 1 kHz logging run); pcov in [{COVERAGE[0]}, {COVERAGE[1]}]; mass "
             f"within {MASS_OK:g} % of the reference run's (default with the body accelerometer's gain off: that "
             f"error + {MASS_SLACK:g} %).", "",
             "| plant | ISO | km/h | case | estimator | HP % | xref | profile mm | pcov | mass % "
             "| max\\|mass\\| % | status | HP | pcov | mass |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for plant, cls, kmh, case, inst in self.grid(suite):
            v = self.values(cells, plant, cls, kmh, case, inst)
            ok = self.verdicts(cells, plant, cls, kmh, case, inst)
            label = inst if errors_of(case) else "default (= told)"

            def f(m: str, fmt: str) -> str:
                mean, worst = v[m]
                return "failed" if math.isnan(mean) else f"{mean:{fmt}} ({worst:{fmt}})"
            status = v["status_max"][1]
            L.append(f"| {plant} | {CLASS_LETTERS[cls - 1]} | {kmh} | {case} | {label} | "
                     f"{f('err_std_hp_pct', '.2f')} | {f('hp_ratio', '.2f')} | {f('rmse_raw_mm', '.2f')} | "
                     f"{f('coverage_2sigma', '.3f')} | "
                     f"{f('mass_err_mean_pct', '+.2f')} | {f('mass_err_max_abs_pct', '.2f')} | "
                     f"{'–' if math.isnan(status) else f'{status:.0f}'} | {verdict(ok['hp'])} | "
                     f"{verdict(ok['coverage'])} | {verdict(ok['mass'])} |")
        lagged = [row for row in self.grid(suite) if row[4] == "told" and told_lag(
            Estimator("told", "told", dict(zip(SENSOR_ERROR_KEYS, errors_of(row[3]))))) > 0]
        if lagged:
            L += ["", "For information (not a target): a 'told' estimator told a delay gives the road of the largest "
                  "told delay ago (the contract); its HP road error std % against the truth of that time, beside the "
                  "table's (against the truth at the step's time). Mean over seeds (worst seed).", "",
                  "| plant | ISO | km/h | case | HP % at the step's time | HP % at the told delay ago |",
                  "|---|---|---|---|---|---|"]
            for plant, cls, kmh, case, inst in lagged:
                runs = cells.get((plant, cls, kmh, case), {})
                at, lag = (np.asarray([runs[s][inst][m] for s in runs], float)
                           for m in ("err_std_hp_pct", "err_std_hp_pct_at_lag"))
                f = (lambda v: f"{np.mean(v):.2f} ({np.max(v):.2f})" if len(v) else "failed")
                L.append(f"| {plant} | {CLASS_LETTERS[cls - 1]} | {kmh} | {case} | {f(at)} | {f(lag)} |")
        return L + [""]

    def targets(self, suite) -> list[tuple[str, str, str]]:
        cells = self.runs_by_cell(suite)
        rows = [(r, self.verdicts(cells, *r)) for r in self.grid(suite)]
        out = []
        for inst in ("default", "told"):
            for key, what in (("hp", "HP road error vs ideal sensors"), ("coverage", "2-sigma coverage of the profile"),
                              ("mass", "sprung mass vs its reference run (200 / 100 Hz: 1 kHz logging)")):
                v = [(r, ok[key]) for r, ok in rows if r[4] == inst and ok[key] is not None
                     and (r[3] not in LOGGING or key != "hp" or r[3] == ONE_KHZ)]
                miss = [f"{p} ISO {CLASS_LETTERS[c - 1]} {u} {case}" for (p, c, u, case, _), ok in v if not ok]
                out.append((f"sensors {what} ({inst})", verdict(not miss if v else None),
                            f"{len(v) - len(miss)}/{len(v)} cells" + (f"; MISS: {', '.join(miss)}" if miss else "")))
        v = [(r, ok["hp"]) for r, ok in rows if r[3] in LOGGING and r[3] != ONE_KHZ and ok["hp"] is not None]
        miss = [f"{p} ISO {CLASS_LETTERS[c - 1]} {u} {case}" for (p, c, u, case, _), ok in v if not ok]
        out.append(("sensors HP at 200 / 100 Hz vs 1 kHz logging", verdict(not miss if v else None),
                    f"{len(v) - len(miss)}/{len(v)} cells" + (f"; MISS: {', '.join(miss)}" if miss else "")))
        return out

    def config(self, suite) -> dict:
        return {"sensors_speeds_kmh": list(self.kmh(suite)), "sensors_cases": list(self.cases),
                "sensors_plants": list(self.plants)}


SENSORS = Sensors()
