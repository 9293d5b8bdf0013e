"""The half car's active suspension: passive, skyhook or the LQR of ``lqr`` with its weights
scheduled (``schedule``) or fixed, the forces saturated at the actuator's limit.

Every mode is a state feedback u = -K xi on the relative states of ``lqr`` (passive K = 0, skyhook
K of ``lqr.skyhook_gain``), so the closed loop of any configuration is A - B K on the design model:
``check`` refuses one that is not asymptotically stable. The LQR is designed for the car given
at the sprung mass of the input, rounded to ``MASS_STEP``; the schedule is read at the speed
rounded to ``SPEED_STEP``. A gain is computed only when its key (mass and weights) is new, and the
last ``CACHE`` gains are kept, so an estimate that wanders by grams does not redesign every step.
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from .lqr import DesignModel, skyhook_gain
from .schedule import Schedule, load_schedule
from ..plant.half_car import HalfCarParams

PASSIVE, SKYHOOK, LQR_SCHEDULED, LQR_FIXED = 0, 1, 2, 3
MODES = {PASSIVE: "passive", SKYHOOK: "skyhook", LQR_SCHEDULED: "LQR, weights scheduled",
         LQR_FIXED: "LQR, fixed weights"}
MASS_STEP = 1.0  # kg: far below the schedule's 84 kg between masses
SPEED_STEP = 0.5  # m/s: a tenth of the schedule's 5 m/s between speeds
CACHE = 64  # gains kept
MIN_MARGIN = 1e-6  # 1/s: the slowest closed-loop mode must decay faster than this to count as stable
# read once, at import: a host may delete an FMU's folder when an instance is freed (FMPy does),
# and later instances of that FMU in the process share this module
SHIPPED = load_schedule()


@dataclass(frozen=True)
class Command:
    """One step's output: the forces demanded and applied (N, front and rear), whether the limit
    cut either, and the LQR weights in use (q1, q2, q3; zeros outside the LQR modes)."""

    demand: tuple[float, float]
    force: tuple[float, float]
    saturated: bool
    weights: tuple[float, float, float]


class SuspensionController:
    """Forces of one half car from its relative states (``lqr.STATES``).

    ``car`` is the controller's model of the car (its m_s unused: the mass is an input);
    ``force_limit`` (N) the actuator's limit, ``c_sky`` (N.s/m) the skyhook damping, ``weights``
    (q1, q2, q3) those of ``LQR_FIXED``, ``schedule`` that of ``LQR_SCHEDULED`` (default: the
    shipped one, ``SHIPPED``). Raises ValueError naming the setting for one out of range.
    """

    def __init__(self, car: HalfCarParams, mode: int, force_limit: float, c_sky: float = 0.0,
                 weights: tuple[float, float, float] | None = None, schedule: Schedule | None = None):
        if problems := car.problems():
            raise ValueError("; ".join(problems))
        if mode not in MODES:
            raise ValueError(f"mode = {mode!r} is not one of {MODES}")
        if mode == LQR_FIXED and weights is None:
            raise ValueError(f"mode = {LQR_FIXED} ({MODES[LQR_FIXED]}) needs the weights")
        if not 0.0 < force_limit < np.inf:
            raise ValueError(f"force_limit = {force_limit!r} N must be positive and finite")
        if not 0.0 <= c_sky < np.inf:
            raise ValueError(f"c_sky = {c_sky!r} N.s/m must be >= 0 and finite")
        self.car, self.mode, self.force_limit = car, mode, float(force_limit)
        self.weights = tuple(float(q) for q in weights) if weights is not None else None
        self.schedule = (schedule or SHIPPED) if mode == LQR_SCHEDULED else None
        self._fixed = {PASSIVE: np.zeros((2, 8)), SKYHOOK: skyhook_gain(car, c_sky)}.get(mode)
        self._gains: OrderedDict[tuple, np.ndarray] = OrderedDict()
        self.designs = 0  # LQR gains computed

    def gain(self, speed: float, road_class: int, sprung_mass: float) -> tuple[np.ndarray, tuple[float, float, float]]:
        """(K, weights) at the working condition: speed (m/s), ISO class 0..8 (0: not known),
        sprung mass (kg)."""
        if self._fixed is not None:
            return self._fixed, (0.0, 0.0, 0.0)
        m = max(MASS_STEP, MASS_STEP * round(sprung_mass / MASS_STEP))
        if self.mode == LQR_FIXED:
            q = self.weights
        else:
            q = self.schedule.weights(SPEED_STEP * round(speed / SPEED_STEP), road_class, m)
        key = (m, q)
        K = self._gains.get(key)
        if K is None:
            K = self._design(m, q)
            self._gains[key] = K
            if len(self._gains) > CACHE:
                self._gains.popitem(last=False)
        else:
            self._gains.move_to_end(key)
        return K, q

    def _design(self, m: float, q: tuple[float, float, float]) -> np.ndarray:
        model = DesignModel.of(self.car.with_(m_s=m))
        self.designs += 1
        K = model.gain(*q)
        if (margin := model.margin(K)) < MIN_MARGIN:
            raise ValueError(f"the LQR at sprung_mass = {m:g} kg, q1 = {q[0]:g}, q2 = {q[1]:g}, q3 = {q[2]:g} leaves "
                             f"a closed loop that is not asymptotically stable (slowest decay {margin:+.3g} 1/s)")
        return K

    def check(self, speed: float, road_class: int, sprung_mass: float) -> None:
        """Raise ValueError, with the reason, unless the closed loop of the design model at this
        working condition is asymptotically stable (every eigenvalue's real part below -MIN_MARGIN)."""
        head = f"mode = {self.mode} ({MODES[self.mode]}) at sprung_mass = {sprung_mass:g} kg"
        try:
            K, _ = self.gain(speed, road_class, sprung_mass)
        except ValueError as e:
            raise ValueError(f"{head}: {e}") from None
        margin = DesignModel.of(self.car.with_(m_s=sprung_mass)).margin(K)
        if margin < MIN_MARGIN:
            why = (": c_f = c_r = 0 and no actuator damping leave the car undamped"
                   if self.car.c_f == self.car.c_r == 0.0 and not K.any() else "")
            raise ValueError(f"{head}: the closed loop is not asymptotically stable (slowest decay "
                             f"{margin:+.3g} 1/s, at least {MIN_MARGIN:g} needed){why}")

    def command(self, state, speed: float, road_class: int, sprung_mass: float) -> Command:
        """The forces for the relative states ``state`` (``lqr.STATES``, SI units)."""
        K, q = self.gain(speed, road_class, sprung_mass)
        demand = -K @ np.asarray(state, dtype=float)
        if not np.all(np.isfinite(demand)):
            raise ValueError(f"the force demand {demand.tolist()} N is not finite")
        force = np.clip(demand, -self.force_limit, self.force_limit)
        return Command((float(demand[0]), float(demand[1])), (float(force[0]), float(force[1])),
                       bool(np.any(np.abs(demand) > self.force_limit)), q)
