"""SuspensionEstimator: road profile (KF, MME&KF, the robust default, or an estimator of the
registry) + sprung mass (RLS) + online ISO class.

Road estimators (contract ``road_estimator``): 0 the KF of the exact linear model and 1 MME&KF
(kf_road.py), 2 (default) the robust combination of docs/robustness.md (anchored_road.py), the
others the estimators of the registry (interface.py). Each is a ``RoadFilter``; this module
composes one with what is common to all: the sample checks, ``status``, the mass estimator and
its feedback, the online class, the IRI and the outputs.

The FMU adapter calls ``SuspensionEstimator(config).step(acc_sprung, acc_unsprung, deflection,
speed, h)`` once per doStep; it returns a dict keyed by the contract's output names. The
estimate refers to the instant of the measurement passed in (filtered estimate x_{k|k}).

The road output. ``road_height_est`` is the road profile as inertial profilers report it: the
filter's road, freed of its common-mode reference (road_profile.Profiler), high-passed in
distance at ``profile_cutoff`` (plant.profile_band, third order), fed while the car moves
(``_profile``); harness.metrics.reference_profile gives it from a true profile.
``road_height_std`` is the filter's ``road_variance`` (the KF family's: its P scaled to the
steady-state error in that band with the allowance for the sensors' calibration,
``KFRoad.band_ratio``). The states z_s_est, z_u_est stay relative to the reference, with the
filter's ``z_shift`` added (the KF family's low-frequency lag, ``KFRoad.lag_rate``).

Mass feedback. The road filter takes the mass of ``mass_estimator`` 1 (``MassEstimator``) in
``RoadFilter.feed_back_mass``: a filter of the registry through ``set_mass``, when the
since-change mass disagrees with the one it was given; the KF family rebuilds and re-filters the
change itself (``KFRoad.feed_back_mass``).
The reported ``sprung_mass_est`` is the paper's fast forgetting-factor RLS.

Bad samples. Each channel is checked every step: non-finite, or frozen (bit-identical for
``frozen_time`` s: a noisy sensor never repeats itself) channels are left out of the update
(the KF family also leaves out outliers, kf_road.py) and ``status`` = 1. The mass regression
skips substituted samples (the road filter's ``substitutes`` feed the state-variable filters
instead) and a short guard after them. ``status`` = 2 when the road filter re-initialised.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..plant.iri import SEGMENT_RANGE, IRIMeter
from ..plant.profile_band import CUTOFF_RANGE, PROFILE_CUTOFF, class_band_rms
from ..plant.quarter_car import NOISE_STD_RANGES
from ..plant.sensors import CALIBRATION_ALLOWANCE, SENSOR_ERROR_RANGES, DelayLine, SensorErrors
from ..plant.step_size import same_step
from ..plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER
from ..plant.vehicle import Vehicle, VEHICLE_RANGES, check_range

from .airspring_observers import config_problems
from .anchored_road import AnchoredRoad
from .imm_filter import imm_problems
from .interface import RoadFilter, code_problems, composed_factory, preload, state_list
from .kf_road import KFRoad
from .mass import MassEstimator
from .model import IVR, IVS, IVU, IZR, IZS, IZU
from .road_class import RoadClassifier
from .road_profile import Profiler
from .sensor_check import INCONSISTENT
from .standstill_bias import LEARNED, StandstillBias
from .tuning import TUNING, TUNING_FIELDS, Tuning
from .vb_akf import vb_problems

OUTPUTS = ("road_height_est", "road_velocity_est", "road_height_std", "z_s_est", "v_s_est",
           "z_u_est", "v_u_est", "susp_deflection_est", "tire_deflection_est", "sprung_mass_est", "mass_std",
           "road_class_est", "nis", "status", "iri_est")

STATUS_OK, STATUS_REJECTED, STATUS_REINIT, STATUS_SENSOR = 0, 1, 2, 3
# the car's motion, from the speed each step (Tuning.standstill_speed): standing, the mass
# regression is not fed and the road profile holds
MOVING, STANDING = "moving", "standing"


@dataclass
class EstimatorConfig:
    """Parameters of the estimator: the contract's (SI units), and the fixed choices (``tuning``)."""

    m_s_nominal: float = 410.0  # kg, sprung mass the model assumes at start
    m_u: float = 39.0  # kg
    k_s: float = 20000.0  # N/m
    k_t: float = 183000.0  # N/m
    c_s: float = 2000.0  # N.s/m
    road_estimator: int = 2  # 0 = KF, 1 = MME&KF, 2 = KF with a suspension-force error state
    mass_estimator: int = 1  # 0 = off, 1 = forgetting-factor RLS, 2 = IMM, 4 = moving-bank IMM
    mass_feedback: bool = True  # rebuild the road filter at the estimated mass
    forgetting_factor: float = 0.995  # RLS lambda per sample, 0.9 < lambda <= 1
    road_class: int = 0  # 0 = identify online, 1..8 = assume A..H
    acc_sprung_noise_std: float = 0.02  # m/s^2
    acc_unsprung_noise_std: float = 0.2  # m/s^2
    defl_noise_std: float = 1e-4  # m
    # 0 = accelerations sampled at the end of the step, 1 = averaged over the step (must match
    # the sensor): 1 appends the previous v_s, v_u to the state (8 states), see model.py
    acc_sampling: int = 0
    # the nonlinear suspension of road_estimator 3, 5 and mass_estimator 3 (airspring_observers.py):
    # the plant's parameters (plant/suspension_forces.py: names, units, defaults); 0 = linear k_s, c_s
    spring_model: int = 0  # 0 = linear spring k_s, 1 = self-levelling air spring (air_*)
    damper_model: int = 0  # 0 = linear damper c_s, 1 = asymmetric piecewise-linear damper (damper_*)
    air_area: float = DEFAULT_AIR_SPRING.air_area  # m^2
    air_volume: float = DEFAULT_AIR_SPRING.air_volume  # m^3
    air_kappa: float = DEFAULT_AIR_SPRING.air_kappa  # 1
    air_pressure_max: float = DEFAULT_AIR_SPRING.air_pressure_max  # Pa, absolute
    damper_c_rebound: float = DEFAULT_DAMPER.damper_c_rebound  # N.s/m
    damper_c_compression: float = DEFAULT_DAMPER.damper_c_compression  # N.s/m
    damper_knee_rebound: float = DEFAULT_DAMPER.damper_knee_rebound  # m/s
    damper_knee_compression: float = DEFAULT_DAMPER.damper_knee_compression  # m/s
    damper_c_rebound_high: float = DEFAULT_DAMPER.damper_c_rebound_high  # N.s/m
    damper_c_compression_high: float = DEFAULT_DAMPER.damper_c_compression_high  # N.s/m
    iri_segment: float = 100.0  # m, segments of the IRI of the road estimate (plant/iri.py)
    # m, long-wavelength cut-off of road_height_est, the profile high-passed in distance
    # (plant/profile_band.py)
    profile_cutoff: float = PROFILE_CUTOFF
    # road_estimator 4 (VB-AKF, vb_akf.VBRoadFilter): fixed-point iterations per step, forgetting
    # factor of the R posterior, weight of the nominal prediction in the PECM prior (0 = R only)
    vb_iterations: int = 6
    vb_forgetting: float = 1.0 - math.exp(-4.0)
    vb_tau: float = 0.0
    # mass_estimator 2 and 4, the IMM of paper 002 (imm_filter.py): the fixed bank's range (kg)
    # and number of models (code 2), the probability of keeping the model per step (both)
    imm_mass_min: float = 250.0
    imm_mass_max: float = 550.0
    imm_models: int = 7
    imm_stay: float = 0.999
    # the known calibration of the sensors (plant/sensors.py): removed from every sample before
    # anything else sees it; the delays are aligned by delaying the other channels
    deflection_offset: float = 0.0  # m
    acc_sprung_bias: float = 0.0  # m/s^2
    acc_unsprung_bias: float = 0.0  # m/s^2
    acc_sprung_scale: float = 1.0
    acc_unsprung_scale: float = 1.0
    acc_sprung_delay: float = 0.0  # s
    acc_unsprung_delay: float = 0.0  # s
    deflection_delay: float = 0.0  # s
    # what road_height_std allows for the calibration errors it is not told (1-sigma): each
    # accelerometer's gain error (relative) and each channel's delay (s); 0 = calibrated sensors
    calibration_gain_std: float = CALIBRATION_ALLOWANCE["calibration_gain_std"][0]
    calibration_delay_std: float = CALIBRATION_ALLOWANCE["calibration_delay_std"][0]
    # everything else is a fixed choice, with its reason, in tuning.py
    tuning: Tuning = TUNING

    def vehicle(self, m_s: float | None = None) -> Vehicle:
        return Vehicle(m_s=self.m_s_nominal if m_s is None else m_s, m_u=self.m_u, k_s=self.k_s,
                       k_t=self.k_t, c_s=self.c_s)

    def problems(self) -> list[str]:
        """Messages naming each invalid parameter and its allowed range (empty when valid)."""
        msgs = []
        for name, key in (("m_s_nominal", "m_s"), ("m_u", "m_u"), ("k_s", "k_s"), ("k_t", "k_t"),
                          ("c_s", "c_s")):
            msgs.append(check_range(name, float(getattr(self, name)), *VEHICLE_RANGES[key]))
        for name, hi in (("road_estimator", None), ("mass_estimator", None), ("road_class", 8),
                         ("acc_sampling", 1)):
            val = getattr(self, name)
            if isinstance(val, float) and not val.is_integer():
                msgs.append(f"{name} = {val!r} must be an integer" + ("" if hi is None else f" in [0, {hi}]"))
            elif hi is not None:
                msgs.append(check_range(name, val, 0, hi))
        # the codes and their combination, once each is an integer in range (None: not checked)
        codes = (None if any(m and m.startswith(("road_estimator", "mass_estimator")) for m in msgs)
                 else code_problems(int(self.road_estimator), int(self.mass_estimator)))
        msgs += codes or []
        msgs.append(check_range("forgetting_factor", float(self.forgetting_factor), 0.9, 1.0,
                                low_inclusive=False))
        for name, (lo, hi) in NOISE_STD_RANGES.items():
            msgs.append(check_range(name, float(getattr(self, name)), lo, hi))
        msgs.append(check_range("iri_segment", float(self.iri_segment), *SEGMENT_RANGE))
        msgs.append(check_range("profile_cutoff", float(self.profile_cutoff), *CUTOFF_RANGE))
        for name, (lo, hi) in SENSOR_ERROR_RANGES.items():
            msgs.append(check_range(name, float(getattr(self, name)), lo, hi))
        for name, (_, (lo, hi)) in CALIBRATION_ALLOWANCE.items():
            msgs.append(check_range(name, float(getattr(self, name)), lo, hi))
        msgs += self.tuning.problems()
        msgs += vb_problems(self)
        if codes == []:
            msgs += config_problems(self)  # the nonlinear model's parameters
        msgs += imm_problems(self)
        return [m for m in msgs if m]


def validate(config: EstimatorConfig) -> list[str]:
    """Alias of ``config.problems()``: one message per invalid parameter, naming it and its range."""
    return config.problems()




def _kf_family(name: str, default=None, doc: str = "") -> property:
    """A property of the composer that reads the KF family's road filter (kf_road.py), and is
    ``default`` with an estimator of the registry."""
    return property(lambda self: getattr(self.road, name) if isinstance(self.road, KFRoad) else default, doc=doc)


class SuspensionEstimator:
    """Joint road-profile, state, sprung-mass and ISO-class estimator (see the module doc).

    ``road`` is the road filter (interface.RoadFilter); ``mass_est`` the mass estimator of
    ``mass_estimator`` 1 (None otherwise)."""

    def __init__(self, config: EstimatorConfig | None = None, **overrides):
        cfg = config or EstimatorConfig()
        if overrides:  # contract parameters and fixed choices (tuning.py) alike, by name
            tuned = {k: v for k, v in overrides.items() if k in TUNING_FIELDS}
            if tuned:
                overrides = {k: v for k, v in overrides.items() if k not in tuned}
                overrides["tuning"] = replace(cfg.tuning, **tuned)
            cfg = replace(cfg, **overrides)
        problems = cfg.problems()
        if problems:
            raise ValueError("; ".join(problems))
        self.cfg = cfg
        self.sensors = SensorErrors.of(cfg)
        lag = max(self.sensors.delays)
        self._aligners = ([DelayLine(lag - d) for d in self.sensors.delays]
                          if not self.sensors.none else None)
        self._sample_time = 0.0  # s, the clock of the aligners
        # accelerometer biases learned while the car stands (standstill_bias.py), removed from
        # the samples once the car moves again; at its first move the road filter restarts
        self.standstill = StandstillBias()
        self.bias_removed = (0.0, 0.0)  # m/s^2, body and wheel, in use
        self._moved = False  # the car has moved since the start
        self._d_last: float | None = None  # m, the last deflection given to the mass regression
        self.acc_sampling = int(cfg.acc_sampling)
        damping = cfg.road_estimator == 2 if cfg.tuning.estimate_damping is None else bool(cfg.tuning.estimate_damping)
        # mass estimates stay within 0.1-10 x the nominal mass and within the vehicle ranges
        lo, hi = VEHICLE_RANGES["m_s"][:2]
        bounds = (max(0.1 * cfg.m_s_nominal, lo), min(10.0 * cfg.m_s_nominal, hi))
        self.mass_est = (MassEstimator(cfg.m_s_nominal, cfg.k_s, cfg.c_s, cfg.forgetting_factor,
                                       damping, m_bounds=bounds, acc_noise_std=cfg.acc_sprung_noise_std,
                                       defl_noise_std=cfg.defl_noise_std) if cfg.mass_estimator == 1 else None)
        # codes beyond the KF family: an estimator of the registry (interface.py)
        factory = composed_factory(int(cfg.road_estimator), int(cfg.mass_estimator))
        if factory is not None:
            self.road: RoadFilter = factory(cfg)
        elif cfg.road_estimator == 2:
            self.road = AnchoredRoad(cfg, self.mass_est)
        else:
            self.road = KFRoad(cfg)
        self.classifier = RoadClassifier(gain=cfg.tuning.class_gain)
        self.iri = IRIMeter(cfg.iri_segment, start=0.0)  # raises a ValueError naming iri_segment
        self.motion = STANDING
        # road_height_est (road_profile.Profiler): the KF family's road model has a common-mode
        # reference to take off, the estimators of the registry none
        self.profile = Profiler(cfg.profile_cutoff, self.road.reference)
        self.time = 0.0  # s
        self._speed_last = 0.0  # m/s, the last finite speed
        self.distance = 0.0  # m
        n_z = 3 if cfg.tuning.use_deflection else 2
        self._z_last = [math.nan] * n_z
        self._same_time = [0.0] * n_z
        self.outputs: dict[str, float] = {}

    # the KF family's filters and counters (kf_road.py, anchored_road.py); None or 0 otherwise
    kf = _kf_family("kf", doc="the road filter's KF (road_estimator 2: the force-error filter)")
    anchor = _kf_family("anchor", doc="road_estimator 2: the anchor's KF")
    anchor_model = _kf_family("anchor_model")
    model = _kf_family("model", doc="the road filter's model (model.DiscreteModel)")
    R = _kf_family("R", doc="the measurement covariance of the road filter")
    n_states = _kf_family("n_states")
    refilters = _kf_family("refilters", 0)
    anchor_resets = _kf_family("anchor_resets", 0)
    anchor_trusted = _kf_family("anchor_trusted", False)

    @property
    def composed(self) -> RoadFilter | None:
        """The estimator of the registry (codes beyond the KF family), or None."""
        return None if isinstance(self.road, KFRoad) else self.road

    @property
    def check(self):
        """The road filter's self-diagnosis (sensor_check.InnovationCheck), or None."""
        return self.road.check

    @property
    def m_model(self) -> float:
        """kg, the sprung mass of the road filter's model (given to it)."""
        m = self.road.m_model
        return float(self.cfg.m_s_nominal) if m is None else m

    @property
    def c_model(self) -> float:
        """N.s/m, the damping of the anchor's model (identified; c_s without an anchor)."""
        return self.road.c_model if isinstance(self.road, KFRoad) else float(self.cfg.c_s)

    @property
    def mass_rebuilds(self) -> int:
        """Changes of the road filter's mass by the mass feedback."""
        return self.road.mass_rebuilds

    @property
    def model_builds(self) -> int:
        return self.road.model_builds

    @property
    def assumed_class(self) -> int:
        if self.cfg.road_class > 0:
            return int(self.cfg.road_class)
        return self.classifier.road_class or int(self.cfg.tuning.default_class)

    def reset_state(self, from_rest: bool = False) -> None:
        """The road filter back to its start state (``from_rest``: a car at rest) and the
        profile's input restarted."""
        if from_rest:
            self.road.restart()
        else:
            self.road.reset()
        self.profile.restart()

    # --- one sample ------------------------------------------------------------------------
    def step(self, acc_sprung: float, acc_unsprung: float, deflection: float, speed: float,
             h: float) -> dict[str, float]:
        """Process one sample: accelerations (m/s^2), deflection z_s - z_u (m), speed (m/s),
        step h (s) since the previous sample. Returns the contract's outputs (SI units). A step
        that differs from the road filter's by rounding only is the filter's step
        (plant.step_size)."""
        cfg = self.cfg
        if not (math.isfinite(h) and h > 0):
            raise ValueError(f"step size h = {h!r} must be finite and > 0")
        if self._aligners is not None:  # the known calibration (EstimatorConfig)
            self._sample_time += h
            t = self._sample_time
            acc_sprung, acc_unsprung, deflection = self.sensors.remove(
                *(line.push(t, float(v)) for line, v in zip(self._aligners, (acc_sprung, acc_unsprung, deflection))))
        if math.isfinite(speed):  # a speed that is not finite keeps the last motion
            self.motion = MOVING if abs(speed) >= cfg.tuning.standstill_speed else STANDING
        acc_sprung, acc_unsprung = self._standstill_bias(acc_sprung, acc_unsprung, h)
        f = self.road
        if f.h is not None:
            h = same_step(h, f.h)
        speed = abs(float(speed)) if math.isfinite(speed) else f.missing_speed(self._speed_last)
        self._speed_last = speed
        ds = speed * h if self.motion == MOVING else 0.0  # m, the distance the profile counts
        vals = (float(acc_sprung), float(acc_unsprung), float(deflection))
        if not cfg.tuning.use_deflection:
            vals = vals[:2]
        self.time += h
        self.distance += speed * h
        live = self._live(vals, h)
        rows = None if all(live) else np.flatnonzero(live)
        used, restarted = f.checked_step(np.array(vals), rows, speed, h, ds)
        status = STATUS_REINIT if restarted else STATUS_OK if used is None else STATUS_REJECTED
        me = self.mass_est
        if f.mass is not None:
            mass = float(f.mass)
        elif me is not None:
            self._update_mass(me, vals, float(deflection), live, used, status, h)
            f.feed_back_mass(me, h, speed, self.time)
            mass = float(me.mass)
        else:
            mass = float(cfg.m_s_nominal)
        f.finish_step(h, ds)
        x = state_list(f.x)
        if status != STATUS_REINIT:
            before = self.classifier.road_class
            if self.classifier.update(self.distance, x[IZR], speed) != before:
                f.set_road_class(self.classifier.road_class)
        out = self.outputs
        shift = f.z_shift
        out["road_velocity_est"] = x[IVR]
        out["z_s_est"] = x[IZS] if shift is None else x[IZS] + shift
        out["v_s_est"] = x[IVS]
        out["z_u_est"] = x[IZU] if shift is None else x[IZU] + shift
        out["v_u_est"] = x[IVU]
        out["susp_deflection_est"] = x[IZS] - x[IZU]
        out["tire_deflection_est"] = x[IZU] - x[IZR]
        out["sprung_mass_est"] = mass
        out["mass_std"] = float(me.mass_std(h)) if f.mass is None and me is not None else 0.0
        out["road_class_est"] = int(self.classifier.road_class if f.road_class is None else f.road_class)
        out["nis"] = float(f.nis)  # of the last update
        fault = f.check is not None and f.check.state == INCONSISTENT
        out["status"] = STATUS_SENSOR if fault and status != STATUS_REINIT else status
        var = float(f.road_variance)
        self._profile(out, x[IZR], speed, h, var if var > 0.0 else math.inf, status)
        if fault:
            # the filter's covariance no longer describes its error: what is known without the
            # sensors, |error| <= |estimate| + |profile|, the profile within 2 x the band rms of
            # the roughest class in sight on 95 % of samples
            cls = max(self.assumed_class, self.classifier.road_class)
            out["road_height_std"] = max(out["road_height_std"], abs(out["road_height_est"])
                                         + class_band_rms(cls, cfg.profile_cutoff))
        out["iri_est"] = self.iri.update(self.distance, out["road_height_est"])
        return out

    def _update_mass(self, me: MassEstimator, vals: tuple[float, ...], deflection: float, live: list[bool],
                     used: np.ndarray | None, status: int, h: float) -> None:
        """Feed the mass regression: the sample, or for a body acceleration or deflection the
        road filter left out its ``substitutes`` (then not used in the regression)."""
        t = self.cfg.tuning
        ok = [used is None or bool(i in used) for i in range(len(vals))]
        ok_a = ok[0]
        ok_d = ok[2] if t.use_deflection else math.isfinite(deflection)
        if (not (ok_a and ok_d) and live[0] and (live[2] if t.use_deflection else ok_d)
                and abs(me.mass - self.m_model) > t.mass_trust_sensors * self.m_model):
            # the road filter rejects a live sensor while the mass estimate already says its
            # model mass is off: the model, not the sensor, is the likely culprit, and the
            # RLS (whose regressor does not use the road filter) must go on learning, else a
            # wrong mass on a rough road locks itself in (rejections -> no mass update)
            ok_a = ok_d = True
        a_use, d_use = vals[0], deflection
        if not (ok_a and ok_d):
            a_sub, d_sub = self.road.substitutes()
            a_use, d_use = (a_use if ok_a else a_sub), (d_use if ok_d else d_sub)
        me.update(a_use, self._mass_deflection(d_use), h, use=ok_a and ok_d and status != STATUS_REINIT
                  and self.motion == MOVING)

    def _mass_deflection(self, d: float) -> float:
        """The deflection (m) the mass regression pairs with this sample's body acceleration: the
        sample itself, or with accelerations averaged over the step (acc_sampling 1) the mean of
        this and the last sample, which refers to the same mid-step instant as the average. Paired
        with the end-of-step deflection the average lags it by half a step, and the regression's
        damping term, in quadrature with the acceleration, takes that lag up: at 5 and 10 ms the
        identified damping came out 21 / 24 % low and the mass 11 / 21 % (ISO C, 40 km/h)."""
        if self.acc_sampling != 1:
            return d
        last, self._d_last = self._d_last, d
        return d if last is None or not math.isfinite(last) else 0.5 * (d + last)

    def _standstill_bias(self, a_s: float, a_u: float, h: float) -> tuple[float, float]:
        """The accelerations less the biases learned while the car stood (standstill_bias.py).
        The biases in use change when the car moves off after a stand; at its first move (the
        road filter has seen only the standing car) the road filter restarts from rest, so that
        the bias it integrated while standing leaves nothing behind."""
        learner = self.standstill
        standing = self.motion == STANDING
        was_standing = learner.standing_for > 0.0
        learner.step(standing, a_s, a_u, h)
        if not standing and was_standing and learner.state == LEARNED:
            self.bias_removed = learner.removable
            if not self._moved:
                self.reset_state(from_rest=True)
        if not standing:
            self._moved = True
        b_s, b_u = self.bias_removed
        return a_s - b_s, a_u - b_u

    def _profile(self, out: dict, road: float, speed: float, h: float, var: float, status: int) -> None:
        """road_height_est and road_height_std: the profile (road_profile.Profiler) of the road
        filter's road ``road`` (m); it holds while the car stands (the road under the tyre does not
        change then; the estimate's drift does not count). ``var`` (m^2): the variance of the band
        error; held while standing."""
        moving = self.motion == MOVING
        # a re-initialised filter restarts the profile's input, as a sample that is not finite
        out["road_height_est"] = self.profile.step(math.nan if status == STATUS_REINIT else road, h,
                                                   abs(speed) * h if moving else 0.0)
        if moving or "road_height_std" not in out:
            out["road_height_std"] = math.sqrt(var) if var >= 0.0 else math.inf

    def _live(self, vals: tuple[float, ...], h: float) -> list[bool]:
        """Per channel: finite and not frozen. Frozen = the value has not changed (bit for bit)
        for frozen_time s: a noisy sensor never repeats itself, a stuck or disconnected one does."""
        last, same, lim = self._z_last, self._same_time, self.cfg.tuning.frozen_time
        ok = []
        isfinite = math.isfinite
        for i, v in enumerate(vals):
            if v == last[i]:
                same[i] += h
                ok.append(isfinite(v) and same[i] < lim)
            else:
                same[i] = 0.0
                last[i] = v
                ok.append(isfinite(v))
        return ok


preload()  # every estimator's module, while the folder this package was loaded from exists
