"""Paper 002's closed loop (``paper002``): road -> HalfCar <- SuspensionController <- estimator, its
Fig. 6 scenario through the built FMUs.

Fig. 6: four 50 s segments at 10 ms, (ISO A, 20 m/s, 400 kg), (B, 30, 300), (D, 20, 400),
(C, 10, 500). The paper's masses are 0.75-1.25 of its 400 kg car; the controller's schedule and
HalfCar's default car are at 672 kg, so the masses are scaled by 672/400 (504-840 kg) and the
IMM banks span the same 504-840 kg (the paper's sub-models sit on the scenario's masses). A
``--duration`` other than 200 s scales the four segments alike.

ISORoad takes its class as a parameter, so the four-segment road is written as a profile (that
of the ``imm`` study: each segment at its length, continuous) and played through ISORoad, the rear
tyre a wheelbase behind. The speed (vehicle_speed) and the plant's sprung_mass are inputs, held
over each segment.

Loops, one run each on the same road and sensor noise (seed i: road seeds 100 i + segment,
HalfCar.noise_seed 1000 + i):

- ``passive``: SuspensionController mode 0;
- ``LQR true``: the scheduled LQR (mode 2) on HalfCar's true relative states, told the true
  speed, class and mass;
- ``LQR <estimator>``: the scheduled LQR on HalfCarEstimator's ``*_est``, ``sprung_mass_est`` and
  ``road_class_est`` for each of its codes (KF, AKF, IMMKF, IMMAKF3, IMMAKF5) on the paper's model
  (``force_error_q`` 0). As the paper: KF and IMMKF assume ISO C, AKF and the IMMAKFs start from
  ISO A; KF and AKF assume 672 kg (its 400 kg).
- ``LQR default``: the same on HalfCarEstimator's defaults (IMMAKF5 with its force-error states);
- ``..., springs -15 %``: LQR on true states, on the paper's IMMAKF5 and on the default, the
  plant's springs 15 % softer than the car the estimator and the controller are told.

Stepping order ISORoad, HalfCar, HalfCarEstimator, SuspensionController (Gauss-Seidel): the
estimator reads the measurements at the end of the plant's step and the force held over it, and
the controller's force over [t, t + h] comes from the estimate at t (a zero-order hold, no further
lag). ``LQR true`` is also run at 1 ms and, at 10 ms, with a Jacobi master (every FMU steps on
the values of the previous communication point, as FMPy's SSP runner and libcosim do): the force
then reaches the plant one step later. The three give what the hold and the coupling delay cost.

Scores over the whole run (the paper's "Total"), rows after initialisation:

- eq. 44 as printed, E = mean(|x - x_hat| / |x|) x 100 %, per velocity state. It divides by
  |x| at every sample, so a few samples where the true velocity crosses zero dominate it (it has
  no bound); it is reported as printed and beside it as RMS(x - x_hat) / RMS(x) x 100 %;
- ride comfort: RMS body acceleration at the CG (heave) and above each axle, suspension
  deflection RMS and peak, dynamic tyre load RMS (-k_t times the tyre deflection, i.e. the tyre
  force minus its static value), the share of steps at the actuator's limit.
"""
from __future__ import annotations

import tempfile
import time
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ...plant.half_car import HalfCarParams
from ..ssp import HALF_CAR_LOOP, HALF_CAR_STATES, SYSTEMS
from .imm import CLASSES, SPEEDS, write_profile
from .runner import CLASS_LETTERS, NOISE_SEED_OFFSET, RunSpec, Study, simulate, verdict, whole_steps

KIND = "paper002"
STEP = 0.01  # s, the paper's
PAPER_MASS = 400.0  # kg, the paper's car
PAPER_MASSES = (400.0, 300.0, 400.0, 500.0)  # kg, Fig. 6
CAR = HalfCarParams()
MASS_SCALE = CAR.m_s / PAPER_MASS  # 672 / 400
MASSES = tuple(MASS_SCALE * m for m in PAPER_MASSES)  # 672, 504, 672, 840 kg
BANK = (MASS_SCALE * 300.0, MASS_SCALE * 500.0)  # kg, the IMM banks' lightest and heaviest sub-model
DEFLECTION_LIMIT = 0.15  # m, eq. 17's constraint
TARGET_TRUE = 0.10  # LQR on the default estimator within 10 % of LQR on true states (body acceleration RMS)
ESTIMATORS = {"KF": 0, "AKF": 1, "IMMKF": 2, "IMMAKF3": 3, "IMMAKF5": 4}  # HalfCarEstimator codes
START_CLASS = {0: 3, 1: 1, 2: 3, 3: 1, 4: 1}  # the paper: KF, IMMKF on ISO C; AKF, IMMAKF from ISO A
PAPER_BEST = "IMMAKF5"
DEFAULT = "default"  # HalfCarEstimator at its defaults: IMMAKF5 with the force-error states
SOFT = 0.85  # the plant's springs in the "springs -15 %" loops, of the car the loop is told


class Loop(NamedTuple):
    mode: int  # SuspensionController.mode
    code: int | None  # HalfCarEstimator.estimator, None = the true states
    step: float  # s
    jacobi: bool = False  # Jacobi master (else Gauss-Seidel)
    paper_model: bool = False  # HalfCarEstimator.force_error_q = 0
    springs: float = 1.0  # the plant's k_f and k_r, of HalfCar's defaults


LOOPS: dict[str, Loop] = {
    "passive": Loop(0, None, STEP),
    "LQR true": Loop(2, None, STEP),
    **{f"LQR {n}": Loop(2, c, STEP, paper_model=True) for n, c in ESTIMATORS.items()},
    f"LQR {DEFAULT}": Loop(2, 4, STEP),
    "LQR true, 1 ms": Loop(2, None, 1e-3),
    "LQR true, Jacobi": Loop(2, None, STEP, jacobi=True),
    "LQR true, springs -15 %": Loop(2, None, STEP, springs=SOFT),
    f"LQR {PAPER_BEST}, springs -15 %": Loop(2, 4, STEP, paper_model=True, springs=SOFT),
    f"LQR {DEFAULT}, springs -15 %": Loop(2, 4, STEP, springs=SOFT),
}
# a loop expected to leave the deflection limit: shown, not counted against it
DIVERGES = (f"LQR {PAPER_BEST}, springs -15 %",)
STATES = HALF_CAR_STATES  # the controller's inputs, lqr.STATES
VELOCITIES = STATES[:4]
SYMBOLS = {"heave_velocity": "heave velocity", "pitch_rate": "pitch rate", "v_u_front": "front wheel velocity",
           "v_u_rear": "rear wheel velocity"}
COMFORT = ("acc_cg_rms", "acc_front_rms", "acc_rear_rms", "defl_front_rms", "defl_rear_rms", "defl_front_peak",
           "defl_rear_peak", "tyre_front_rms", "tyre_rear_rms", "saturated_pct")
# Table 3 (simulation, whole run): % by which IMMAKF5 lowers eq. 44's error against IMMKF, AKF, KF
PAPER_TABLE3 = {"heave_velocity": (55.17, 56.84, 60.19), "pitch_rate": (48.69, 48.85, 45.31),
                "v_u_front": (77.18, 77.43, 79.36), "v_u_rear": (76.78, 77.05, 79.43)}
# Table 5: the quarter-car rig (2.45 kg body, ISO A, 20 m/s), not the Fig. 6 half car: % by which
# IMMAKF5 lowers body acceleration and suspension deflection against the KF and the passive car
PAPER_TABLE5 = {"body acceleration": (14.64, 62.73), "suspension deflection": (11.43, 74.38)}


def segments(duration: float) -> np.ndarray:
    """Start times (s) of the four segments of a run of ``duration`` s."""
    return np.arange(len(CLASSES)) * duration / len(CLASSES)


def loop_system(dist: Path, estimator: bool):
    """The closed loop's ``System``: ISORoad -> HalfCar -> [HalfCarEstimator ->] SuspensionController
    -> HalfCar (and -> HalfCarEstimator), input ``vehicle_speed`` (m/s). On the true states the
    controller reads HalfCar's noise-free states; its ``road_class`` and ``sprung_mass`` are then left
    to the caller (inputs ``SuspensionController.road_class``, ``.sprung_mass``)."""
    from ..cosim import System

    dist = Path(dist)
    order, conns, _ = SYSTEMS[HALF_CAR_LOOP]
    if estimator:
        conns = conns + [("HalfCarEstimator.sprung_mass_est", "SuspensionController.sprung_mass")]
    else:
        order = [c for c in order if c != "HalfCarEstimator"]
        true = {s: s + "_true" if s.startswith(("susp", "tire")) else s for s in STATES}
        conns = [(a, b) for a, b in conns if "HalfCarEstimator" not in a + b]
        conns += [(f"HalfCar.{true[s]}", f"SuspensionController.{s}") for s in STATES]
    return System({c: dist / f"{c}.fmu" for c in order}, conns, order=list(order),
                  name=HALF_CAR_LOOP if estimator else f"{HALF_CAR_LOOP}True")


def loop_parameters(loop: Loop, seed: int, profile: Path) -> dict:
    """Parameters of the loop's instances: the profile, the seeds, the plant's springs, the
    controller's mode and, with an estimator, its code, start class, mass bank and model."""
    p = {"ISORoad.profile_file": str(profile), "ISORoad.profile_end": 1, "ISORoad.wheelbase": CAR.wheelbase,
         "HalfCar.noise_seed": NOISE_SEED_OFFSET + seed, "SuspensionController.mode": loop.mode}
    if loop.springs != 1.0:
        p.update({"HalfCar.k_f": loop.springs * CAR.k_f, "HalfCar.k_r": loop.springs * CAR.k_r})
    if loop.code is not None:
        p.update({"HalfCarEstimator.estimator": loop.code, "HalfCarEstimator.road_class": START_CLASS[loop.code],
                  "HalfCarEstimator.imm_mass_min": BANK[0], "HalfCarEstimator.imm_mass_max": BANK[1]})
        if loop.paper_model:
            p["HalfCarEstimator.force_error_q"] = 0.0
    return p


def eq44(x: np.ndarray, x_hat: np.ndarray) -> float:
    """Eq. 44 as printed: mean over the samples of |x - x_hat| / |x|, in %. Unbounded where x -> 0."""
    x, x_hat = np.asarray(x, float), np.asarray(x_hat, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(100 * np.mean(np.abs(x - x_hat) / np.abs(x)))


def rms_error_pct(x: np.ndarray, x_hat: np.ndarray) -> float:
    """RMS(x - x_hat) / RMS(x), in %: eq. 44's idea with the normalisation taken over the run."""
    x, x_hat = np.asarray(x, float), np.asarray(x_hat, float)
    return float(100 * np.sqrt(np.mean((x - x_hat) ** 2) / np.mean(x ** 2)))


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def comfort(r: np.ndarray) -> dict[str, float]:
    """Ride comfort of a record (rows after initialisation): m/s2, m, N, %."""
    a_f, a_r = r["HalfCar.acc_body_front_true"], r["HalfCar.acc_body_rear_true"]
    L = CAR.wheelbase
    d_f, d_r = r["HalfCar.susp_deflection_front_true"], r["HalfCar.susp_deflection_rear_true"]
    return {"acc_cg_rms": rms((CAR.l_r * a_f + CAR.l_f * a_r) / L), "acc_front_rms": rms(a_f),
            "acc_rear_rms": rms(a_r), "defl_front_rms": rms(d_f), "defl_rear_rms": rms(d_r),
            "defl_front_peak": float(np.max(np.abs(d_f))), "defl_rear_peak": float(np.max(np.abs(d_r))),
            "tyre_front_rms": rms(CAR.k_tf * r["HalfCar.tire_deflection_front_true"]),
            "tyre_rear_rms": rms(CAR.k_tr * r["HalfCar.tire_deflection_rear_true"]),
            "saturated_pct": float(100 * np.mean(r["SuspensionController.saturated"] != 0))}


def run_loop(spec: RunSpec, loop: str) -> dict:
    """One closed loop of ``LOOPS`` over the Fig. 6 scenario of ``spec.duration`` s: ride comfort and,
    with an estimator, its errors per state (eq. 44 and RMS), its mass and class at the end of each
    segment."""
    from ..cosim import JACOBI, CoSimulation
    from ..scenario import Profile

    spec_loop = LOOPS[loop]
    code, step = spec_loop.code, spec_loop.step
    starts = segments(spec.duration)
    system = loop_system(Path(spec.dist), code is not None)
    inputs = {"vehicle_speed": Profile(starts, np.array(SPEEDS), "step"),
              "HalfCar.sprung_mass": Profile(starts, np.array(MASSES), "step")}
    if code is None:
        inputs.update({"SuspensionController.sprung_mass": inputs["HalfCar.sprung_mass"],
                       "SuspensionController.road_class": Profile(starts, np.array(CLASSES, float), "step")})
    truth = ["heave_velocity", "pitch_rate", "v_u_front", "v_u_rear", "susp_deflection_front_true",
             "susp_deflection_rear_true", "tire_deflection_front_true", "tire_deflection_rear_true",
             "acc_body_front_true", "acc_body_rear_true"]
    record = [f"HalfCar.{v}" for v in truth] + ["SuspensionController.force_front",
                                                "SuspensionController.force_rear", "SuspensionController.saturated"]
    if code is not None:
        record += [f"HalfCarEstimator.{s}_est" for s in STATES] + [
            "HalfCarEstimator.sprung_mass_est", "HalfCarEstimator.road_class_est"]
    with tempfile.TemporaryDirectory() as tmp:
        profile = Path(tmp) / "fig6_road.csv"
        write_profile(profile, spec.seed, spec.duration / len(CLASSES))
        params = loop_parameters(spec_loop, spec.seed, profile)
        run_spec = RunSpec(spec.study, spec.road_class, spec.seed, spec.duration, 0.0, step, spec.dist)
        if spec_loop.jacobi:
            t0 = time.perf_counter()
            with CoSimulation(system, params, inputs, record, coupling=JACOBI) as sim:
                r = sim.run(spec.duration, step)
            wall = time.perf_counter() - t0
            timing = {"run_s": wall, "steps": len(r) - 1, "us_per_step": 1e6 * wall / (len(r) - 1)}
        else:
            r, timing = simulate(system, params, inputs, record, run_spec, spec.duration)
    t, r = r["time"][1:], r[1:]
    out: dict = {"timing": timing, "loop": loop, "step": step, "comfort": comfort(r),
                 "finite": bool(all(np.all(np.isfinite(r[n])) for n in record))}
    if code is not None:
        x = {s: r[f"HalfCar.{s}"] for s in VELOCITIES}
        out["eq44"] = {s: eq44(x[s], r[f"HalfCarEstimator.{s}_est"]) for s in VELOCITIES}
        out["rms_error"] = {s: rms_error_pct(x[s], r[f"HalfCarEstimator.{s}_est"]) for s in VELOCITIES}
        ends = [np.searchsorted(t, b - 1e-9) for b in list(starts[1:]) + [spec.duration]]
        out["mass_end"] = [float(r["HalfCarEstimator.sprung_mass_est"][min(i, len(t) - 1)]) for i in ends]
        out["class_end"] = [int(r["HalfCarEstimator.road_class_est"][min(i, len(t) - 1)]) for i in ends]
    return out


RUNS = {f"{KIND} {loop}": partial(run_loop, loop=loop) for loop in LOOPS}


def reduction(ours: float, other: float) -> float:
    """% by which ``ours`` is below ``other``."""
    return 100 * (1 - ours / other)


class Paper002(Study):
    name = KIND
    runs = RUNS
    defaults = {"seeds": 1, "duration": 200.0}

    def check(self, suite) -> None:
        if not whole_steps(suite.duration, STEP):
            raise ValueError(f"--duration = {suite.duration} s is not a whole number of the study's {STEP} s steps")

    def specs(self, suite) -> list[RunSpec]:
        d = str(Path(suite.dist).resolve())
        return [RunSpec(kind, 0, s, suite.duration, 0.0, LOOPS[kind.removeprefix(KIND + ' ')].step, d)
                for kind in RUNS for s in range(1, suite.seeds + 1)]

    @staticmethod
    def values(suite, loop: str, *keys: str) -> np.ndarray:
        """Per seed, ``result[keys[0]][keys[1]]...`` of the loop's completed runs."""
        out = []
        for r in suite.ok(f"{KIND} {loop}"):
            v = r
            for k in keys:
                v = v[k]
            out.append(v)
        return np.array(out, float)

    def mean(self, suite, loop: str, *keys: str) -> float:
        v = self.values(suite, loop, *keys)
        return float(np.mean(v)) if len(v) else float("nan")

    def markdown(self, suite) -> list[str]:
        m = self.mean
        seg = suite.duration / len(CLASSES)
        L = ["## Paper 002: the closed loop of its Fig. 6 scenario", "",
             f"{seg:g} s segments " + " → ".join(
                 f"ISO {CLASS_LETTERS[c - 1]} / {v:g} m/s / {mass:g} kg (paper {p:g} kg)"
                 for c, v, mass, p in zip(CLASSES, SPEEDS, MASSES, PAPER_MASSES))
             + f"; {1e3 * STEP:g} ms; IMM banks {BANK[0]:g}-{BANK[1]:g} kg; HalfCar's default car and sensors; "
             f"mean over {suite.seeds} seed(s), whole run scored.", "",
             "### Ride comfort", "",
             "| loop | body acc. CG RMS m/s² | front / rear RMS m/s² | deflection RMS front / rear mm | "
             "deflection peak front / rear mm | dyn. tyre load RMS front / rear N | at the limit % | vs passive | "
             "vs LQR true (same springs) |", "|---|---|---|---|---|---|---|---|---|"]
        passive, true = m(suite, "passive", "comfort", "acc_cg_rms"), m(suite, "LQR true", "comfort", "acc_cg_rms")
        soft_true = m(suite, "LQR true, springs -15 %", "comfort", "acc_cg_rms")  # the springs' own reference
        for loop in LOOPS:
            if not suite.ok(f"{KIND} {loop}"):
                L.append(f"| {loop} | failed | | | | | | | |")
                continue

            def c(k, scale=1.0, fmt=".3f"):
                return f"{scale * m(suite, loop, 'comfort', k):{fmt}}"
            a = m(suite, loop, "comfort", "acc_cg_rms")
            L.append(f"| {loop} | {c('acc_cg_rms')} | {c('acc_front_rms')} / {c('acc_rear_rms')} | "
                     f"{c('defl_front_rms', 1e3, '.1f')} / {c('defl_rear_rms', 1e3, '.1f')} | "
                     f"{c('defl_front_peak', 1e3, '.1f')} / {c('defl_rear_peak', 1e3, '.1f')} | "
                     f"{c('tyre_front_rms', 1, '.0f')} / {c('tyre_rear_rms', 1, '.0f')} | {c('saturated_pct', 1, '.2f')} | "
                     f"{a / passive - 1:+.1%} | {a / (true if LOOPS[loop].springs == 1.0 else soft_true) - 1:+.1%} |")
        L += ["", "### Estimation error per state (each estimator in its own loop)", "",
              "Eq. 44 as printed (mean of |x - x̂| / |x|: unbounded where x crosses zero) and RMS(x - x̂) / RMS(x), %.",
              "", "| estimator | " + " | ".join(f"{SYMBOLS[s]} eq. 44 / RMS" for s in VELOCITIES)
              + " | mass at the segment ends kg | class at the segment ends |", "|---|" + "---|" * (len(VELOCITIES) + 2)]
        for n in [*ESTIMATORS, DEFAULT]:
            loop = f"LQR {n}"
            if not suite.ok(f"{KIND} {loop}"):
                L.append(f"| {n} | failed |" + " |" * (len(VELOCITIES) + 1))
                continue
            cells = [f"{m(suite, loop, 'eq44', s):.1f} / {m(suite, loop, 'rms_error', s):.1f}" for s in VELOCITIES]
            first = suite.ok(f"{KIND} {loop}")[0]
            L.append(f"| {n} | " + " | ".join(cells) + " | " + ", ".join(f"{v:.0f}" for v in first["mass_end"])
                     + " | " + ", ".join(CLASS_LETTERS[c - 1] if c else "–" for c in first["class_end"]) + " |")
        L += ["", "### The paper's claims beside ours", "",
              "| claim | paper | ours (eq. 44 / RMS error) |", "|---|---|---|"]
        for s in VELOCITIES:
            for j, other in enumerate(("IMMKF", "AKF", "KF")):
                ours = [reduction(m(suite, f"LQR {PAPER_BEST}", k, s), m(suite, f"LQR {other}", k, s))
                        for k in ("eq44", "rms_error")]
                L.append(f"| IMMAKF5 lowers the {SYMBOLS[s]} error against {other} (Table 3) | "
                         f"{PAPER_TABLE3[s][j]:.2f} % | {ours[0]:.1f} % / {ours[1]:.1f} % |")
        for k, key in (("body acceleration", "acc_cg_rms"), ("suspension deflection", "defl_front_rms")):
            ours_kf = reduction(m(suite, f"LQR {PAPER_BEST}", "comfort", key), m(suite, "LQR KF", "comfort", key))
            ours_p = reduction(m(suite, f"LQR {PAPER_BEST}", "comfort", key), m(suite, "passive", "comfort", key))
            L.append(f"| LQR on IMMAKF5 lowers the {k} (RMS{', front' if 'defl' in key else ', CG'}) against LQR on "
                     f"the KF / the passive car (Table 5: its quarter-car rig) | {PAPER_TABLE5[k][0]:.2f} / "
                     f"{PAPER_TABLE5[k][1]:.2f} % | {ours_kf:.1f} / {ours_p:.1f} % |")
        L += ["", "### The one-step coupling delay", "",
              "| LQR on true states | body acc. CG RMS m/s² | vs 10 ms Gauss-Seidel |", "|---|---|---|"]
        for loop, label in (("LQR true, 1 ms", "1 ms, Gauss-Seidel (hold of 1 ms)"),
                            ("LQR true", "10 ms, Gauss-Seidel (hold of 10 ms)"),
                            ("LQR true, Jacobi", "10 ms, Jacobi (the force one step late)")):
            a = m(suite, loop, "comfort", "acc_cg_rms")
            L.append(f"| {label} | {a:.4f} | {a / true - 1:+.2%} |")
        L.append("")
        return L

    def targets(self, suite) -> list[tuple[str, str, str]]:
        m = self.mean
        out = []
        loops = [lp for lp in LOOPS if lp != "LQR true, Jacobi" and lp not in DIVERGES]
        done = [lp for lp in loops if suite.ok(f"{KIND} {lp}")]
        peak = max((max(m(suite, lp, "comfort", "defl_front_peak"), m(suite, lp, "comfort", "defl_rear_peak"))
                    for lp in done), default=float("nan"))
        finite = all(bool(np.all(self.values(suite, lp, "finite"))) for lp in done)
        out.append(("paper 002: every closed loop runs the Fig. 6 scenario, finite, deflection within 0.15 m",
                    verdict(len(done) == len(loops) and finite and peak < DEFLECTION_LIMIT),
                    f"{len(done)}/{len(loops)} loops ran, largest deflection {1e3 * peak:.1f} mm"))
        true, est = m(suite, "LQR true", "comfort", "acc_cg_rms"), m(suite, f"LQR {DEFAULT}", "comfort", "acc_cg_rms")
        out.append((f"paper 002: LQR on {DEFAULT} within {TARGET_TRUE:.0%} of LQR on true states (body acc. RMS)",
                    verdict(None if not np.isfinite(true * est) else est <= (1 + TARGET_TRUE) * true),
                    f"{est:.4f} vs {true:.4f} m/s² ({est / true - 1:+.1%})"))
        soft_true, soft_est = (m(suite, f"LQR {k}, springs -15 %", "comfort", "acc_cg_rms") for k in ("true", DEFAULT))
        out.append((f"paper 002, springs 15 % softer than told: LQR on {DEFAULT} within {TARGET_TRUE:.0%} of LQR on "
                    "true states (body acc. RMS)",
                    verdict(None if not np.isfinite(soft_true * soft_est) else soft_est <= (1 + TARGET_TRUE) * soft_true),
                    f"{soft_est:.4f} vs {soft_true:.4f} m/s² ({soft_est / soft_true - 1:+.1%})"))
        passive = m(suite, "passive", "comfort", "acc_cg_rms")
        out.append(("paper 002: LQR on true states below the passive car (body acc. RMS)",
                    verdict(None if not np.isfinite(true * passive) else true < passive),
                    f"{true:.4f} vs {passive:.4f} m/s² ({true / passive - 1:+.1%})"))
        kf = {s: m(suite, "LQR KF", "rms_error", s) for s in VELOCITIES}
        best = {s: m(suite, f"LQR {PAPER_BEST}", "rms_error", s) for s in VELOCITIES}
        out.append(("paper 002 Table 3 (direction): IMMAKF5 below the KF on every velocity (RMS error)",
                    verdict(None if not all(np.isfinite(v) for v in [*kf.values(), *best.values()])
                            else all(best[s] < kf[s] for s in VELOCITIES)),
                    ", ".join(f"{SYMBOLS[s]} {best[s]:.1f} vs {kf[s]:.1f} %" for s in VELOCITIES)))
        lqr_kf = m(suite, "LQR KF", "comfort", "acc_cg_rms")
        out.append(("paper 002 Table 5 (direction): LQR on IMMAKF5 below LQR on the KF and the passive car "
                    "(body acc. RMS)", verdict(None if not np.isfinite(est * lqr_kf * passive)
                                               else est < lqr_kf and est < passive),
                    f"{est:.4f} vs {lqr_kf:.4f} and {passive:.4f} m/s²"))
        return out

    def config(self, suite) -> dict:
        return {KIND: {"step_s": STEP, "classes": [CLASS_LETTERS[c - 1] for c in CLASSES], "speeds_m_s": SPEEDS,
                       "masses_kg": MASSES, "paper_masses_kg": PAPER_MASSES, "imm_bank_kg": BANK,
                       "loops": {k: v._asdict() for k, v in LOOPS.items()}}}

    def json(self, suite) -> dict:
        return {KIND: {"paper_table3_reduction_pct_vs_IMMKF_AKF_KF": PAPER_TABLE3,
                       "paper_table5_reduction_pct_vs_KF_passive": PAPER_TABLE5}}


PAPER002 = Paper002()
