"""SuspensionEstimator: road profile (KF, MME&KF, or the robust default) + sprung mass (RLS) +
online ISO class.

Road estimators (contract ``road_estimator``): 0 the KF of the exact linear model, 1 MME&KF,
2 (default) the robust combination of docs/robustness.md:

* the force-error filter (``self.kf``): the KF with the suspension-force error states of
  ``model.force_error_matrices`` (a fast error and a slow bias, which holds the mean force of
  an asymmetric damper's jacking that the linear spring would read as a road offset); its road follows from the whole-corner force balance
  m_s a_s + m_u a_u = k_t (z_r - z_u), which holds for any spring and damper law, so a wrong
  c_s or k_s costs little in band. It gates, rejects and re-filters as the KF does;
* the anchor (``self.anchor``): the exact-model KF built at the identified mass and damping
  (``MassEstimator`` with ``estimate_damping``: the since-change least squares of [m_s, c]),
  run on the same update decisions. The force-error filter's free force error leaves the
  body's absolute position to the double-integrated accelerometer (raw road error ~38 mm
  against ~4 mm on ISO C at 40 km/h); below ``blend_hz`` the road, body and wheel heights are
  the anchor's (a second-order low-pass of their difference is added), and each step the
  force-error filter's common velocity is pulled towards the anchor's (``align_hz``);
* after an update without every channel the output is the anchor's and fades back over
  ``anchor_hold`` s (the force-error filter needs all three channels), and both filters
  restart at their fixed points when it ends. ``road_height_std`` follows the anchor's P;
* the anchor restarts from the force-error filter's state when the two disagree by more than
  ``anchor_gate`` times the force-error filter's own std (road height or body velocity): its
  linear spring and damper are then wrong at low frequency (a nonlinear suspension). Not in the
  first ``START_DISAGREE_SPAN`` s, where a disagreement that outlasts the identification of the
  damping drops the anchor and re-filters the start without it.

The FMU adapter calls ``SuspensionEstimator(config).step(acc_sprung, acc_unsprung, deflection,
speed, h)`` once per doStep; it returns a dict keyed by the contract's output names. The
estimate refers to the instant of the measurement passed in (filtered estimate x_{k|k}).

The road output. ``road_height_est`` is the road profile as inertial profilers report it: the
filter's road, freed of its common-mode reference (road_profile.Profiler), high-passed in
distance at ``profile_cutoff`` (plant.profile_band, third order), fed while the car moves
(``_profile``); harness.metrics.reference_profile gives it from a true profile.
``road_height_std`` is the filter's P scaled to the steady-state error in that band with the
allowance for the sensors' calibration (``_band_ratio``). The states z_s_est, z_u_est stay
relative to the reference, with the filter's low-frequency lag added back (``_lag_rate``).

Mass feedback. The road filter is rebuilt at ``MassEstimator.mass_slow`` (least squares over
all data since the last detected payload change) when it differs from the model mass by more
than max(0.1 %, 3 standard errors); the reported ``sprung_mass_est`` stays the paper's fast
forgetting-factor RLS. Feeding back the fast RLS with a 2 % dead band left the model up to 2 %
off for the whole run and let spurious covariance resets on smooth roads (an RLS excursion to
268 kg on ISO B) rebuild the filter mid-run: on ISO B a 0.6 % model-mass error alone costs about
2 % of the road in band, because the body-acceleration mismatch integrates into the unobservable
common velocity. Joint / true-mass HP error on ISO B went from 1.40 (590 kg) and 1.20 (230 kg)
to about 1.0.

Bad samples. Each channel is checked every step: non-finite, or frozen (bit-identical for
``frozen_time`` s: a noisy sensor never repeats itself) channels are left out of the update; if
the full update's NIS exceeds ``outlier_nis`` it is undone and the channels whose own normalised
innovation exceeds it are left out. The filter updates with the remaining channels (or predicts
through when none is left) and ``status`` = 1. The mass regression skips substituted samples
(the road filter's prediction feeds the state-variable filters instead) and a short guard after
them. Re-initialisation (``status`` = 2) only when every finite channel has disagreed with the
prediction for ``reinit_after`` s (a diverged filter), not after a burst on one channel.
"""
from __future__ import annotations

import copy
import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import butter

from ..plant import iso8608
from ..plant.iri import SEGMENT_RANGE, IRIMeter
from ..plant.profile_band import CUTOFF_RANGE, PROFILE_CUTOFF, class_band_rms
from ..plant.quarter_car import NOISE_STD_RANGES
from ..plant.sensors import CALIBRATION_ALLOWANCE, SENSOR_ERROR_RANGES, DelayLine, SensorErrors
from ..plant.step_size import same_step
from ..plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER
from ..plant.vehicle import Vehicle, VEHICLE_RANGES, check_range

from .airspring_observers import config_problems
from .imm_filter import imm_problems
from .interface import RoadFilter, code_problems, composed_factory, preload, state_list
from .kalman import LinearKF, MMEKF
from .mass import MassEstimator
from .model import (IVR, IVS, IVU, IZR, IZS, IZU, N_STATES, N_STATES_AVG, DiscreteModel,
                    held_input_matrix, measurement_covariance)
from .road_class import RoadClassifier
from .road_profile import Profiler
from .sensor_check import INCONSISTENT, InnovationCheck
from .standstill_bias import LEARNED, StandstillBias
from .steady_state import band_error_budget, reference_lag
from .tuning import TUNING, TUNING_FIELDS, Tuning
from .vb_akf import vb_problems

OUTPUTS = ("road_height_est", "road_velocity_est", "road_height_std", "z_s_est", "v_s_est",
           "z_u_est", "v_u_est", "susp_deflection_est", "tire_deflection_est", "sprung_mass_est", "mass_std",
           "road_class_est", "nis", "status", "iri_est")

STATUS_OK, STATUS_REJECTED, STATUS_REINIT, STATUS_SENSOR = 0, 1, 2, 3
# the car's motion, from the speed each step (Tuning.standstill_speed): standing, the mass
# regression is not fed and the road profile holds
MOVING, STANDING = "moving", "standing"
# road_estimator 2: this many anchor restarts within this many seconds and the anchor is no longer
# used (linear plant: 0-7 restarts in 40 s with a vehicle 30 % off; air spring + asymmetric
# damper: ~30 per second)
ANCHOR_DISTRUST_RESETS, ANCHOR_DISTRUST_SPAN = 20, 10.0
# ... of which this many since the damping was identified: before, the anchor runs at the nominal
# c_s, and a damper 30 % off restarts it too (ISO D, 40 km/h: 20 restarts in the first 5 s, the
# anchor dropped, raw error 38-82 % and 2-sigma coverage 0-48 %; 7-8 % and 92-100 % kept)
ANCHOR_DISTRUST_IDENTIFIED = 5
# road_estimator 2: no pull of the force-error filter's common velocity towards the anchor's
# (align_hz) within this many s of an anchor restart: a restarting anchor is wrong at low
# frequency, and the pull carried its error into the force-error filter, which keeps it once the
# anchor is dropped (air-spring plant, ISO C, 40 km/h, 40 s, seeds 1-4: raw rms error 369 / 46 /
# 85 / 79 mm with the pull, 50 / 9 / 43 / 34 mm without; 1, 2 and 5 s gave the same). Linear
# plants without restarts are unchanged; "all -" seed 2, which restarts: 9.8 -> 11.6 mm).
# Not within ALIGN_AFTER_FAULT s of an update without every channel: restarts after a sensor
# fault mean the force-error filter was kicked, and the pull is what brings it back (deflection
# frozen for 100 ms on the exact vehicle: raw error after it 10.4 mm with the pull, 16.8 mm
# without)
ALIGN_QUIET = 1.0
ALIGN_AFTER_FAULT = 2.0
# road_estimator 2 with the damping estimated: within this many s of the start the anchor is not
# restarted when it disagrees with the force-error filter (both are in their start transients, and
# the anchor runs at the nominal c_s until the damping is identified, 1.6-2.0 s into the data).
# Restarting it from the force-error filter's state 12 times in 1.8 s left it 85 mm off on a 3 %
# grade with c_s -30 % (both filters lag the car's 0.33 m/s rise by 40-60 mm/s then): raw error
# 48.6 mm rms, 2-sigma coverage 0, which road_height_std did not say. Without restarts, and with
# the velocity pull of _align on, a linear plant's disagreement (up to 17-36 times the
# force-error filter's own velocity std) is gone once the damping is identified (below 1 after
# 2 s); the air spring's goes on at 13-100 times. So a disagreement for START_DISAGREE_DROP s
# (leaky count: -h per agreeing step) after the damping is identified drops the anchor, and the
# start is re-filtered with the force-error filter alone, without the pull that carried the
# anchor's error into it until then. Cores, ISO B-D at 40 and 80 km/h, 3 seeds: D 80 "all -" raw
# error 17.9 -> 2.8 mm, coverage 0.797 -> 1.000; the other linear cells unchanged; air spring raw
# 22-28 mm and coverage 0.80-1.00 as before
START_DISAGREE_SPAN = 4.0
START_DISAGREE_DROP = 0.5  # s
START_FADE = 0.25  # s, the output's move to and from the force-error filter alone at the start


def _apply(kf: LinearKF, z: np.ndarray, rows) -> None:
    """One step of ``kf``: rows None = full update, else predict and update these rows (if any)."""
    if rows is None:
        kf.step(z)
    else:
        kf.predict_only()
        if len(rows):
            kf.update_rows(z, rows)


def _checked_ratio(var: float, P: np.ndarray) -> float:
    """var (m^2) over the filter's P[z_r, z_r]; 1 (keep P) where that is garbage from an
    ill-conditioned vehicle (P not positive, a ratio beyond 1e3)."""
    ratio = var / float(P[IZR, IZR]) if P[IZR, IZR] > 0 else math.nan
    return ratio if 0.0 < ratio <= 1e3 else 1.0


class Blend:
    """Second-order Butterworth low-pass (corner ``hz``) of a scalar, one sample per step of h s
    (coefficients of scipy.signal.butter, direct form II transposed); ``y`` the last output."""

    def __init__(self, hz: float):
        self.hz = float(hz)
        self._h = None
        self._b = self._a = None  # the filter's coefficients at step _h
        self.reset()

    def reset(self) -> None:
        self.s1 = self.s2 = self.y = 0.0

    def copy(self) -> "Blend":
        b = Blend.__new__(Blend)
        b.__dict__.update(self.__dict__)
        return b

    def step(self, u: float, h: float) -> float:
        if h != self._h:
            b, a = butter(2, self.hz, fs=1.0 / h)
            self._b, self._a, self._h = tuple(b.tolist()), tuple(a.tolist()), h
        (b0, b1, b2), (_, a1, a2) = self._b, self._a
        y = b0 * u + self.s1
        self.s1 = b1 * u - a1 * y + self.s2
        self.s2 = b2 * u - a2 * y
        self.y = y
        return y


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


class SuspensionEstimator:
    """Joint road-profile, state, sprung-mass and ISO-class estimator (see the package doc)."""

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
        # codes beyond the KF family: an estimator of the registry (interface.py), composed here
        factory = composed_factory(int(cfg.road_estimator), int(cfg.mass_estimator))
        self.composed: RoadFilter | None = None if factory is None else factory(cfg)
        self.R = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std,
                                        cfg.defl_noise_std if cfg.tuning.use_deflection else None)
        dim_z = self.R.shape[0]
        self.acc_sampling = int(cfg.acc_sampling)
        self.n_states = N_STATES_AVG if self.acc_sampling == 1 else N_STATES
        self._noise = cfg.tuning.model_noise
        self._force_states = 0
        if cfg.road_estimator == 2:  # the suspension-force error states, appended last
            self._noise = replace(cfg.tuning.model_noise, q_f=float(cfg.tuning.force_error_q),
                                  q_b=float(cfg.tuning.force_bias_q), tau_b=float(cfg.tuning.force_bias_tau))
            self._force_states = self._noise.force_states
            self.n_states += self._force_states
        damping = cfg.road_estimator == 2 if cfg.tuning.estimate_damping is None else bool(cfg.tuning.estimate_damping)
        self._road_hold = bool(cfg.tuning.road_hold == 1 or (cfg.tuning.road_hold == -1 and self.acc_sampling == 1))
        if cfg.road_estimator == 1:
            self.kf: LinearKF = MMEKF(self.n_states, dim_z, W=cfg.tuning.mme_weight, freeze_tol=cfg.tuning.freeze_tol,
                                      fast=cfg.tuning.fast_gain, direct=self.acc_sampling == 0)
        else:
            self.kf = LinearKF(self.n_states, dim_z, freeze_tol=cfg.tuning.freeze_tol, fast=cfg.tuning.fast_gain)
        self.kf.R = self.R
        # road_estimator 2: the exact-model KF at the identified mass and damping runs alongside
        # and gives the road below ``blend_hz`` (module doc); it gets the same update decisions
        self.anchor: LinearKF | None = None
        self.anchor_model: DiscreteModel | None = None
        if cfg.road_estimator == 2:
            self.anchor = LinearKF(self.n_states - self._force_states, dim_z, freeze_tol=cfg.tuning.freeze_tol, fast=cfg.tuning.fast_gain)
            self.anchor.R = self.R
        self._blend = Blend(cfg.tuning.blend_hz)
        self._hold_left = 0.0  # s of the anchor hold left (see _after_update)
        self.anchor_resets = 0
        self._resets_identified = 0  # anchor restarts since the damping was identified
        self._reset_times: deque = deque()
        self._disagree_for = 0.0  # s, leaky count of disagreement once the damping is identified
        self._replaying = False  # a re-filter is replaying buffered steps
        self._refilter_start = False  # the anchor was dropped at the start: re-filter without it
        self._start_gap_until = -math.inf  # s, end of the start disagreement's hold
        # road_estimator 2, damping estimated: the force-error filter without the velocity pull,
        # run through the start (START_DISAGREE_SPAN), and its weight in the output
        self._start_kf: LinearKF | None = None
        self._start_w = 0.0
        self._last_partial = -math.inf  # s, the last update without every channel
        self.anchor_trusted = self.anchor is not None
        self._nonlinear = False  # the anchor was dropped (see _blend_step)
        # mass estimates stay within 0.1-10 x the nominal mass and within the vehicle ranges
        lo, hi = VEHICLE_RANGES["m_s"][:2]
        bounds = (max(0.1 * cfg.m_s_nominal, lo), min(10.0 * cfg.m_s_nominal, hi))
        self.mass_est = (MassEstimator(cfg.m_s_nominal, cfg.k_s, cfg.c_s, cfg.forgetting_factor,
                                       damping, m_bounds=bounds, acc_noise_std=cfg.acc_sprung_noise_std,
                                       defl_noise_std=cfg.defl_noise_std) if cfg.mass_estimator == 1 else None)
        # the episode at the start of the run spans damping_refilter_span (see _span), and the
        # anchor is not restarted in the first START_DISAGREE_SPAN s (_blend_step)
        self._long_start = bool(self.anchor is not None and self.mass_est is not None
                                and self.mass_est.estimate_damping)
        self.classifier = RoadClassifier(gain=cfg.tuning.class_gain)
        self.iri = IRIMeter(cfg.iri_segment, start=0.0)  # raises a ValueError naming iri_segment
        self.motion = STANDING
        # road_height_est (road_profile.Profiler): the KF family's road model has a common-mode
        # reference to take off, the estimators of the registry none
        rm = cfg.tuning.road_model
        self._reference = (rm.f_ref, rm.zeta_ref) if self.composed is None and rm.f_ref > 0 else None
        self.profile = Profiler(cfg.profile_cutoff, self._reference)
        self._gap_profile = Profiler(cfg.profile_cutoff, self._reference)  # of _start_output's gap
        # self-diagnosis (sensor_check.py) of the linear filters; MME&KF's model-error injection
        # is not in the check's error responses. The check allows at least the default calibration
        # errors: on ideal sensors the exact model's deflection innovations reach 1.9-3.1 x S over
        # 1 s windows (ISO C at 40, D at 80 km/h), which only the allowance's share explains
        gain_std, delay_std = (max(getattr(cfg, k), CALIBRATION_ALLOWANCE[k][0])
                               for k in ("calibration_gain_std", "calibration_delay_std"))
        self.check = (InnovationCheck(dim_z, 2, gain_std, delay_std,
                                      cfg.tuning.diagnosis_window, cfg.tuning.diagnosis_limit,
                                      cfg.tuning.diagnosis_hold * cfg.profile_cutoff, cfg.tuning.diagnosis_start,
                                      (1,), cfg.tuning.diagnosis_mean_limit)
                      if cfg.road_estimator != 1 else None)
        self._band_cache: tuple | None = None  # (model, class, ratio): see _band_ratio
        self.model: DiscreteModel | None = None
        self._model_key: tuple | None = None
        self.m_model = float(cfg.m_s_nominal)
        self.c_model = float(cfg.c_s)  # damping of the anchor filter's model (identified)
        self.time = 0.0
        self._h: float | None = None  # s, the step of the last sample
        self._speed_last = 0.0  # m/s, the last finite speed (composed estimators)
        self.distance = 0.0
        self._rejected_time = 0.0
        self._outlier_time = [0.0] * self.R.shape[0]  # s of the current outlier streak per channel
        self._z_last = [math.nan] * self.R.shape[0]
        self._same_time = [0.0] * self.R.shape[0]
        self._last_rebuild = -math.inf
        self.outputs: dict[str, float] = {}
        # re-filtering buffers (see the module doc): recorded measurements and update decisions,
        # periodic snapshots of the filter, the onset of the current mass change
        self._steps = 0
        self._epoch_step = 0  # step of the last model rebuild for a reason other than the mass
        self._record: deque = deque()
        self._snaps: deque = deque()
        self._onset = 0.0  # start of the current mass-change episode (s)
        self._confirmed_for = 0.0  # s the model mass has agreed with the data without a break
        self._resets_seen = 0
        self.refilters = 0
        self.model_builds = 0  # discretisations of the road filter's model (each costs ~1-3 ms)
        self.mass_rebuilds = 0  # changes of the model mass by the mass feedback
        self._lag: tuple | None = None  # (model, q): see _lag_rate
        self.reset_state(from_rest=True)

    # --- state -----------------------------------------------------------------------------
    def reset_state(self, from_rest: bool = False) -> None:
        """Zero state at the stationary covariance of the model (before the first step, when
        there is no model yet: body and wheel known to 0.1 mm / 0.1 mm/s, road to 1 cm / 0.1 m/s;
        the first step builds the model and sets the stationary covariance). ``from_rest``: the
        start of a run, from a car at rest (the relative states are then known exactly)."""
        n = self.n_states
        kf = self.kf
        kf.x = np.zeros(n)
        self.profile.restart()
        self._blend.reset()
        self._hold_left = 0.0
        if self.anchor is not None:
            a = self.anchor
            na = a.dim_x
            a.x, a.P_post = np.zeros(na), None
            a.unfreeze()
            if self.anchor_model is None or not a.stationary():
                a.P = np.diag(([1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-1] + [1e-4] * n)[:na]) ** 2
        self._x_int = 0.0  # m, integral of q x since the (re)start (steady_state.reference_lag)
        kf.P_post = None
        kf.unfreeze()
        if self.model is None or not kf.stationary():
            kf.P = np.diag(([1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-1] + [1e-4] * n)[:n]) ** 2
        self._start_kf = copy.deepcopy(kf) if from_rest and self._long_start else None
        self._start_w = 0.0
        self._record.clear()
        self._snaps.clear()
        # before the first model the filter is due to start at that model's fixed point
        self._snap(stationary=self.model is None or kf.stationary_now)

    def _lag_rate(self) -> float:
        """Rate q (1/s) by which the active filter's road misses the common-mode reference below
        its band (steady_state.reference_lag), for z_s_est and z_u_est; recomputed (about 1 ms)
        when the model changes; 0 for MME&KF (not this filter form) or without a fixed point."""
        kf, m = (self.anchor, self.anchor_model) if self.anchor_trusted else (self.kf, self.model)
        hit = self._lag
        if hit is not None and hit[0] is m:
            return hit[1]
        sol = None if m is None else kf.stationary_solution
        q = 0.0
        if sol is not None and not isinstance(kf, MMEKF):
            rm = self.cfg.tuning.road_model
            q = reference_lag(m.Phi, m.H, sol[0], m.h, rm.f_ref, rm.zeta_ref, m.vehicle, self.acc_sampling, IZR)
        self._lag = (m, q)
        return q

    def _snap(self, stationary: bool | None = None) -> None:
        kf, a = self.kf, self.anchor
        st = kf.stationary_now if stationary is None else stationary
        # at a (re)start (``stationary`` given) the anchor too is due to start at its model's
        # fixed point: restored with its placeholder P instead, a re-filter from this snapshot
        # left it with a covariance minutes from settling (3 % grade at 72 km/h, a mass change
        # detected at 0.3 s: road_height_std 0.001 mm, raw error 16 mm)
        ast = None if a is None else (a.stationary_now if stationary is None
                                      else self.anchor_model is None or a.stationary_now)
        anchor = None if a is None else (a.x.copy(), a.P.copy(), ast)
        self._snaps.append((self.time, self._steps, kf.x.copy(), kf.P.copy(), st, anchor, self._blend.copy(),
                            self._hold_left))

    @property
    def assumed_class(self) -> int:
        if self.cfg.road_class > 0:
            return int(self.cfg.road_class)
        return self.classifier.road_class or int(self.cfg.tuning.default_class)

    def _ensure_model(self, speed: float, h: float) -> None:
        key = self._model_key  # (h, class, speed band, mass) the model was last checked for
        cls = self.cfg.road_class or self.classifier.road_class or self.cfg.tuning.default_class
        if key is not None and h == key[0] and cls == key[1] and self.m_model == key[4] and self.c_model == key[5]:
            v = abs(speed)
            if key[2] <= (v if v > 0.1 else 0.1) <= key[3]:
                return
        self._check_model(speed, h)
        m, tol = self.model, self.cfg.tuning.speed_rebuild_tol
        self._model_key = (h, cls, m.speed - tol * m.speed, m.speed + tol * m.speed, self.m_model, self.c_model)

    def _check_model(self, speed: float, h: float) -> None:
        m = self.model
        cls = self.assumed_class
        gd = iso8608.class_psd_n0(max(cls, int(self.cfg.tuning.q_class_min)))
        v = max(abs(speed), 0.1)
        same_rest = (m is not None and m.h == h and m.gd_n0 == gd
                     and abs(v - m.speed) <= self.cfg.tuning.speed_rebuild_tol * m.speed)
        if same_rest and m.vehicle.m_s == self.m_model and (
                self.anchor_model is None or self.anchor_model.vehicle.c_s == self.c_model):
            return
        if not same_rest:
            self._epoch_step = self._steps  # steps before this one used another model
        if same_rest:
            v = m.speed  # a mass rebuild keeps the speed the buffered steps were filtered at
        self.model_builds += 1
        self.model = DiscreteModel.build(self.cfg.vehicle(self.m_model), v, gd, h,
                                         self.cfg.tuning.road_model, self._noise,
                                         self.cfg.tuning.use_deflection, self.acc_sampling,
                                         self._road_hold)
        if isinstance(self.kf, MMEKF):
            Gamma = np.zeros((self.n_states, 1))
            Gamma[:N_STATES] = held_input_matrix(self.model.A, self.kf.G[:N_STATES], h)
            self.kf.set_model(self.model.Phi, self.model.Q, self.model.H, self.R, Gamma=Gamma)
        else:
            self.kf.set_model(self.model.Phi, self.model.Q, self.model.H, self.R)
        self.kf.stationary()
        sk = self._start_kf
        if sk is not None:  # the same model and fixed point (kept while its state is its own)
            sk.set_model(self.model.Phi, self.model.Q, self.model.H, self.R)
            sk.share_fixed_point(self.kf)
            sk.stationary()
        if self.anchor is not None:
            am = self.anchor_model = DiscreteModel.build(
                replace(self.cfg.vehicle(self.m_model), c_s=self.c_model), v, gd, h, self.cfg.tuning.road_model,
                self.cfg.tuning.model_noise, self.cfg.tuning.use_deflection, self.acc_sampling, self._road_hold)
            self.anchor.set_model(am.Phi, am.Q, am.H, self.R)
            self.anchor.stationary()

    def _filter(self, z: np.ndarray, rows) -> None:
        """Replay one recorded step: rows None = full update, else the rows used (may be none)."""
        _apply(self.kf, z, rows)
        if self.anchor is not None:
            _apply(self.anchor, z, rows)
        self._after_update(rows is not None)
        self._blend_step()

    def _refilter(self, from_start: bool = False) -> bool:
        """Re-run the road filter (already rebuilt at the new mass) from the latest snapshot
        taken at or before the onset of the mass change, over the buffered measurements, with
        the recorded update decisions (full, some rows, none). Exact: the state AND covariance
        are then those the filter would have had with the new mass since the snapshot, so the
        common mode is not left where the wrong-mass innovations pushed it. False if no
        snapshot applies (too old, or the model changed for another reason since).
        ``from_start``: from the first snapshot of the run, if it is still kept."""
        onset = 0.0 if from_start else self._onset
        if not from_start and self.time - onset > self._span():
            return False
        snap = None
        for sn in self._snaps:
            if sn[0] <= onset + 1e-12:
                snap = sn
            else:
                break
        if snap is None or self._epoch_step > snap[1] + 1:
            return False
        _, k0, x0, P0, stationary, anchor, blend, self._hold_left = snap
        for kf, saved in ((self.kf, (x0, P0, stationary)), (self.anchor, anchor)):
            if kf is None or saved is None:
                continue
            x0, P0, stationary = saved
            kf.x, kf.P, kf.P_post = x0.copy(), P0.copy(), None
            kf.unfreeze()
            if stationary:  # at the old model's fixed point: start at the new model's
                kf.stationary()
        self._blend = blend.copy()
        self._replaying = True
        try:
            for k, z, rows in self._record:
                if k > k0:
                    self._filter(z, rows)
        finally:
            self._replaying = False
        self.refilters += 1
        return True

    def _after_update(self, partial: bool) -> None:
        """Anchor hold: after an update without every channel, the output is the anchor's and
        fades back to the force-error filter's over ``anchor_hold`` s, during which that filter
        keeps the anchor's common velocity (``_align``). The force-error filter needs all three
        channels (without a_s its force error is unobserved; without d nothing ties the body to
        the wheel); the anchor's model carries a missing channel (a deflection stuck for 4 s
        left the force-error filter at 26 % HP error, the anchor at 10 %)."""
        if not self.anchor_trusted:
            return
        if partial:
            self._last_partial = self.time
            self._hold_left = self.cfg.tuning.anchor_hold
        elif self._hold_left > 0.0:
            self._hold_left = max(self._hold_left - self._h, 0.0)
            if self._hold_left == 0.0:
                # both filters back at their fixed points: the force-error filter's covariance
                # would otherwise take minutes to return there along the weakly observable
                # common mode (running the full recursion all that time)
                for kf in (self.kf, self.anchor):
                    if not kf.stationary_now:
                        kf.stationary()
        if self._hold_left > 0.0:
            self._align()
        elif self.cfg.tuning.align_hz > 0.0 and not (
                self._reset_times and self.time - self._reset_times[-1] < ALIGN_QUIET
                and self.time - self._last_partial > ALIGN_AFTER_FAULT):
            self._align(min(2 * math.pi * self.cfg.tuning.align_hz * self._h, 1.0))

    def _align(self, gain: float = 1.0) -> None:
        """After an update without every channel: give the force-error filter the anchor's
        common velocity (the same shift of v_s, v_u, v_r). Without the body acceleration its
        force error is unobserved, and the body velocity it then mis-predicts is the common mode
        that nothing but the 0.01 Hz reference corrects: 50 ms of NaN on a_s left a drift of
        twice the raw error 1-2 s later, in band too (its start passes the 0.2 Hz blend)."""
        a = self.anchor
        if a is not None:
            x = self.kf.x.copy()
            x[[IVS, IVU, IVR]] += gain * float(a.x[IVS] - x[IVS])
            self.kf.x = x

    def _blend_step(self) -> None:
        a = self.anchor
        if self.anchor_trusted:
            kf, g = self.kf, self.cfg.tuning.anchor_gate
            y = self._blend.step(float(a.x[IZR] - kf.x[IZR]), self._h)
            P = kf.P
            if g > 0 and (y * y > g * g * P[IZR, IZR] or (a.x[IVS] - kf.x[IVS]) ** 2 > g * g * P[IVS, IVS]):
                me = self.mass_est
                if (self._long_start and self.time < START_DISAGREE_SPAN
                        and self.time - self._last_partial > ALIGN_AFTER_FAULT):
                    self._start_gap_until = self.time + START_DISAGREE_DROP
                    # at the start both filters are in their start transients and the anchor
                    # runs at the nominal c_s until the damping is identified: a restart would
                    # copy the force-error filter's transient into the anchor. A disagreement
                    # that goes on once the damping is identified is a suspension that is not
                    # linear: the anchor is dropped and the start re-filtered without it
                    # (START_DISAGREE_SPAN). After a sensor fault the force-error filter was
                    # kicked, not the anchor: restarts as later in the run (ALIGN_AFTER_FAULT)
                    if me.damping_identified and not self._replaying:
                        self._disagree_for += self._h
                        if self._disagree_for >= START_DISAGREE_DROP:
                            self._distrust_anchor()
                            self._refilter_start = True
                    return
                # the anchor disagrees with the force-error filter beyond what the latter's own
                # error explains: its linear spring and damper are wrong at low frequency (a
                # nonlinear suspension): it restarts from the force-error filter's state
                # with the force-error filter's covariance of those states: the anchor takes
                # over its error (its low frequencies are loosely pinned), and road_height_std,
                # the anchor's, says so until the anchor has converged back (ISO D, 40 km/h,
                # every parameter off: 38 mm of error 5 s after such restarts against a std of 1 mm)
                n = a.dim_x
                a.restore(kf.x[:n].copy(), kf.P[:n, :n].copy(), False)
                a.P_post = None
                self._blend.reset()
                self.anchor_resets += 1
                recent = self._reset_times
                recent.append(self.time)
                if me is None or not me.estimate_damping or me.damping_identified:
                    self._resets_identified += 1
                while recent and recent[0] < self.time - ANCHOR_DISTRUST_SPAN:
                    recent.popleft()
                if len(recent) >= ANCHOR_DISTRUST_RESETS and self._resets_identified >= ANCHOR_DISTRUST_IDENTIFIED:
                    self._distrust_anchor()  # restarting does not help
            elif self._disagree_for > 0.0 and not self._replaying:
                self._disagree_for = max(self._disagree_for - self._h, 0.0)

    def _distrust_anchor(self) -> None:
        """The suspension is not linear at low frequency: from here on the output is the
        force-error filter's alone, at the nominal mass (its force-error state takes up a mass
        error too). With the nonlinear terms of the mass regression (mass.py) feeding the mass
        back made no difference to the road: air-spring plant, ISO C/D at 40/80 km/h, 2 seeds,
        HP error within +-0.5 points of the nominal mass's, mass within 0.8 % (2-3 % low on ISO D
        at 80 km/h)."""
        self.anchor_trusted = False
        self._nonlinear = True
        self._hold_left = 0.0
        self._start_kf = None  # the start is re-filtered without the anchor (_refilter_start)

    def _start_output(self, x: list, h: float) -> tuple[float, float]:
        """While the anchor disagrees with the force-error filter at the start (_blend_step), the
        output (``x``, changed in place) moves over START_FADE s to the force-error filter run
        without the pull towards the anchor (``_start_kf``), and back when they agree: which of
        the two is right is not known until the damping is identified. Returns (share, gap): the
        share of their road gap (m) the output may be off by, which road_height_std takes in the
        profile's band."""
        if self.time - self._last_partial <= ALIGN_AFTER_FAULT:
            # a sensor fault: the anchor carries the output (_after_update), and the filter
            # without the pull, which needs every channel as much as the force-error filter, is
            # of no further use
            self._start_kf, self._start_w = None, 0.0
            return 0.0, 0.0
        sk = self._start_kf
        target = 1.0 if self.time <= self._start_gap_until else 0.0
        w = self._start_w
        w = min(w + h / START_FADE, target) if target > w else max(w - h / START_FADE, target)
        self._start_w = w
        xs = sk.x.tolist()
        gap = x[IZR] - xs[IZR]
        if w == 0.0:
            if self.time >= START_DISAGREE_SPAN:
                self._start_kf = None  # the start is over
            return 0.0, gap
        for i in range(N_STATES):
            x[i] = w * xs[i] + (1.0 - w) * x[i]
        return max(w, 1.0 - w), gap

    def _episode_closed(self) -> bool:
        return (self._confirmed_for >= self.cfg.tuning.refilter_confirm
                or self.time - self._onset > self._span())

    def _span(self) -> float:
        """s after the onset of a mass-change episode within which a rebuild re-filters:
        ``refilter_span``, or ``damping_refilter_span`` for the episode at the start of the run
        when the damping is estimated: its first value comes 1.6-2.02 s into the data, at the
        edge of a 2 s span, and the mass rebuilds at it and after it belong to the same episode."""
        t = self.cfg.tuning
        if self._long_start and self._onset == 0.0 and not self._nonlinear:
            return max(t.refilter_span, t.damping_refilter_span)
        return t.refilter_span

    def _keep_snapshots(self) -> None:
        """Snapshot the filter every snapshot_interval s; drop what no re-filter can use."""
        cfg, snaps = self.cfg, self._snaps
        if snaps and self.time - snaps[-1][0] < cfg.tuning.snapshot_interval - 1e-12:
            return
        self._snap()
        old = self.time - self._span() - cfg.tuning.refilter_lookback
        while len(snaps) > 1 and snaps[1][0] <= old:
            snaps.popleft()
        rec, k0 = self._record, snaps[0][1]
        while rec and rec[0][0] <= k0:
            rec.popleft()

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

    def _channel_ok(self, z: np.ndarray) -> np.ndarray:
        """Per-channel outlier test against the prediction: y_i^2 / S_ii <= outlier_nis.

        S_ii is at most the stationary innovation variance of the model: while the filter
        predicts through rejected samples its own uncertainty grows, and the gate must not open
        because of that (a +100 g burst on the wheel passed after three rejected samples), for
        the first ``gate_hold`` s of an outlier streak on the channel. When
        the joint NIS failed but no channel does on its own, the worst channel is left out."""
        kf = self.kf
        xp = kf.F @ kf.x
        Pp = kf.F @ kf.P @ kf.F.T + kf.Q
        y = z - kf.H @ xp
        S = np.einsum("ij,jk,ik->i", kf.H, Pp, kf.H) + np.diag(kf.R)
        s_ss = kf.stationary_innovation_variance
        if s_ss is not None:
            hold = np.array(self._outlier_time) < self.cfg.tuning.gate_hold
            S = np.where(hold, np.minimum(S, s_ss), S)
        ratio = y * y / S
        ok = ratio <= self.cfg.tuning.outlier_nis
        if ok.all():
            ok[int(np.argmax(ratio))] = False
        return ok

    # --- one sample ------------------------------------------------------------------------
    def step(self, acc_sprung: float, acc_unsprung: float, deflection: float, speed: float,
             h: float) -> dict[str, float]:
        """Process one sample: accelerations (m/s^2), deflection z_s - z_u (m), speed (m/s),
        step h (s) since the previous sample. Returns the contract's outputs (SI units). A step
        that differs from the model's by rounding only is the model's step (plant.step_size)."""
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
        if self.composed is not None:
            return self._step_composed(acc_sprung, acc_unsprung, deflection, speed, h)
        if self.model is not None:
            h = same_step(h, self.model.h)
        if not math.isfinite(speed):
            speed = self.model.speed if self.model is not None else 0.0
        status = STATUS_OK
        vals = ((float(acc_sprung), float(acc_unsprung), float(deflection)) if cfg.tuning.use_deflection
                else (float(acc_sprung), float(acc_unsprung)))
        z = np.array(vals)
        self.time += h
        self._h = h
        self.distance += abs(speed) * h
        self._steps += 1
        self._ensure_model(speed, h)
        live = self._live(vals, h)
        all_live = all(live)
        valid = None if all_live else np.array(live)

        kf = self.kf
        x_prev, P_prev, st_prev = kf.x, kf.P, kf.stationary_now
        outliers = False  # some finite, live channel disagreed with the prediction
        if all_live:
            kf.step(z)
            if kf.nis > cfg.tuning.outlier_nis:
                # undo; find the outlying channels below and update with the others
                kf.restore(x_prev, P_prev, st_prev)
                valid = self._channel_ok(z)
                outliers = True
        if all_live and not outliers and self.check is not None:
            self.check.update(kf.y, kf.S, z - kf.y, kf.F, kf.K, kf.H, h,
                              abs(speed) * h if self.motion == MOVING else 0.0)
        if valid is not None and not valid.all():
            status = STATUS_REJECTED
            kf.predict_only()  # (MME&KF: no model-error injection without all channels)
            if valid.any():
                x_pred, P_pred = kf.x, kf.P
                kf.update_rows(z, np.flatnonzero(valid))
                if kf.nis > cfg.tuning.outlier_nis:  # the remaining channels disagree too: predict
                    kf.x, kf.P = x_pred, P_pred
                    valid[:] = False
        rejected_all = outliers and not valid.any()
        if outliers or any(self._outlier_time):
            ot = self._outlier_time
            for i in range(len(ot)):
                ot[i] = ot[i] + h if outliers and not valid[i] else 0.0
        rows = None if valid is None or valid.all() else np.flatnonzero(valid)
        a = self.anchor
        if a is not None:  # the same decisions as the road filter's
            _apply(a, z, rows)
            if self._start_kf is not None:
                _apply(self._start_kf, z, rows)
            self._after_update(rows is not None)
        if valid is None or valid.all():
            valid = (True, True, True)
        self._rejected_time = self._rejected_time + h if rejected_all else 0.0
        # a channel the filter has disagreed with for reinit_after s while the others agree: the
        # filter has drifted (e.g. after accepting the first samples of a burst), not the sensor
        if self._rejected_time >= cfg.tuning.reinit_after or max(self._outlier_time) >= cfg.tuning.reinit_after:
            self._outlier_time = [0.0] * len(self._outlier_time)
            # every finite channel disagrees with the prediction for reinit_after s: diverged
            self.reset_state()
            self._rejected_time = 0.0
            status = STATUS_REINIT
        if not math.isfinite(sum(kf.x.tolist()) + (0.0 if kf.frozen else float(kf.P.sum()))
                            + (0.0 if a is None else sum(a.x.tolist()) + (0.0 if a.frozen else float(a.P.sum())))):
            self.reset_state()
            status = STATUS_REINIT
        self._blend_step()
        if cfg.tuning.refilter_span > 0 and status != STATUS_REINIT:
            self._record.append((self._steps, z, rows))

        if self.mass_est is not None:
            # substitute the filter's own value for a rejected body acceleration or deflection
            ok_a = bool(valid[0])
            ok_d = bool(valid[2]) if cfg.tuning.use_deflection else math.isfinite(deflection)
            me = self.mass_est
            if (not (ok_a and ok_d) and live[0] and (live[2] if cfg.tuning.use_deflection else ok_d)
                    and abs(me.mass - self.m_model) > cfg.tuning.mass_trust_sensors * self.m_model):
                # the road filter rejects a live sensor while the mass estimate already says its
                # model mass is off: the model, not the sensor, is the likely culprit, and the
                # RLS (whose regressor does not use the road filter) must go on learning, else a
                # wrong mass on a rough road locks itself in (rejections -> no mass update)
                ok_a = ok_d = True
            # (road_estimator 2: the deflection from the anchor, whose model ties the body to the
            # wheel; the body acceleration from the force-error filter, which carries the force
            # error the anchor's model lacks)
            src = self.anchor if self.anchor_trusted else kf
            a_use = acc_sprung if ok_a else float(self.model.H[0] @ kf.x)
            d_use = deflection if ok_d else float(src.x[IZS] - src.x[IZU])
            me.update(a_use, self._mass_deflection(d_use), h, use=ok_a and ok_d and status != STATUS_REINIT
                      and self.motion == MOVING)
            if me.resets != self._resets_seen:  # a payload change detected
                self._resets_seen = me.resets
                if self._episode_closed():  # else: still part of the open one (e.g. the start)
                    self._onset = self.time - cfg.tuning.refilter_lookback
                    self._confirmed_for = 0.0
            if self._nonlinear and self.m_model != cfg.m_s_nominal:
                self.m_model = cfg.m_s_nominal  # see _blend_step
                self._ensure_model(speed, h)
            if self._refilter_start:
                # the force-error filter alone from the start, at the nominal mass: the pull
                # towards the anchor it had until now carried the anchor's error (module doc)
                self._refilter_start = False
                self._refilter(from_start=True)
            if cfg.mass_feedback and me.samples * h >= cfg.tuning.mass_warmup and not self._nonlinear:
                m, sd, agree = self._mass_agrees(me, h)
                # the model mass is confirmed by enough data: closes the re-filter episode
                # (road_estimator 2: and the damping estimated, whose first value also re-filters)
                agree_all = agree and math.isfinite(sd) and (self.anchor is None or me.damping_identified)
                self._confirmed_for = self._confirmed_for + h if agree_all else 0.0
                # outside a re-filter episode a rebuild cannot be re-filtered: only a large change
                # (the episode is looked at only when a rebuild is in question: not per step)
                if not agree and self.time - self._last_rebuild >= cfg.tuning.mass_rebuild_interval:
                    in_episode = cfg.tuning.refilter_span > 0 and not self._episode_closed()
                    if in_episode or abs(m - self.m_model) > cfg.tuning.mass_rebuild_tol_late * self.m_model:
                        self.m_model = m
                        self._last_rebuild = self.time
                        self.mass_rebuilds += 1
                        if cfg.tuning.refilter_span > 0:
                            self._ensure_model(speed, h)  # rebuild now and re-filter the change
                            if in_episode:
                                self._refilter()
                dc = abs(me.damping - self.c_model)
                t = cfg.tuning
                if (self.anchor is not None and dc > min(t.damping_rebuild_tol, t.damping_rebuild_tol_late) * self.c_model
                        and self.time - self._last_rebuild >= t.mass_rebuild_interval):
                    in_episode = t.refilter_span > 0 and not self._episode_closed()
                    if dc > (t.damping_rebuild_tol if in_episode else t.damping_rebuild_tol_late) * self.c_model:
                        self.c_model = me.damping  # the anchor filter at the identified damping
                        self._last_rebuild = self.time
                        self._ensure_model(speed, h)
                        if in_episode:
                            self._refilter()
        if cfg.tuning.refilter_span > 0:
            self._keep_snapshots()
        x = kf.x.tolist()
        if self.anchor_trusted:
            low = self._blend.y  # m, the anchor's road below blend_hz minus the road filter's
            x[IZR] += low
            x[IZS] += low
            x[IZU] += low
            w = self._hold_left / self.cfg.tuning.anchor_hold if self.cfg.tuning.anchor_hold > 0 else 0.0
            if w > 0.0:  # the anchor hold (_after_update)
                xa = self.anchor.x.tolist()
                x = [w * xa[i] + (1.0 - w) * x[i] for i in range(N_STATES)]
        start_var = 0.0
        if self._start_kf is not None:
            # the share of the two filters' road gap the output may be off by, in the profile's band
            share, gap = self._start_output(x, h)
            ds = abs(speed) * h if self.motion == MOVING else 0.0
            start_var = (share * self._gap_profile.step(gap, h, ds)) ** 2
        if status != STATUS_REINIT:
            self.classifier.update(self.distance, x[IZR], speed)
        out = self.outputs
        if status != STATUS_REINIT and math.isfinite(x[IZR]) and not isinstance(kf, MMEKF):
            # z_s_est and z_u_est relative to the reference: the filter's low-frequency lag added back
            self._x_int += self._lag_rate() * x[IZR] * h  # q at each step: no jump when q changes
        shift = self._x_int
        out["road_velocity_est"] = x[IVR]
        out["z_s_est"] = x[IZS] + shift
        out["v_s_est"] = x[IVS]
        out["z_u_est"] = x[IZU] + shift
        out["v_u_est"] = x[IVU]
        out["susp_deflection_est"] = x[IZS] - x[IZU]
        out["tire_deflection_est"] = x[IZU] - x[IZR]
        out["sprung_mass_est"] = float(self.mass_est.mass if self.mass_est is not None
                                       else cfg.m_s_nominal)
        out["mass_std"] = float(self.mass_est.mass_std(h)) if self.mass_est is not None else 0.0
        out["road_class_est"] = int(self.classifier.road_class)
        out["nis"] = float(kf.nis)  # of the last update (kept through rejected steps)
        fault = self.check is not None and self.check.state == INCONSISTENT
        out["status"] = STATUS_SENSOR if fault and status != STATUS_REINIT else status
        # a covariance that rounding has taken to 0 or below (or past the floats) claims nothing:
        # an infinite std, never a small one (seen on a 1 kg wheel damped at 1e5 N.s/m). Once the
        # anchor is dropped the band ratio takes the force errors as zero (the vehicle the
        # model's), and the filter's own P, whose force-error states carry them, is right in rms
        # but not in its tails (Tuning.nonlinear_std_factor)
        p_zr = float((self.anchor if self.anchor_trusted else kf).P[IZR, IZR])
        band_var = (p_zr * self._band_ratio() * (cfg.tuning.nonlinear_std_factor ** 2 if self._nonlinear else 1.0)
                    + start_var if p_zr > 0.0 else math.inf)
        self._profile(out, x[IZR], speed, h, band_var, status)
        if fault:
            # the filter's covariance no longer describes its error: what is known without the
            # sensors, |error| <= |estimate| + |profile|, the profile within 2 x the band rms of
            # the roughest class in sight on 95 % of samples
            cls = max(self.assumed_class, self.classifier.road_class)
            out["road_height_std"] = max(out["road_height_std"], abs(out["road_height_est"])
                                         + class_band_rms(cls, cfg.profile_cutoff))
        out["iri_est"] = self.iri.update(self.distance, out["road_height_est"])
        return out

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
                if self.composed is not None:
                    self.composed.reset()
                    self.profile.restart()
                else:
                    self.reset_state(from_rest=True)
        if not standing:
            self._moved = True
        b_s, b_u = self.bias_removed
        return a_s - b_s, a_u - b_u

    def _band_ratio(self) -> float:
        """Steady-state variance of the road error in the distance band of road_height_est
        (steady_state.band_error_budget: the ISO road of the assumed class and the sensor
        noise, the vehicle the model's) over the active filter's own P[z_r, z_r] (the anchor's,
        or the force-error filter's once the anchor is dropped), so that the std follows P
        through rejected samples and restarts. Recomputed (about 3 ms) when the model or the
        class changes; 1 (the raw P, an upper bound) for MME&KF or without a fixed point."""
        kf, m = (self.anchor, self.anchor_model) if self.anchor_trusted else (self.kf, self.model)
        cls = self.assumed_class
        hit = self._band_cache
        if hit is not None and hit[0] is m and hit[1] == cls:
            return hit[2]
        sol = None if m is None else kf.stationary_solution
        ratio = 1.0
        if sol is not None and not isinstance(kf, MMEKF):
            K, P = sol
            gd, c = iso8608.class_psd_n0(cls), self.cfg
            var, v_g, v_tau = band_error_budget(m.Phi, m.H, K, self.R, m.h, gd, m.speed, self.cfg.profile_cutoff,
                                                m.vehicle, self.acc_sampling, IZR, reference=self._reference)
            var += c.calibration_gain_std ** 2 * float(v_g[:2].sum()) + c.calibration_delay_std ** 2 * float(v_tau.sum())
            ratio = _checked_ratio(var, P)
        self._band_cache = (m, cls, ratio)
        return ratio

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

    def _mass_agrees(self, me: MassEstimator, h: float) -> tuple[float, float, bool]:
        """(since-change mass kg, its standard error kg, whether it agrees with the model mass):
        agreement within max(mass_rebuild_tol, mass_rebuild_sigma standard errors)."""
        t = self.cfg.tuning
        m, sd = me.mass_slow, me.mass_slow_std(h)
        return m, sd, abs(m - self.m_model) <= max(t.mass_rebuild_tol * self.m_model, t.mass_rebuild_sigma * sd)

    def _step_composed(self, acc_sprung: float, acc_unsprung: float, deflection: float, speed: float,
                       h: float) -> dict[str, float]:
        """``step`` for an estimator of the registry (interface.RoadFilter): the sample checks,
        status, re-initialisation, the RLS mass when the estimator has none of its own (fed back
        through ``set_mass`` as for the KF), class, IRI and outputs are this object's."""
        cfg, f = self.cfg, self.composed
        if f.h is not None:
            h = same_step(h, f.h)
        speed = abs(float(speed)) if math.isfinite(speed) else self._speed_last
        self._speed_last = speed
        vals = (float(acc_sprung), float(acc_unsprung), float(deflection))
        self.time += h
        self._h = h
        self.distance += speed * h
        self._steps += 1
        live = self._live(vals, h)
        rows = None if all(live) else np.flatnonzero(live)
        status = STATUS_OK if rows is None else STATUS_REJECTED
        f.step(np.array(vals), rows, speed, h)
        x, var = state_list(f.x), float(f.road_variance)
        if not math.isfinite(sum(x) + var):
            f.reset()
            status = STATUS_REINIT
            x, var = state_list(f.x), float(f.road_variance)
        self.model_builds = f.model_builds
        me = self.mass_est
        if f.mass is not None:
            mass = float(f.mass)
        elif me is not None:
            ok = live[0] and live[2]
            me.update(vals[0] if live[0] else 0.0, self._mass_deflection(vals[2] if live[2] else x[IZS] - x[IZU]), h,
                      use=ok and status != STATUS_REINIT and self.motion == MOVING)
            if cfg.mass_feedback and me.samples * h >= cfg.tuning.mass_warmup:
                m, _, agree = self._mass_agrees(me, h)
                if not agree and self.time - self._last_rebuild >= cfg.tuning.mass_rebuild_interval:
                    self.m_model = m
                    self._last_rebuild = self.time
                    self.mass_rebuilds += 1
                    f.set_mass(m)
            mass = float(me.mass)
        else:
            mass = float(cfg.m_s_nominal)
        if status != STATUS_REINIT:
            before = self.classifier.road_class
            if self.classifier.update(self.distance, x[IZR], speed) != before:
                f.set_road_class(self.classifier.road_class)
        out = self.outputs
        out["road_velocity_est"] = x[IVR]
        out["z_s_est"], out["v_s_est"], out["z_u_est"], out["v_u_est"] = x[IZS], x[IVS], x[IZU], x[IVU]
        out["susp_deflection_est"] = x[IZS] - x[IZU]
        out["tire_deflection_est"] = x[IZU] - x[IZR]
        out["sprung_mass_est"] = mass
        out["mass_std"] = float(me.mass_std(h)) if f.mass is None and me is not None else 0.0
        out["road_class_est"] = int(self.classifier.road_class if f.road_class is None else f.road_class)
        out["nis"] = float(f.nis)
        out["status"] = status
        self._profile(out, x[IZR], speed, h, var if var > 0.0 else math.inf, status)  # the raw variance: an upper bound
        out["iri_est"] = self.iri.update(self.distance, out["road_height_est"])
        return out


preload()  # every estimator's module, while the folder this package was loaded from exists
