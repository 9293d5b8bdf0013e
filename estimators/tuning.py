"""The estimators' fixed choices: every knob of ``SuspensionEstimator`` that is not a parameter
of the FMU, with the reason for its value, in one place.

Each was chosen once for all ISO classes, speeds and masses (the reasons below give the
measurements behind them); none is meant to be tuned per vehicle or per road, which is why the
FMU does not expose them. Studies, benchmarks and tests that probe a choice pass a changed copy:
``SuspensionEstimator(blend_hz=1e-9)`` or ``EstimatorConfig(tuning=replace(TUNING, ...))``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..plant.vehicle import check_range
from .model import ModelNoise, RoadModel


@dataclass(frozen=True)
class Tuning:
    """Fixed choices of the estimator (SI units; see each comment for the reason)."""

    # the vehicle sees the road held over the step at its end-of-step value (co-simulation
    # convention); -1 = only with acc_sampling = 1, 0 = never, 1 = always
    road_hold: int = -1
    use_deflection: bool = True  # use the deflection sensor in the road filter
    mme_weight: float = 10.0  # W of MME&KF, (m/s^2)^-2
    # RLS on [m_s, c] instead of m_s; None = with road_estimator 2 (which does not trust c_s)
    estimate_damping: bool | None = None
    # intensity of the suspension-force error state of road_estimator 2 per unit speed, N^2/m
    # (model.force_error_matrices): 1e4 N^2/s at 40 km/h, chosen on the linear plant with c_s
    # +-30 % and k_s +-15 % against the cost on the exact vehicle (docs/robustness.md)
    force_error_q: float = 900.0
    # road_estimator 2: the slow force bias (model.force_error_matrices), N^2/m and s. On the
    # air-spring plant with a 3:1 asymmetric damper (ISO B-D, 40 and 80 km/h, road seeds 1-3)
    # the damper's jacking shifts the mean deflection by 6-12 mm, which the linear spring reads
    # as a road offset: raw road error 60.7 mm rms (worst 466 mm) and 2-sigma coverage 0.74
    # without the bias, 25.1 mm and 0.93 with it, HP error 3.43 -> 3.01 %; on the linear plant
    # (exact and parameters off) HP 3.84 -> 3.79 %, coverage unchanged (docs/robustness.md);
    # 0 = no bias state
    force_bias_q: float = 1000.0
    force_bias_tau: float = 10.0
    # road_estimator 2: once the anchor is dropped (a suspension that is not linear at low
    # frequency) road_height_std is the force-error filter's own std times this. That std is
    # right in rms on the air-spring plant on ISO B and C (rms error / std 0.95-1.03, seeds
    # 1-40 of 60 s), but the error is a slow wander of the common mode whose size differs from
    # run to run (one run's 2-sigma coverage 0.16-1.00), so +-2 std covered only 0.81-0.91 of
    # it over forty runs a cell; x1.2: 0.86-0.97 there and on seeds 41-80 (docs/robustness.md)
    nonlinear_std_factor: float = 1.2
    # road_estimator 2: corner (Hz) below which the road comes from the exact-model KF at the
    # identified mass and damping (the anchor) instead of the force-error filter, whose free
    # force error leaves the body's absolute position to the double-integrated accelerometer
    # (raw road error 38 mm against 4.4 mm on ISO C at 40 km/h; module doc)
    blend_hz: float = 1.0
    # ... at steps longer than blend_coarse_step s (logging below 400 Hz) the corner is
    # blend_coarse_hz: there the force-error filter, which takes the body accelerometer nearly as
    # an input and so integrates its point samples, is worse than the anchor over the whole band
    # (exact vehicle, ISO C at 80 km/h, 10 ms: HP error 4.11 % at 1 Hz, 2.18 % at 30 Hz, the plain
    # KF 1.88 %), with the vehicle off too (c_s +30 %, k_s -15 %: 16.1 % and 2-sigma coverage 0.42
    # at 1 Hz, 6.5 % and 0.99 at 30 Hz); at 2 ms a 4 Hz corner was already no better than 1 Hz
    # (cells -20 to +12 %), at 3 and 5 ms 30 Hz was (docs/real-sensors.md)
    blend_coarse_step: float = 0.0025
    blend_coarse_hz: float = 30.0
    damping_rebuild_tol: float = 0.03  # relative change of the identified damping that rebuilds the anchor
    # ... outside a re-filter episode, where the rebuild cannot be re-filtered. The identified
    # damping wanders by a few % after its first value (1997-2062 N.s/m on the sag road at
    # 72 km/h, k_s 17000 N/m told exactly), and an anchor rebuilt at a new damping during a large
    # vertical motion moves the road's low-frequency level: there raw road error 18.3 mm rms with
    # 0.03 against 5.3 mm without the rebuild (tests/test_robust.py, docs/robustness.md)
    damping_rebuild_tol_late: float = 0.10
    # road_estimator 2: each step the force-error filter's common velocity (v_s, v_u, v_r alike)
    # moves towards the anchor's by 2 pi align_hz h: its own is pinned only by the 0.01 Hz
    # reference and wanders (and a burst on a channel kicks it). ISO C, 40 km/h, HP error on the
    # exact vehicle 2.59 / 2.42 % and with c_s -30 % 3.28 / 3.03 % at 0 / 1 Hz
    align_hz: float = 1.0
    # road_estimator 2: the anchor restarts from the force-error filter's state when it differs
    # from it by more than this many of the force-error filter's own std (road height or body
    # velocity); 0 = never
    anchor_gate: float = 5.0
    anchor_hold: float = 0.5  # s: after an update without every channel the output fades from the anchor's
    # Mass feedback: the road filter is rebuilt at the since-last-change least-squares mass
    # (MassEstimator.mass_slow) when it differs from the model mass by more than
    # max(mass_rebuild_tol, mass_rebuild_sigma standard errors): a significant AND relevant change.
    mass_rebuild_tol: float = 0.001  # relative; 0.6 % model-mass error cost ~2 % HP error on ISO B
    mass_rebuild_sigma: float = 3.0
    # ... outside a re-filter episode (a payload change detected by the RLS opens one), where the
    # rebuild cannot be re-filtered, only a change of more than this (relative). A rebuild of the
    # road filter at a new mass during a large vertical motion moves the road's low-frequency
    # level, like a late damping rebuild (damping_rebuild_tol_late): curves road at 72 km/h, k_s
    # -15 %, noise seed 2, a 0.45 % mass rebuild at 8.15 s in a 2 m sag: raw road error 10.8 mm
    # rms and 2-sigma coverage 0.07, without it 2.6 mm and 0.88 (docs/robustness.md)
    mass_rebuild_tol_late: float = 0.02
    # s of data before the mass is fed back. The since-change least squares' standard error is not
    # honest on a fraction of a second: with 0.2 s, a 3 % grade entered at 72 km/h (noise seed 13)
    # put the model at 417.6 kg at 0.32 s (true 410, outside 3 standard errors), then 412.1 kg
    # until 6.3 s, and the road's common mode drifted 16-20 mm; with 1 s, 0.5 mm. The first
    # feedback still falls inside refilter_span, so the filter is re-run from the start at it.
    mass_warmup: float = 1.0
    # m/s below which the car stands: the road excites nothing, the body's free decay ends in
    # about 2 s, and the regression's excitation test (a 1 s low-pass of F[a_s]^2) stays open
    # ~9 s longer, in which the RLS fitted noise to noise (410 kg -> 41 kg, the bound, in 3 s
    # standing). Below it the mass and its std hold.
    standstill_speed: float = 0.5
    # relative difference of the RLS mass from the model mass above which the RLS keeps using
    # live body-acceleration and deflection samples that the road filter rejects
    mass_trust_sensors: float = 0.05
    mass_rebuild_interval: float = 0.02  # s, minimum time between two mass rebuilds (cost cap)
    default_class: int = 3  # class assumed while road_class = 0 and none identified yet
    # Q is set from the class max(assumed class, q_class_min). Scheduling Q down to the class
    # of a smooth road did NOT help: a smaller road intensity pins the unobservable common drift
    # of body, wheel and road harder and the filter shrinks the road in band (ISO B, 40 km/h,
    # true mass 230 kg: HP error 11.1 % with the Q of B, 1.7 % with D, 1.4 % with F; switching
    # Q at the first identified class also kicks the drift). So classes below F share F's Q.
    q_class_min: int = 6
    speed_rebuild_tol: float = 0.01  # relative speed change that re-discretises
    outlier_nis: float = 1e4  # NIS above which a measurement is rejected as an outlier
    # Re-initialise when every finite channel has been rejected for this long (a diverged
    # filter); a burst of bad samples on some channels is predicted through instead.
    reinit_after: float = 0.2  # s
    # s of an outlier streak on a channel during which its gate uses at most the stationary
    # innovation variance; after it the actual (grown) variance, so that a channel the filter
    # itself has drifted away from is taken back
    gate_hold: float = 0.1
    # Self-diagnosis (sensor_check.py): the innovations' variance (each sample clipped at 3 sigma)
    # over that of the model and the calibration allowance, averaged over diagnosis_window s,
    # above diagnosis_limit on a channel = an error the filter cannot absorb (status 3). On the
    # cores, ISO C at 40 km/h: every sensor error at the end of its range, and all together, at
    # most 0.92 (ideal sensors 0.25), the linear vehicles of the robustness grid at most 1.26
    # (c_s -30 %, ISO D), the air-spring plant 1.72 (ISO C; 2.36 on ISO D); a dead wheel
    # accelerometer or deflection sensor, a sign flipped, skews of 6-10 ms and biases of 2-3
    # m/s2 3-58; a dead body accelerometer only 2.5-2.7 (benchmarks/sensor_faults.py,
    # docs/real-sensors.md). 2.0 flagged a 30 mm pothole at 72 km/h on ISO B
    # (tests/test_real_roads.py), 2.5 does not. The check starts diagnosis_start s into the run,
    # once the filter has absorbed the offsets and biases it can absorb.
    diagnosis_window: float = 1.0
    diagnosis_limit: float = 2.5
    diagnosis_start: float = 3.0
    # ... or the wheel accelerometer's innovations' mean over diagnosis_window s above this many of
    # its stds: a bias the filter is taking up (sensor_check.py). At most 0.9 on ideal sensors, 0.7
    # on the robustness grid's linear vehicles, 2.5 on the air-spring plant, 3.8 on a 3 % grade at
    # 72 km/h, 6.0 with every error at the end of its range, 7.1 with a 30 mm deflection offset;
    # a body bias of 0.5 m/s2 22 (docs/real-sensors.md)
    diagnosis_mean_limit: float = 8.0
    # status 3 is held until the car has gone this many profile_cutoff lengths with the ratios back
    # below the limit: after a body-accelerometer bias stepping by 1 m/s2 (ISO C, 40 km/h) the
    # profile's error was 0.47-0.67 m for 4 s, 70 mm 8 s (one cut-off length) after the ratio fell
    # back and 6-16 mm for 10 s more, while the force-bias state took the bias up
    diagnosis_hold: float = 3.0
    frozen_time: float = 0.05  # s a channel may repeat its value bit for bit before it is rejected
    # The road filter starts at the stationary covariance of its model (DARE), again whenever the
    # model is rebuilt or the filter re-initialised, and keeps its gain frozen there (kalman.py);
    # after a skipped or partial update it runs the full recursion until the posterior
    # covariance is back within freeze_tol (relative) of the fixed point.
    freeze_tol: float = 1e-8
    fast_gain: bool = True  # False: the full covariance recursion every step (same estimates)
    road_model: RoadModel = field(default_factory=RoadModel)
    model_noise: ModelNoise = field(default_factory=ModelNoise)
    class_gain: float = 1.0  # in-band amplitude gain of the road estimate (class correction)
    # Re-filtering after a mass rebuild (see the module doc): when the road filter is rebuilt at
    # a new mass within refilter_span s of the onset of the mass change (the start of the run, or
    # the RLS change detection minus refilter_lookback s), the filter is re-run from a snapshot
    # taken before the onset over the buffered measurements with the new model. 0 disables.
    refilter_span: float = 2.0  # s
    # road_estimator 2: the span (s) of the episode at the start of the run. The damping's first
    # identified value comes 1.6-2.02 s into the data, and the mass rebuilds at it and after it:
    # with 2 s they missed the re-filter in 5 of 9 runs (ISO B-C at 40 km/h, c_s +30 % or every
    # parameter off, seeds 1-3), and the anchor kept the common-mode velocity error of its wrong
    # damping and mass (raw road error 8.2 mm against 3.3 mm, 2-sigma coverage 0.72 against
    # 1.00; benchmarks/robust_cores.py)
    damping_refilter_span: float = 4.0
    refilter_lookback: float = 0.1  # s before the RLS change detection (it comes up to 85 ms late)
    refilter_confirm: float = 0.5  # s of agreement of data and model mass that close an episode
    snapshot_interval: float = 0.02  # s between filter snapshots
    # mass_estimator 2 and 4 (imm_filter.py, docs/imm.md): the road corner of the IMM's
    # sub-models (1/m; near 2 kHz at 20 m/s: with paper 002's 200 Hz the bank was fragile, 17 % of
    # a segment outside +-5 %), and the window (s) code 2's mass is averaged over, as the paper
    # does (Table 4): on its grid the bank jumps to a neighbour for 1-60 ms now and then, the
    # window cut the excursions beyond +-5 % from 166 to 4 in 25 s on ISO A; 0 = none
    imm_road_n_hi: float = 30.0
    imm_window: float = 0.25

    def problems(self) -> list[str]:
        """Messages naming each invalid value and its allowed range (empty when valid)."""
        msgs = [check_range("mme_weight", float(self.mme_weight), 0.0, 1e12),
                check_range("force_error_q", float(self.force_error_q), 0.0, 1e12, low_inclusive=False),
                check_range("damping_refilter_span", float(self.damping_refilter_span), 0.0, 60.0),
                check_range("damping_rebuild_tol_late", float(self.damping_rebuild_tol_late), 0.0, 1.0),
                check_range("mass_rebuild_tol_late", float(self.mass_rebuild_tol_late), 0.0, 1.0),
                check_range("force_bias_q", float(self.force_bias_q), 0.0, 1e12),
                check_range("force_bias_tau", float(self.force_bias_tau), 0.01, 1e4),
                check_range("nonlinear_std_factor", float(self.nonlinear_std_factor), 1.0, 10.0),
                check_range("diagnosis_window", float(self.diagnosis_window), 0.01, 60.0),
                check_range("diagnosis_limit", float(self.diagnosis_limit), 1.0, 1e6),
                check_range("diagnosis_mean_limit", float(self.diagnosis_mean_limit), 1.0, 1e6),
                check_range("diagnosis_hold", float(self.diagnosis_hold), 0.0, 100.0),
                check_range("default_class", self.default_class, 1, 8),
                check_range("q_class_min", self.q_class_min, 1, 8)]
        return [m for m in msgs if m]


TUNING = Tuning()
TUNING_FIELDS = frozenset(TUNING.__dataclass_fields__)
