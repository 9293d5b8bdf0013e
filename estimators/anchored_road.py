"""The default road estimator (``road_estimator`` 2): the robust combination of docs/robustness.md.

* the force-error filter (``kf``): the KF with the suspension-force error states of
  ``model.force_error_matrices`` (a fast error and a slow bias, which holds the mean force of
  an asymmetric damper's jacking that the linear spring would read as a road offset); its road
  follows from the whole-corner force balance m_s a_s + m_u a_u = k_t (z_r - z_u), which holds
  for any spring and damper law, so a wrong c_s or k_s costs little in band. It gates, rejects
  and re-filters as the KF does (kf_road.py);
* the anchor (``anchor``): the exact-model KF built at the identified mass and damping
  (``MassEstimator`` with ``estimate_damping``: the since-change least squares of [m_s, c]),
  run on the same update decisions. The force-error filter's free force error leaves the
  body's absolute position to the double-integrated accelerometer (raw road error ~38 mm
  against ~4 mm on ISO C at 40 km/h); below ``blend_hz`` the road, body and wheel heights are
  the anchor's (a second-order low-pass of their difference is added, ``Blend``), and each step
  the force-error filter's common velocity is pulled towards the anchor's (``align_hz``);
* after an update without every channel the output is the anchor's and fades back over
  ``anchor_hold`` s (the force-error filter needs all three channels), and both filters
  restart at their fixed points when it ends. ``road_height_std`` follows the anchor's P;
* the anchor restarts from the force-error filter's state when the two disagree by more than
  ``anchor_gate`` times the force-error filter's own std (road height or body velocity): its
  linear spring and damper are then wrong at low frequency (a nonlinear suspension). Not in the
  first ``START_DISAGREE_SPAN`` s, where a disagreement that outlasts the identification of the
  damping drops the anchor and re-filters the start without it; there the anchor is also judged
  against the force-error filter run without the pull, in the profile's band
  (``START_BAND_GATE``). Nor when the force-error filter is the one misled, by a body
  accelerometer whose bias stepped (bias_step.py).

The anchor's mode (``mode``): ``TRUSTED``, ``HOLDING`` (the output fades back from the anchor's
after a partial update, ``_hold_left`` s to go), ``KEPT`` (the force-error filter was misled: the
output is the anchor's while they disagree) or ``DROPPED`` (the suspension is not linear at low
frequency: the force-error filter alone from then on). The start (``start``, with the
damping estimated): ``START`` (the force-error filter without the pull, ``_start_kf``, runs
beside: ``_start_output``), ``START_REFILTER`` (the anchor was dropped at the start: the start
is re-filtered without it once this step's mass feedback is done) or ``RUNNING``.
"""
from __future__ import annotations

import copy
import math
from collections import deque
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from scipy.signal import butter

from .bias_step import BiasStep
from .kalman import LinearKF
from .kf_road import KFRoad, _apply
from .mass import MassEstimator
from .model import IVR, IVS, IVU, IZR, IZS, IZU, N_STATES, DiscreteModel, ModelNoise
from .road_profile import Profiler

if TYPE_CHECKING:  # pragma: no cover
    from .suspension import EstimatorConfig

# the anchor's mode
TRUSTED, HOLDING, KEPT, DROPPED = "trusted", "holding", "kept", "dropped"
# the start of a run with the damping estimated
START, START_REFILTER, RUNNING = "start", "start re-filter", "running"

# this many anchor restarts within this many seconds and the anchor is no longer used (linear
# plant: 0-7 restarts in 40 s with a vehicle 30 % off; air spring + asymmetric damper: ~30 per
# second)
ANCHOR_DISTRUST_RESETS, ANCHOR_DISTRUST_SPAN = 20, 10.0
# ... of which this many since the damping was identified: before, the anchor runs at the nominal
# c_s, and a damper 30 % off restarts it too (ISO D, 40 km/h: 20 restarts in the first 5 s, the
# anchor dropped, raw error 38-82 % and 2-sigma coverage 0-48 %; 7-8 % and 92-100 % kept)
ANCHOR_DISTRUST_IDENTIFIED = 5
# no pull of the force-error filter's common velocity towards the anchor's (align_hz) within this
# many s of an anchor restart: a restarting anchor is wrong at low frequency, and the pull carried
# its error into the force-error filter, which keeps it once the anchor is dropped (air-spring
# plant, ISO C, 40 km/h, 40 s, seeds 1-4: raw rms error 369 / 46 / 85 / 79 mm with the pull,
# 50 / 9 / 43 / 34 mm without; 1, 2 and 5 s gave the same). Linear plants without restarts are
# unchanged; "all -" seed 2, which restarts: 9.8 -> 11.6 mm).
# Not within ALIGN_AFTER_FAULT s of an update without every channel: restarts after a sensor
# fault mean the force-error filter was kicked, and the pull is what brings it back (deflection
# frozen for 100 ms on the exact vehicle: raw error after it 10.4 mm with the pull, 16.8 mm
# without)
ALIGN_QUIET = 1.0
ALIGN_AFTER_FAULT = 2.0
# with the damping estimated: within this many s of the start the anchor is not restarted when it
# disagrees with the force-error filter (both are in their start transients, and the anchor runs
# at the nominal c_s until the damping is identified, 1.6-2.0 s into the data). Restarting it
# from the force-error filter's state 12 times in 1.8 s left it 85 mm off on a 3 % grade with
# c_s -30 % (both filters lag the car's 0.33 m/s rise by 40-60 mm/s then): raw error 48.6 mm rms,
# 2-sigma coverage 0, which road_height_std did not say. Without restarts, and with the velocity
# pull of _align on, a linear plant's disagreement (up to 17-36 times the force-error filter's
# own velocity std) is gone once the damping is identified (below 1 after 2 s); the air spring's
# goes on at 13-100 times. So a disagreement for START_DISAGREE_DROP s (leaky count: -h per
# agreeing step) after the damping is identified drops the anchor, and the start is re-filtered
# with the force-error filter alone, without the pull that carried the anchor's error into it
# until then. Cores, ISO B-D at 40 and 80 km/h, 3 seeds: D 80 "all -" raw error 17.9 -> 2.8 mm,
# coverage 0.797 -> 1.000; the other linear cells unchanged; air spring raw 22-28 mm and coverage
# 0.80-1.00 as before
START_DISAGREE_SPAN = 4.0
START_DISAGREE_DROP = 0.5  # s
START_FADE = 0.25  # s, the output's move to and from the force-error filter alone at the start
# ... and at the start the two disagree too when the output and the force-error filter without the
# pull differ in the profile's band by more than START_BAND_GATE of the output's std (the anchor's
# band std without the start's share); once the damping is identified, by as much since then (the
# start's transients are behind: rising from rest on a 3 % grade with c_s +30 %, the filter without
# the pull lags the car, 10.6 mm or 17 stds in band, and its gap then changes by at most 7 stds).
# The tests above compare the anchor with the *pulled* filter, whose own road std is decimetres at
# 10 ms: logged at 10 ms, the pull kept that filter on an air-spring anchor running away (0.22
# m/s^2, its linear spring's mean force error) and the start was read as agreeing: profile 0.2-0.5
# m rms off over 4 s with a std of 0.6 mm. Once the damping is identified (benchmarks/start_gap.py,
# ISO B-D, 40 and 80 km/h): the linear cars of the robust grid at most 1.6 stds, the air spring
# 78-484 stds, logged at 1 or 10 ms
START_BAND_GATE = 10.0
# After the start, an anchor that disagrees with the force-error filter is restarted, unless the
# force-error filter is the one misled (bias_step.py: a body-accelerometer bias that stepped); not
# told apart yet, the restart waits up to KEEP_WAIT s. KEPT ends after KEEP_SETTLE s of agreement
KEEP_WAIT = 0.25  # s
KEEP_SETTLE = 0.5  # s
ZD = 2  # the deflection's row in z


def blend_corner(hz: float, h: float, coarse_step: float, coarse_hz: float) -> float:
    """The blend's corner (Hz) at a step of h s: ``hz`` (Tuning.blend_hz), or ``coarse_hz`` at
    steps longer than ``coarse_step`` s (Tuning.blend_coarse_step, blend_coarse_hz); never above
    0.45 of the sampling rate."""
    return min(coarse_hz if h > coarse_step else hz, 0.45 / h)


class Blend:
    """Second-order Butterworth low-pass of a scalar, one sample per step of h s, its corner
    ``blend_corner(hz, h, coarse_step, coarse_hz)`` (coefficients of scipy.signal.butter, direct
    form II transposed); ``y`` the last output."""

    def __init__(self, hz: float, coarse_step: float, coarse_hz: float):
        self.hz = float(hz)
        self.coarse = (float(coarse_step), float(coarse_hz))
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
            corner = blend_corner(self.hz, h, *self.coarse)
            moved = self._h is not None and corner != blend_corner(self.hz, self._h, *self.coarse)
            b, a = butter(2, corner, fs=1.0 / h)
            self._b, self._a, self._h = tuple(b.tolist()), tuple(a.tolist()), h
            if moved:
                # a new corner: the output goes on from where it is, as if its input had held
                # there (the old corner's state taken as the new one's makes the output ring)
                (_, b1, b2), (_, a1, a2) = self._b, self._a
                self.s2 = (b2 - a2) * self.y
                self.s1 = (b1 - a1) * self.y + self.s2
        (b0, b1, b2), (_, a1, a2) = self._b, self._a
        y = b0 * u + self.s1
        self.s1 = b1 * u - a1 * y + self.s2
        self.s2 = b2 * u - a2 * y
        self.y = y
        return y


class AnchoredRoad(KFRoad):
    """The force-error filter ``kf`` with the anchor (module doc). ``mass_est``: the composer's
    mass estimator (None without one), whose identified damping the anchor takes."""

    def __init__(self, cfg: "EstimatorConfig", mass_est: MassEstimator | None = None):
        self.mass_est = mass_est
        # the episode at the start of the run spans damping_refilter_span (KFRoad._span), and
        # the anchor is not restarted in the first START_DISAGREE_SPAN s (_compare)
        self.damping_estimated = bool(mass_est is not None and mass_est.estimate_damping)
        super().__init__(cfg)

    def _model_noise(self) -> tuple[ModelNoise, int]:
        t = self.cfg.tuning  # the suspension-force error states, appended last
        noise = replace(t.model_noise, q_f=float(t.force_error_q), q_b=float(t.force_bias_q),
                        tau_b=float(t.force_bias_tau))
        return noise, noise.force_states

    def _init_anchor(self) -> None:
        t = self.cfg.tuning
        # the exact-model KF at the identified mass and damping runs alongside and gives the road
        # below ``blend_hz`` (module doc); it gets the same update decisions
        self.anchor: LinearKF = LinearKF(self.n_states - self.force_states, self.R.shape[0],
                                         freeze_tol=t.freeze_tol, fast=t.fast_gain)
        self.anchor.R = self.R
        self.anchor_model: DiscreteModel | None = None
        self.blend = Blend(t.blend_hz, t.blend_coarse_step, t.blend_coarse_hz)
        self.mode = TRUSTED
        self._hold_left = 0.0  # s of the anchor hold left (HOLDING, see _after_update)
        self.anchor_resets = 0
        self._resets_identified = 0  # anchor restarts since the damping was identified
        self._reset_times: deque = deque()
        self._disagree_for = 0.0  # s, leaky count of disagreement once the damping is identified
        self._last_partial = -math.inf  # s, the last update without every channel
        # KEPT (bias_step.py): the judge, the disagreement's start and last step (s), the gap's
        # profile since the anchor was kept, its largest value fading over profile_cutoff m, and
        # the anchor's weight in the output
        self.bias_step = BiasStep()
        self._disagree_from = -math.inf
        self._last_disagree = -math.inf
        self._kept_gap: Profiler | None = None
        self._kept_peak = 0.0
        self._kept_w = 0.0
        # with the damping estimated: the force-error filter without the velocity pull, run
        # through the start (START_DISAGREE_SPAN), and its weight in the output
        self.start = RUNNING
        self._start_kf: LinearKF | None = None
        self._start_w = 0.0
        self._start_gap_until = -math.inf  # s, end of the start disagreement's hold
        self._gap_profile = Profiler(self.cfg.profile_cutoff, self.reference)  # of _start_output's gap
        self._drift: Profiler | None = None  # of the same gap from when the damping is identified
        self._start_band_gap = 0.0  # m, the gap in band (from _drift once it runs): START_BAND_GATE

    @property
    def anchor_trusted(self) -> bool:
        """The output follows the anchor below ``blend_hz`` (its mode is not ``DROPPED``)."""
        return self.mode != DROPPED

    def _hold(self, left: float) -> None:
        """``left`` s of the anchor hold to go: HOLDING while it lasts (a dropped anchor stays dropped)."""
        self._hold_left = left
        if left > 0.0 and self.mode != DROPPED:
            self.mode = HOLDING
        elif self.mode == HOLDING:
            self.mode = TRUSTED

    def _active(self) -> tuple[LinearKF, DiscreteModel | None]:
        return (self.anchor, self.anchor_model) if self.mode != DROPPED else (self.kf, self.model)

    def _restart_anchor(self, from_rest: bool) -> None:
        self.blend.reset()
        self._hold(0.0)
        if self.mode != DROPPED:
            self.mode = TRUSTED
            self.bias_step.release()
        a = self.anchor
        na = a.dim_x
        a.start_at(np.zeros(na))
        if self.anchor_model is None or not a.stationary():
            a.P = np.diag(([1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-1] + [1e-4] * na)[:na]) ** 2
        if from_rest and self.damping_estimated:
            self.start, self._start_kf = START, copy.deepcopy(self.kf)
        else:
            self.start, self._start_kf = RUNNING, None
        self._start_w = 0.0
        self._drift, self._start_band_gap = None, 0.0

    def _anchor_snapshot(self, stationary: bool | None) -> tuple:
        a = self.anchor
        # at a (re)start (``stationary`` given) the anchor too is due to start at its model's
        # fixed point: restored with its placeholder P instead, a re-filter from this snapshot
        # left it with a covariance minutes from settling (3 % grade at 72 km/h, a mass change
        # detected at 0.3 s: road_height_std 0.001 mm, raw error 16 mm)
        st = a.stationary_now if stationary is None else self.anchor_model is None or a.stationary_now
        return (a.x.copy(), a.P.copy(), st), self.blend.copy(), self._hold_left

    def _restore_anchor(self, saved: tuple) -> None:
        (x0, P0, stationary), blend, hold_left = saved
        self._hold(hold_left)
        a = self.anchor
        a.start_at(x0.copy(), P0.copy())
        if stationary:
            a.stationary()
        self.blend = blend.copy()

    def _anchor_current(self) -> bool:
        return self.anchor_model is None or self.anchor_model.vehicle.c_s == self.c_model

    def _build_anchor(self, v: float, gd: float, h: float) -> None:
        m, t = self.model, self.cfg.tuning
        if self.start == START:  # the same model and fixed point (kept while its state is its own)
            sk = self._start_kf
            sk.set_model(m.Phi, m.Q, m.H, self.R)
            sk.share_fixed_point(self.kf)
            sk.stationary()
        am = self.anchor_model = DiscreteModel.build(
            replace(self.cfg.vehicle(self.m_model), c_s=self.c_model), v, gd, h, t.road_model,
            t.model_noise, t.use_deflection, self.acc_sampling, self.road_hold)
        self.anchor.set_model(am.Phi, am.Q, am.H, self.R)
        self.anchor.stationary()

    def _follow(self, z: np.ndarray, rows, replay: bool = False) -> None:
        _apply(self.anchor, z, rows)
        if self.start == START and not replay:
            _apply(self._start_kf, z, rows)
        if rows is None and not replay:
            kf, an, n = self.kf, self.anchor, self.n_states
            x = kf.x
            self.bias_step.update(kf.y.item(ZD) / math.sqrt(kf.S.item(ZD, ZD)),
                                  an.y.item(ZD) / math.sqrt(an.S.item(ZD, ZD)),
                                  sum(x.item(i) for i in range(n - self.force_states, n)),
                                  self._h, self.time, self.m_model)
            if self.mode == KEPT and self.bias_step.beyond_range and self.check is not None:
                self.check.flag()  # a body bias beyond the range: status 3
        self._after_update(rows is not None)

    def _anchor_sum(self) -> float:
        return self.anchor.state_sum()

    def _after_update(self, partial: bool) -> None:
        """Anchor hold: after an update without every channel, the output is the anchor's and
        fades back to the force-error filter's over ``anchor_hold`` s, during which that filter
        keeps the anchor's common velocity (``_align``). The force-error filter needs all three
        channels (without a_s its force error is unobserved; without d nothing ties the body to
        the wheel); the anchor's model carries a missing channel (a deflection stuck for 4 s
        left the force-error filter at 26 % HP error, the anchor at 10 %)."""
        if self.mode == DROPPED:
            return
        if partial:
            self._last_partial = self.time
            self._hold(self.cfg.tuning.anchor_hold)
        elif self.mode == HOLDING:
            self._hold(max(self._hold_left - self._h, 0.0))
            if self.mode == TRUSTED:
                # both filters back at their fixed points: the force-error filter's covariance
                # would otherwise take minutes to return there along the weakly observable
                # common mode (running the full recursion all that time)
                for kf in (self.kf, self.anchor):
                    if not kf.stationary_now:
                        kf.stationary()
        if self.mode == HOLDING:
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
        x = self.kf.x.copy()
        x[[IVS, IVU, IVR]] += gain * float(self.anchor.x[IVS] - x[IVS])
        self.kf.x = x

    def _compare(self, replay: bool = False) -> None:
        """The low-pass of the two filters' road gap (``blend``), and the anchor's restart or
        drop when they disagree (module doc). ``replay``: a re-filter replays a recorded step."""
        if self.mode == DROPPED:
            return
        a, kf, g = self.anchor, self.kf, self.cfg.tuning.anchor_gate
        y = self.blend.step(float(a.x[IZR] - kf.x[IZR]), self._h)
        P = kf.P
        if g > 0 and (y * y > g * g * P[IZR, IZR] or (a.x[IVS] - kf.x[IVS]) ** 2 > g * g * P[IVS, IVS]
                      or (self.start == START and not replay and self._start_gap_large())):
            me = self.mass_est
            if (self.damping_estimated and self.time < START_DISAGREE_SPAN
                    and self.time - self._last_partial > ALIGN_AFTER_FAULT):
                self._start_gap_until = self.time + START_DISAGREE_DROP
                # at the start both filters are in their start transients and the anchor
                # runs at the nominal c_s until the damping is identified: a restart would
                # copy the force-error filter's transient into the anchor. A disagreement
                # that goes on once the damping is identified is a suspension that is not
                # linear: the anchor is dropped and the start re-filtered without it
                # (START_DISAGREE_SPAN). After a sensor fault the force-error filter was
                # kicked, not the anchor: restarts as later in the run (ALIGN_AFTER_FAULT)
                if me.damping_identified and not replay:
                    self._disagree_for += self._h
                    if self._disagree_for >= START_DISAGREE_DROP:
                        self._distrust_anchor()
                        self.start = START_REFILTER
                return
            # a re-filter replays the decisions taken: a kept anchor stays kept, a restart restarts
            if (self.mode == KEPT) if replay else self._keep_anchor():
                return
            # the anchor disagrees with the force-error filter beyond what the latter's own
            # error explains: its linear spring and damper are wrong at low frequency (a
            # nonlinear suspension): it restarts from the force-error filter's state
            # with the force-error filter's covariance of those states: the anchor takes
            # over its error (its low frequencies are loosely pinned), and road_height_std,
            # the anchor's, says so until the anchor has converged back (ISO D, 40 km/h,
            # every parameter off: 38 mm of error 5 s after such restarts against a std of 1 mm)
            n = a.dim_x
            a.start_at(kf.x[:n].copy(), kf.P[:n, :n].copy())
            self.blend.reset()
            self.anchor_resets += 1
            recent = self._reset_times
            recent.append(self.time)
            if me is None or not me.estimate_damping or me.damping_identified:
                self._resets_identified += 1
            while recent and recent[0] < self.time - ANCHOR_DISTRUST_SPAN:
                recent.popleft()
            if len(recent) >= ANCHOR_DISTRUST_RESETS and self._resets_identified >= ANCHOR_DISTRUST_IDENTIFIED:
                self._distrust_anchor()  # restarting does not help
        elif not replay:
            if self._disagree_for > 0.0:
                self._disagree_for = max(self._disagree_for - self._h, 0.0)
            if self.mode == KEPT and self.time - self._last_disagree > KEEP_SETTLE:
                self.mode = TRUSTED
                self.bias_step.release()

    def _keep_anchor(self) -> bool:
        """A disagreement after the start: True when the anchor is kept, or the decision waits
        (no restart this step; bias_step.py)."""
        if self.time - self._last_disagree > KEEP_SETTLE:
            self._disagree_from = self.time
        self._last_disagree = self.time
        if self.mode == KEPT:
            return True
        if (self.mode != TRUSTED or self.time - self._last_partial <= ALIGN_AFTER_FAULT
                or (self._reset_times and self.time - self._reset_times[-1] < ANCHOR_DISTRUST_SPAN)):
            return False  # after a sensor fault, or restarting already: restart
        misled = self.bias_step.judge(self.time)
        if misled is None:
            return self.time - self._disagree_from < KEEP_WAIT
        if misled:
            self.mode = KEPT
            self._kept_gap, self._kept_peak = Profiler(self.cfg.profile_cutoff, self.reference), 0.0
        return misled

    def _start_gap_large(self) -> bool:
        """At the start: the output and the force-error filter without the pull differ in the
        profile's band (once the damping is identified: have moved apart since) by more than
        START_BAND_GATE output stds."""
        return self._start_band_gap ** 2 > START_BAND_GATE ** 2 * self._band_variance()

    def _distrust_anchor(self) -> None:
        """The suspension is not linear at low frequency: from here on the output is the
        force-error filter's alone, at the nominal mass (its force-error state takes up a mass
        error too). With the nonlinear terms of the mass regression (mass.py) feeding the mass
        back made no difference to the road: air-spring plant, ISO C/D at 40/80 km/h, 2 seeds,
        HP error within +-0.5 points of the nominal mass's, mass within 0.8 % (2-3 % low on ISO D
        at 80 km/h)."""
        self.mode = DROPPED
        self._hold_left = 0.0
        self.start, self._start_kf = RUNNING, None  # the start is re-filtered without the anchor

    # --- mass feedback (KFRoad.feed_back_mass) -----------------------------------------------
    def _before_feedback(self, speed: float, h: float) -> None:
        if self.mode == DROPPED and self.m_model != self.cfg.m_s_nominal:
            self.m_model = self.cfg.m_s_nominal  # see _distrust_anchor
            self._ensure_model(speed, h)
        if self.start == START_REFILTER:
            # the force-error filter alone from the start, at the nominal mass: the pull
            # towards the anchor it had until now carried the anchor's error (module doc)
            self.start = RUNNING
            self._refilter(from_start=True)

    def _takes_mass(self) -> bool:
        # KEPT: the body accelerometer's bias stepped, and the mass regression, which reads m a_s,
        # took the step for a payload change (fed back, its since-change mass moved the anchor)
        return self.mode not in (DROPPED, KEPT)

    def _damping_known(self, me: MassEstimator) -> bool:
        return me.damping_identified

    def _feed_back_damping(self, me: MassEstimator, h: float, speed: float) -> None:
        """The anchor filter at the identified damping when it differs from the model's (a
        re-filter within the episode)."""
        t = self.cfg.tuning
        dc = abs(me.damping - self.c_model)
        if (dc > min(t.damping_rebuild_tol, t.damping_rebuild_tol_late) * self.c_model
                and self.time - self._last_rebuild >= t.mass_rebuild_interval):
            in_episode = t.refilter_span > 0 and not self._episode_closed()
            if dc > (t.damping_rebuild_tol if in_episode else t.damping_rebuild_tol_late) * self.c_model:
                self.c_model = me.damping
                self._last_rebuild = self.time
                self._ensure_model(speed, h)
                if in_episode:
                    self._refilter()

    def _long_first_episode(self) -> bool:
        return self.damping_estimated and self.mode != DROPPED

    # --- the output ------------------------------------------------------------------------
    def _output(self, x: list, h: float, ds: float) -> tuple[list, float]:
        if self.mode != DROPPED:
            low = self.blend.y  # m, the anchor's road below blend_hz minus the road filter's
            x[IZR] += low
            x[IZS] += low
            x[IZU] += low
            if self.mode == HOLDING:  # the anchor hold (_after_update)
                hold = self.cfg.tuning.anchor_hold
                w = self._hold_left / hold if hold > 0 else 0.0
            else:  # the anchor kept (bias_step.py): faded in and out over START_FADE s
                kw = self._kept_w
                self._kept_w = w = (min(kw + h / START_FADE, 1.0) if self.mode == KEPT
                                    else max(kw - h / START_FADE, 0.0))
            if w > 0.0:
                xa = self.anchor.x.tolist()
                x = [w * xa[i] + (1.0 - w) * x[i] for i in range(N_STATES)]
        start_var = 0.0
        if self.mode == KEPT:  # the output may be off by the two filters' gap since then
            gap = abs(self._kept_gap.step(float(self.anchor.x[IZR] - self.kf.x[IZR]), h, ds))
            self._kept_peak = max(gap, self._kept_peak * math.exp(-ds / self.cfg.profile_cutoff))
            start_var = self._kept_peak ** 2
        if self.start == START:
            # the share of the two filters' road gap the output may be off by, in the profile's band
            share, gap = self._start_output(x, h)
            band_gap = self._gap_profile.step(gap, h, ds)
            start_var += (share * band_gap) ** 2
            if self._drift is None and self.mass_est.damping_identified:
                self._drift = Profiler(self.cfg.profile_cutoff, self.reference)
            self._start_band_gap = band_gap if self._drift is None else self._drift.step(gap, h, ds)
        return x, start_var

    def _start_output(self, x: list, h: float) -> tuple[float, float]:
        """While the anchor disagrees with the force-error filter at the start (_compare), the
        output (``x``, changed in place) moves over START_FADE s to the force-error filter run
        without the pull towards the anchor (``_start_kf``), and back when they agree: which of
        the two is right is not known until the damping is identified. Returns (share, gap): the
        share of their road gap (m) the output may be off by, which road_height_std takes in the
        profile's band."""
        if self.time - self._last_partial <= ALIGN_AFTER_FAULT:
            # a sensor fault: the anchor carries the output (_after_update), and the filter
            # without the pull, which needs every channel as much as the force-error filter, is
            # of no further use
            self.start, self._start_kf, self._start_w = RUNNING, None, 0.0
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
                self.start, self._start_kf = RUNNING, None  # the start is over
            return 0.0, gap
        for i in range(N_STATES):
            x[i] = w * xs[i] + (1.0 - w) * x[i]
        return max(w, 1.0 - w), gap

    def _variance_factor(self) -> float:
        # once the anchor is dropped the band ratio takes the force errors as zero (the vehicle
        # the model's), and the filter's own P, whose force-error states carry them, is right in
        # rms but not in its tails (Tuning.nonlinear_std_factor)
        return self.cfg.tuning.nonlinear_std_factor ** 2 if self.mode == DROPPED else 1.0
