"""The IMM of paper 002 as a joint road and sprung-mass estimator of ``SuspensionEstimator``
(``mass_estimator`` 2 and 4, with ``road_estimator`` 0): the road, body and wheel from the mixed
filter (eqs. 31-32), the sprung mass from the model probabilities.

- ``IMMRoad`` (code 2), paper 002's fixed bank: ``imm_models`` sub-models at sprung masses evenly
  spaced over [``imm_mass_min``, ``imm_mass_max``] (kg), transition probability ``imm_stay`` of
  keeping the model per step (the rest shared equally, ``imm.transition_matrix``); the mass is
  sum_i mu_i m_i, averaged over the last ``imm_window`` s (paper 002's n-step window). Between
  its grid points it snaps to the nearest model (docs/imm.md).
- ``MovingIMMRoad`` (code 4): ``imm.MovingMassIMM``, five models around a centre that follows
  the windowed maximum-likelihood mass, starting at ``m_s_nominal`` and kept within 0.1-10 times
  it (as the RLS); as good between any grid points as on them. ``imm_mass_min`` / ``imm_mass_max``
  and ``imm_models`` are those of code 2 only.

Both identify the damping as the default estimator does (``mass.MassEstimator`` on [m_s, c],
paper 001's force balance) and re-discretise their sub-models at it once it is known (then at a
change of more than ``damping_rebuild_tol``): a bank over the mass alone told a damping 20 % off
explains the body with a mass 14-19 % off (docs/imm.md). ``estimate_damping`` False keeps c_s.

The sub-models' road intensity is that of ISO class max(assumed class, ``q_class_min``), the
assumed class being ``road_class`` or, with ``road_class`` 0, the class the composer identifies
online (``set_road_class``: eqs. 33-37 in road_class.py) or ``default_class`` before it; the
sub-models' road corner is ``imm_road_n_hi`` (1/m). The sub-models are re-discretised when the
speed moves by ``speed_rebuild_tol`` (relative), the step or the class changes.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..plant import iso8608
from ..plant.vehicle import VEHICLE_RANGES, check_range
from .imm import MassIMM, MovingMassIMM
from .interface import RoadFilter
from .mass import MassEstimator

# the start covariance of every filter (m^2, m^2/s^2): 1 cm, 1 cm/s on every state, as measured in
# benchmarks/imm_offgrid.py. The KF's start (0.1 mm on body and wheel) gives an S of condition
# ~1e11 at the first update, where filterpy's likelihood (tests/test_imm_fmu.py) loses all digits
P_START = 1e-4 * np.eye(6)
MOVING_MODELS = 5  # models of the moving bank (MovingMassIMM's default)


def imm_problems(cfg) -> list[str]:
    """Messages for IMM parameters out of range or not fitting together (empty when valid)."""
    t = cfg.tuning
    msgs = [check_range(name, float(getattr(cfg, name)), *VEHICLE_RANGES["m_s"])
            for name in ("imm_mass_min", "imm_mass_max")]
    if not any(msgs) and not float(cfg.imm_mass_min) < float(cfg.imm_mass_max):
        msgs.append(f"imm_mass_min = {cfg.imm_mass_min!r} must be below imm_mass_max = {cfg.imm_mass_max!r}")
    n = cfg.imm_models
    if isinstance(n, bool) or float(n) != int(n) or not 2 <= int(n) <= 25:
        msgs.append(f"imm_models = {n!r} is outside the allowed range [2, 25] (an integer)")
    msgs += [check_range("imm_stay", float(cfg.imm_stay), 0.0, 1.0, low_inclusive=False, high_inclusive=False),
             check_range("imm_window", float(t.imm_window), 0.0, 10.0),
             check_range("imm_road_n_hi", float(t.imm_road_n_hi), 0.1, 1e3)]
    return [m for m in msgs if m]


class IMMRoad(RoadFilter):
    """``mass_estimator`` 2: paper 002's IMM over a fixed bank of sprung masses (module doc)."""

    def __init__(self, cfg):
        super().__init__(cfg)
        msgs = imm_problems(cfg)
        if msgs:
            raise ValueError("; ".join(msgs))
        self.std = (float(cfg.acc_sprung_noise_std), float(cfg.acc_unsprung_noise_std), float(cfg.defl_noise_std))
        self.road = replace(cfg.tuning.road_model, n_hi=float(cfg.tuning.imm_road_n_hi))
        self.noise = replace(cfg.tuning.model_noise, q_f=0.0)
        damping = True if cfg.tuning.estimate_damping is None else bool(cfg.tuning.estimate_damping)
        self.damping_est = MassEstimator(cfg.m_s_nominal, cfg.k_s, cfg.c_s, cfg.forgetting_factor, True) \
            if damping else None
        self.c_model = float(cfg.c_s)
        self.imm: MassIMM | None = None
        self.speed = None
        self.gd = None
        self.damping_rebuilds = 0
        self._win: np.ndarray | None = None  # the last masses of the window (code 2)
        self._win_k, self._win_sum = 0, 0.0  # samples into it, and their sum
        self.given_class = 0  # the composer's online class (set_road_class), 0 = none yet

    def set_road_class(self, road_class: int) -> None:
        """The composer's online class: the sub-models' road intensity follows it (``_gd``)."""
        self.given_class = int(road_class)

    # --- the bank ------------------------------------------------------------------------------
    def _gd(self) -> float:
        cfg = self.cfg
        cls = int(cfg.road_class) or self.given_class or int(cfg.tuning.default_class)
        return iso8608.class_psd_n0(max(cls, int(cfg.tuning.q_class_min)))

    def _vehicle(self):
        return self.cfg.vehicle().with_(c_s=self.c_model)

    def _make(self, speed: float, h: float) -> MassIMM:
        cfg = self.cfg
        masses = np.linspace(float(cfg.imm_mass_min), float(cfg.imm_mass_max), int(cfg.imm_models))
        return MassIMM(masses, self._vehicle(), speed, self.gd, h, self.std, stay=float(cfg.imm_stay),
                       road=self.road, noise=self.noise, P0=P_START)

    def _ensure(self, speed: float, h: float) -> None:
        v = max(speed, 0.1)
        gd = self._gd()
        c = self.c_model
        de = self.damping_est
        if de is not None and de.damping_identified and \
                abs(de.damping - c) > self.cfg.tuning.damping_rebuild_tol * c:
            c = self.c_model = float(de.damping)
            self.damping_rebuilds += 1
        elif self.imm is not None and h == self.h and gd == self.gd and \
                abs(v - self.speed) <= self.cfg.tuning.speed_rebuild_tol * self.speed:
            return
        self.gd, self.speed = gd, v
        if self.imm is None:
            self.imm = self._make(v, h)
        else:
            self.imm.rebuild(vehicle=self._vehicle(), speed=v, gd_n0=gd, h=h)
        self.h = h
        self.model_builds += 1

    # --- RoadFilter ------------------------------------------------------------------------------
    def step(self, z: np.ndarray, rows: np.ndarray | None, speed: float, h: float) -> None:
        de = self.damping_est
        if de is not None:
            ok = rows is None or (0 in rows and 2 in rows)
            x = self.x
            de.update(float(z[0]) if ok else 0.0, float(z[2]) if ok else x[0] - x[2], h, use=ok)
        self._ensure(speed, h)
        imm = self.imm
        if rows is None:
            imm.step(z)
        elif len(rows):
            imm.predict()
            imm.update(z, rows)
        else:
            imm.predict_only()
        self.x = imm.x.tolist()
        self.road_variance = float(imm.P[4, 4])
        self.nis = float(imm.mu @ imm.quad)
        self.mass = self._mass(h)

    def _mass(self, h: float) -> float:
        """Paper 002 reads the mass over a window of n steps (its Table 4): the mean of
        sum_i mu_i m_i over the last ``imm_window`` s. On its grid the bank jumps to another
        model for 1-60 ms now and then (ISO A, 20 m/s: 166 excursions beyond ±5 % in 25 s)."""
        m = self.imm.mass
        n = max(1, int(round(float(self.cfg.tuning.imm_window) / h)))
        if n == 1:
            return m
        if self._win is None or len(self._win) != n:
            self._win, self._win_k, self._win_sum = np.zeros(n), 0, 0.0
        i = self._win_k % n
        self._win_sum += m - self._win[i]
        self._win[i] = m
        self._win_k += 1
        if i == n - 1:
            self._win_sum = float(self._win.sum())  # no drift of the running sum
        return self._win_sum / min(self._win_k, n)

    def reset(self) -> None:
        self._win = None
        imm = self.imm
        if imm is not None:
            imm.xs[:] = 0.0
            imm.Ps[:] = P_START
            imm.mu = np.full(imm.r, 1.0 / imm.r)
            imm.combine()
            self.x = imm.x.tolist()
        else:
            self.x = [0.0] * 6


class MovingIMMRoad(IMMRoad):
    """``mass_estimator`` 4: the IMM whose bank follows the mass (imm.MovingMassIMM; module doc)."""

    def _mass(self, h: float) -> float:
        return self.imm.mass  # the bank's centre, already a windowed maximum-likelihood mass

    def _make(self, speed: float, h: float) -> MassIMM:
        cfg = self.cfg
        m0 = float(cfg.m_s_nominal)
        lo, hi = VEHICLE_RANGES["m_s"][:2]
        return MovingMassIMM(m0, self._vehicle(), speed, self.gd, h, self.std, r=MOVING_MODELS,
                             stay=float(cfg.imm_stay), road=self.road, noise=self.noise, P0=P_START,
                             bounds=(max(0.1 * m0, lo), min(10.0 * m0, hi)))

    def reset(self) -> None:
        super().reset()
        imm = self.imm
        if imm is not None:
            imm._n = 0
            imm._score[:] = 0.0
