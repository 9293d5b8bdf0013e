"""The road filter of the KF family: ``road_estimator`` 0 (the KF of the exact linear model) and 1
(MME&KF); code 2 adds the anchor of anchored_road.py. ``KFRoad`` is a ``RoadFilter``
(interface.py) that gates its samples, re-filters after a mass change and scales its own
covariance to road_height_std.

Bad samples. The composer leaves out non-finite and frozen channels (``rows``); if the full
update's NIS exceeds ``outlier_nis`` it is undone and the channels whose own normalised
innovation exceeds it are left out (``_channel_ok``). The filter updates with the remaining
channels (or predicts through when none is left): the composer's ``status`` 1. Re-initialisation
(``status`` 2) only when every finite channel has disagreed with the prediction for
``reinit_after`` s (a diverged filter), not after a burst on one channel.

Mass feedback (``feed_back_mass``). The filter is rebuilt at ``MassEstimator.mass_slow`` (least
squares over all data since the last detected payload change) when it differs from the model
mass by more than max(0.1 %, 3 standard errors); the reported ``sprung_mass_est`` stays the
paper's fast forgetting-factor RLS. Feeding back the fast RLS with a 2 % dead band left the model
up to 2 % off for the whole run and let spurious covariance resets on smooth roads (an RLS
excursion to 268 kg on ISO B) rebuild the filter mid-run: on ISO B a 0.6 % model-mass error alone
costs about 2 % of the road in band, because the body-acceleration mismatch integrates into the
unobservable common velocity. Joint / true-mass HP error on ISO B went from 1.40 (590 kg) and 1.20
(230 kg) to about 1.0. A rebuild within ``refilter_span`` s of the onset of the change re-runs the
filter from a snapshot before it over the recorded measurements and update decisions
(``_refilter``).

The road output. ``road_variance`` is the filter's P scaled to the steady-state error in the
profile's band with the allowance for the sensors' calibration (``band_ratio``); ``z_shift`` the
filter's low-frequency lag of the common-mode reference, added back to z_s_est and z_u_est
(``lag_rate``).
"""
from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from ..plant import iso8608
from ..plant.sensors import CALIBRATION_ALLOWANCE
from .interface import RoadFilter
from .kalman import LinearKF, MMEKF
from .mass import MassEstimator
from .model import (IZR, IZS, IZU, N_STATES, N_STATES_AVG, DiscreteModel, ModelNoise, held_input_matrix,
                    measurement_covariance)
from .sensor_check import InnovationCheck
from .steady_state import band_error_budget, reference_lag

if TYPE_CHECKING:  # pragma: no cover
    from .suspension import EstimatorConfig


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


class KFRoad(RoadFilter):
    """The KF (``road_estimator`` 0) or MME&KF (1) of the linear quarter-car + road model at the
    model mass ``m_model`` (kg), rebuilt when the step, the speed band, the class or the mass
    change. ``step`` decides the update (gating, module doc); ``finish_step`` after the mass
    feedback gives ``x``, ``road_variance`` and ``z_shift``."""

    # what road_estimator 2 adds (anchored_road.py)
    anchor: LinearKF | None = None
    anchor_model: DiscreteModel | None = None
    anchor_trusted = False
    anchor_resets = 0

    def __init__(self, cfg: "EstimatorConfig"):
        super().__init__(cfg)
        t = cfg.tuning
        self.R = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std,
                                        cfg.defl_noise_std if t.use_deflection else None)
        dim_z = self.R.shape[0]
        self.acc_sampling = int(cfg.acc_sampling)
        self.noise, self.force_states = self._model_noise()
        self.n_states = (N_STATES_AVG if self.acc_sampling == 1 else N_STATES) + self.force_states
        self.road_hold = bool(t.road_hold == 1 or (t.road_hold == -1 and self.acc_sampling == 1))
        # the road model's common-mode reference (road_profile.Profiler takes it off)
        rm = t.road_model
        self.reference = (rm.f_ref, rm.zeta_ref) if rm.f_ref > 0 else None
        if cfg.road_estimator == 1:
            self.kf: LinearKF = MMEKF(self.n_states, dim_z, W=t.mme_weight, freeze_tol=t.freeze_tol,
                                      fast=t.fast_gain, direct=self.acc_sampling == 0)
        else:
            self.kf = LinearKF(self.n_states, dim_z, freeze_tol=t.freeze_tol, fast=t.fast_gain)
        self.kf.R = self.R
        self._init_anchor()
        # self-diagnosis (sensor_check.py) of the linear filters; MME&KF's model-error injection
        # is not in the check's error responses. The check allows at least the default calibration
        # errors: on ideal sensors the exact model's deflection innovations reach 1.9-3.1 x S over
        # 1 s windows (ISO C at 40, D at 80 km/h), which only the allowance's share explains
        gain_std, delay_std = (max(getattr(cfg, k), CALIBRATION_ALLOWANCE[k][0])
                               for k in ("calibration_gain_std", "calibration_delay_std"))
        self.check = (InnovationCheck(dim_z, 2, gain_std, delay_std, t.diagnosis_window, t.diagnosis_limit,
                                      t.diagnosis_hold * cfg.profile_cutoff, t.diagnosis_start,
                                      (1,), t.diagnosis_mean_limit)
                      if cfg.road_estimator != 1 else None)
        self._class = 0  # the composer's online class (set_road_class), 0 = none yet
        self._band_cache: tuple | None = None  # (model, class, ratio): see band_ratio
        self._lag: tuple | None = None  # (model, q): see lag_rate
        self.model: DiscreteModel | None = None
        self._model_key: tuple | None = None
        self.m_model = float(cfg.m_s_nominal)
        self.c_model = float(cfg.c_s)  # damping of the anchor filter's model (identified)
        self.time = 0.0  # s
        self._h: float | None = None  # s, the step of the last sample
        self._rejected_time = 0.0
        self._outlier_time = [0.0] * dim_z  # s of the current outlier streak per channel
        self._last_rebuild = -math.inf
        self.used: np.ndarray | None = None  # the rows of the last update (None: all)
        self.restarted = False  # the last step re-initialised the filter
        self._start_var = 0.0  # m^2 the start adds to road_variance (anchored_road.py)
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
        self.reset_state(from_rest=True)

    # --- the interface (interface.RoadFilter) --------------------------------------------------
    @property
    def h(self) -> float | None:
        """s, the step of the model (None before the first step)."""
        return None if self.model is None else self.model.h

    @property
    def nis(self) -> float:
        return float(self.kf.nis)  # of the last update (kept through rejected steps)

    @property
    def z_shift(self) -> float:
        """m added to z_s and z_u: the integral of the filter's reference lag (``lag_rate``)."""
        return self._x_int

    @property
    def road_variance(self) -> float:
        """m^2: the active filter's P[z_r, z_r] scaled to the band of road_height_est
        (``band_ratio``), with the start's share (anchored_road.py). A covariance that rounding
        has taken to 0 or below (or past the floats) claims nothing: an infinite variance, never
        a small one (seen on a 1 kg wheel damped at 1e5 N.s/m)."""
        return self._band_variance() + self._start_var

    def _band_variance(self) -> float:
        """m^2: ``road_variance`` without the start's share."""
        p_zr = float(self._active()[0].P[IZR, IZR])
        return p_zr * self.band_ratio() * self._variance_factor() if p_zr > 0.0 else math.inf

    def missing_speed(self, last: float) -> float:
        """A speed that is not finite: the model's (0 before the first)."""
        return self.model.speed if self.model is not None else 0.0

    def set_road_class(self, road_class: int) -> None:
        self._class = int(road_class)

    def reset(self) -> None:
        self.reset_state()

    def restart(self) -> None:
        self.reset_state(from_rest=True)

    def substitutes(self) -> tuple[float, float]:
        """The body acceleration (m/s^2) the model predicts from the filter's state (its force
        error included), and the deflection (m) of the active filter, whose model ties the body
        to the wheel."""
        src = self._active()[0]
        return float(self.model.H[0] @ self.kf.x), float(src.x[IZS] - src.x[IZU])

    def checked_step(self, z: np.ndarray, rows: np.ndarray | None, speed: float, h: float,
                     ds: float) -> tuple[np.ndarray | None, bool]:
        """``step``: it leaves out more rows than ``rows`` (outliers) and re-initialises on its
        own terms (module doc)."""
        self.step(z, rows, speed, h, ds)
        return self.used, self.restarted

    def step(self, z: np.ndarray, rows: np.ndarray | None, speed: float, h: float, ds: float = 0.0) -> None:
        """One sample: z (m/s^2, m/s^2, m), the composer's valid ``rows`` (None: all), speed m/s,
        step h s, ``ds`` m travelled (0 standing: the self-diagnosis holds)."""
        cfg = self.cfg
        self.time += h
        self._h = h
        self._steps += 1
        self._ensure_model(speed, h)
        if rows is None:
            valid = None
        else:
            valid = np.zeros(len(z), bool)
            valid[rows] = True
        kf = self.kf
        x_prev, P_prev, st_prev = kf.x, kf.P, kf.stationary_now
        outliers = False  # some finite, live channel disagreed with the prediction
        if rows is None:
            kf.step(z)
            if kf.nis > cfg.tuning.outlier_nis:
                # undo; find the outlying channels below and update with the others
                kf.restore(x_prev, P_prev, st_prev)
                valid = self._channel_ok(z)
                outliers = True
        if rows is None and not outliers and self.check is not None:
            self.check.update(kf.y, kf.S, z - kf.y, kf.F, kf.K, kf.H, h, ds)
        if valid is not None and not valid.all():
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
        self._follow(z, rows)
        self._rejected_time = self._rejected_time + h if rejected_all else 0.0
        restarted = False
        # a channel the filter has disagreed with for reinit_after s while the others agree: the
        # filter has drifted (e.g. after accepting the first samples of a burst), not the sensor
        if self._rejected_time >= cfg.tuning.reinit_after or max(self._outlier_time) >= cfg.tuning.reinit_after:
            self._outlier_time = [0.0] * len(self._outlier_time)
            # every finite channel disagrees with the prediction for reinit_after s: diverged
            self.reset_state()
            self._rejected_time = 0.0
            restarted = True
        if not math.isfinite(kf.state_sum() + self._anchor_sum()):
            self.reset_state()
            restarted = True
        self._compare()
        if cfg.tuning.refilter_span > 0 and not restarted:
            self._record.append((self._steps, z, rows))
        self.used, self.restarted = rows, restarted

    def finish_step(self, h: float, ds: float) -> None:
        """After the mass feedback (which may re-filter): snapshots, and ``x`` and ``z_shift``."""
        if self.cfg.tuning.refilter_span > 0:
            self._keep_snapshots()
        x, self._start_var = self._output(self.kf.x.tolist(), h, ds)
        if not self.restarted and math.isfinite(x[IZR]) and not isinstance(self.kf, MMEKF):
            # z_s_est and z_u_est relative to the reference: the filter's low-frequency lag added back
            self._x_int += self.lag_rate() * x[IZR] * h  # q at each step: no jump when q changes
        self.x = x

    # --- state -----------------------------------------------------------------------------
    def reset_state(self, from_rest: bool = False) -> None:
        """Zero state at the stationary covariance of the model (before the first step, when
        there is no model yet: body and wheel known to 0.1 mm / 0.1 mm/s, road to 1 cm / 0.1 m/s;
        the first step builds the model and sets the stationary covariance). ``from_rest``: the
        start of a run, from a car at rest (the relative states are then known exactly)."""
        n = self.n_states
        kf = self.kf
        kf.start_at(np.zeros(n))
        self._x_int = 0.0  # m, integral of q x since the (re)start (steady_state.reference_lag)
        if self.model is None or not kf.stationary():
            kf.P = np.diag(([1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-1] + [1e-4] * n)[:n]) ** 2
        self._restart_anchor(from_rest)
        self._record.clear()
        self._snaps.clear()
        # before the first model the filter is due to start at that model's fixed point
        self._snap(stationary=self.model is None or kf.stationary_now)

    @property
    def assumed_class(self) -> int:
        if self.cfg.road_class > 0:
            return int(self.cfg.road_class)
        return self._class or int(self.cfg.tuning.default_class)

    def lag_rate(self) -> float:
        """Rate q (1/s) by which the active filter's road misses the common-mode reference below
        its band (steady_state.reference_lag), for z_s_est and z_u_est; recomputed (about 1 ms)
        when the model changes; 0 for MME&KF (not this filter form) or without a fixed point."""
        kf, m = self._active()
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

    def band_ratio(self) -> float:
        """Steady-state variance of the road error in the distance band of road_height_est
        (steady_state.band_error_budget: the ISO road of the assumed class and the sensor
        noise, the vehicle the model's) over the active filter's own P[z_r, z_r] (the anchor's,
        or the force-error filter's once the anchor is dropped), so that the std follows P
        through rejected samples and restarts. Recomputed (about 3 ms) when the model or the
        class changes; 1 (the raw P, an upper bound) for MME&KF or without a fixed point."""
        kf, m = self._active()
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
                                                m.vehicle, self.acc_sampling, IZR, reference=self.reference)
            var += c.calibration_gain_std ** 2 * float(v_g[:2].sum()) + c.calibration_delay_std ** 2 * float(v_tau.sum())
            ratio = _checked_ratio(var, P)
        self._band_cache = (m, cls, ratio)
        return ratio

    def _snap(self, stationary: bool | None = None) -> None:
        kf = self.kf
        st = kf.stationary_now if stationary is None else stationary
        self._snaps.append((self.time, self._steps, kf.x.copy(), kf.P.copy(), st, self._anchor_snapshot(stationary)))

    # --- the model -------------------------------------------------------------------------
    def _ensure_model(self, speed: float, h: float) -> None:
        key = self._model_key  # (h, class, speed band, mass) the model was last checked for
        cls = self.cfg.road_class or self._class or self.cfg.tuning.default_class
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
        if same_rest and m.vehicle.m_s == self.m_model and self._anchor_current():
            return
        if not same_rest:
            self._epoch_step = self._steps  # steps before this one used another model
        if same_rest:
            v = m.speed  # a mass rebuild keeps the speed the buffered steps were filtered at
        self.model_builds += 1
        self.model = DiscreteModel.build(self.cfg.vehicle(self.m_model), v, gd, h,
                                         self.cfg.tuning.road_model, self.noise,
                                         self.cfg.tuning.use_deflection, self.acc_sampling,
                                         self.road_hold)
        if isinstance(self.kf, MMEKF):
            Gamma = np.zeros((self.n_states, 1))
            Gamma[:N_STATES] = held_input_matrix(self.model.A, self.kf.G[:N_STATES], h)
            self.kf.set_model(self.model.Phi, self.model.Q, self.model.H, self.R, Gamma=Gamma)
        else:
            self.kf.set_model(self.model.Phi, self.model.Q, self.model.H, self.R)
        self.kf.stationary()
        self._build_anchor(v, gd, h)

    # --- gating ----------------------------------------------------------------------------
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

    # --- mass feedback and re-filtering ----------------------------------------------------
    def feed_back_mass(self, me: MassEstimator, h: float, speed: float, time: float) -> None:
        """After ``me`` took this step's sample: open a re-filter episode at a detected payload
        change, and rebuild the filter at the since-change mass when it disagrees with the model
        mass, re-filtering the change within the episode (module doc). ``time`` is not used:
        this filter keeps its own clock (``self.time``)."""
        cfg = self.cfg
        if me.resets != self._resets_seen:  # a payload change detected
            self._resets_seen = me.resets
            if self._episode_closed():  # else: still part of the open one (e.g. the start)
                self._onset = self.time - cfg.tuning.refilter_lookback
                self._confirmed_for = 0.0
        self._before_feedback(speed, h)
        if cfg.mass_feedback and me.samples * h >= cfg.tuning.mass_warmup and self._takes_mass():
            t = cfg.tuning
            m, sd, agree = me.agrees_with(self.m_model, t.mass_rebuild_tol, t.mass_rebuild_sigma, h)
            # the model mass is confirmed by enough data: closes the re-filter episode
            # (road_estimator 2: and the damping estimated, whose first value also re-filters)
            agree_all = agree and math.isfinite(sd) and self._damping_known(me)
            self._confirmed_for = self._confirmed_for + h if agree_all else 0.0
            # outside a re-filter episode a rebuild cannot be re-filtered: only a large change
            # (the episode is looked at only when a rebuild is in question: not per step)
            if not agree and self.time - self._last_rebuild >= t.mass_rebuild_interval:
                in_episode = t.refilter_span > 0 and not self._episode_closed()
                if in_episode or abs(m - self.m_model) > t.mass_rebuild_tol_late * self.m_model:
                    self.m_model = m
                    self._last_rebuild = self.time
                    self.mass_rebuilds += 1
                    if t.refilter_span > 0:
                        self._ensure_model(speed, h)  # rebuild now and re-filter the change
                        if in_episode:
                            self._refilter()
            self._feed_back_damping(me, h, speed)

    def _filter(self, z: np.ndarray, rows) -> None:
        """Replay one recorded step: rows None = full update, else the rows used (may be none)."""
        _apply(self.kf, z, rows)
        self._follow(z, rows, replay=True)
        self._compare(replay=True)

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
        _, k0, x0, P0, stationary, anchor = snap
        kf = self.kf
        kf.start_at(x0.copy(), P0.copy())
        if stationary:  # at the old model's fixed point: start at the new model's
            kf.stationary()
        self._restore_anchor(anchor)
        for k, z, rows in self._record:
            if k > k0:
                self._filter(z, rows)
        self.refilters += 1
        return True

    def _episode_closed(self) -> bool:
        return (self._confirmed_for >= self.cfg.tuning.refilter_confirm
                or self.time - self._onset > self._span())

    def _span(self) -> float:
        """s after the onset of a mass-change episode within which a rebuild re-filters:
        ``refilter_span``, or ``damping_refilter_span`` for the episode at the start of the run
        when the damping is estimated (anchored_road.py): its first value comes 1.6-2.02 s into
        the data, at the edge of a 2 s span, and the mass rebuilds at it and after it belong to
        the same episode."""
        t = self.cfg.tuning
        if self._onset == 0.0 and self._long_first_episode():
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

    # --- what road_estimator 2 adds (anchored_road.py); nothing here -------------------------
    def _model_noise(self) -> tuple[ModelNoise, int]:
        """(the model's process noise, the number of force-error states it appends)."""
        return self.cfg.tuning.model_noise, 0

    def _init_anchor(self) -> None:
        """Make the filters that run beside ``kf`` (right after it: a saved FMU state lists them
        before the caches that refer to their models)."""

    def _active(self) -> tuple[LinearKF, DiscreteModel | None]:
        """The filter whose road and covariance the outputs follow, and its model."""
        return self.kf, self.model

    def _restart_anchor(self, from_rest: bool) -> None:
        pass

    def _anchor_snapshot(self, stationary: bool | None) -> tuple | None:
        return None

    def _restore_anchor(self, saved: tuple | None) -> None:
        pass

    def _anchor_current(self) -> bool:
        """The filters beside ``kf`` are built for the current damping."""
        return True

    def _build_anchor(self, v: float, gd: float, h: float) -> None:
        pass

    def _follow(self, z: np.ndarray, rows, replay: bool = False) -> None:
        """The update decisions of ``kf`` (``rows``) for the filters beside it."""

    def _anchor_sum(self) -> float:
        return 0.0

    def _compare(self, replay: bool = False) -> None:
        """After the update: compare the filters."""

    def _before_feedback(self, speed: float, h: float) -> None:
        pass

    def _takes_mass(self) -> bool:
        return True

    def _damping_known(self, me: MassEstimator) -> bool:
        return True

    def _feed_back_damping(self, me: MassEstimator, h: float, speed: float) -> None:
        pass

    def _long_first_episode(self) -> bool:
        return False

    def _output(self, x: list, h: float, ds: float) -> tuple[list, float]:
        """(the output state from the filter's ``x``, the start's variance m^2)."""
        return x, 0.0

    def _variance_factor(self) -> float:
        return 1.0
