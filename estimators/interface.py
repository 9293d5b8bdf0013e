"""The one small interface of the estimators that ``SuspensionEstimator`` composes, and the
registry of every ``road_estimator`` and ``mass_estimator`` code.

``SuspensionEstimator`` (suspension.py) owns what is common to every estimator: the sample
checks (non-finite or frozen channels), ``status``, re-initialisation after a non-finite state,
the online road class, the IRI and the contract's outputs. An estimator owns its model, its state
and its own step-size bookkeeping. Adding one touches its own module, one line of the registry
below, its code, name and meaning in the contract (the registry takes the codes from there), and
the docs.

Codes 0-2 of ``road_estimator`` and 0-1 of ``mass_estimator`` are the KF family, road filters
too (kf_road.KFRoad, anchored_road.AnchoredRoad for code 2) that ``SuspensionEstimator`` makes
itself: they gate their samples and re-initialise on their own terms, and take the mass
feedback through ``KFRoad.feed_back_mass``, which re-filters a payload change. Every other code
names a ``RoadFilter`` subclass.
A mass code with a class of its own is a joint estimator: it gives the road too, and says which
road codes it goes with (``roads``).
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..suspension_fmi import contract
from .model import IZS, IZU

if TYPE_CHECKING:  # pragma: no cover
    from .mass import MassEstimator
    from .suspension import EstimatorConfig

# the state every estimator reports, in this order (m, m/s), at the instant of the sample
STATE = ("z_s", "v_s", "z_u", "v_u", "z_r", "v_r")


class RoadFilter:
    """Base of the estimators composed by ``SuspensionEstimator`` (codes beyond its KF family).

    A subclass implements ``__init__(cfg)`` (raise ``ValueError`` naming a bad parameter and its
    range) and ``step``, and keeps the attributes below current after each step.

    Attributes:
        x: 6 floats [z_s, v_s, z_u, v_u, z_r, v_r] (m, m/s), filtered estimate x_{k|k}.
        road_variance: m^2, the variance of x[4] the estimator stands for (``road_height_std``).
        nis: normalised innovation squared of the last update (0 when none).
        mass: kg, its own sprung-mass estimate, or None when it has none (the composer's
            ``mass_estimator`` 1 then estimates it and passes it on through ``set_mass``).
        h: s, the step its model is built for (None before the first step).
        model_builds: how many times it (re-)built its model: a test counts them.
        road_class: the ISO class (1..8) it identified itself and reports as ``road_class_est``,
            or None (the composer's class of the estimated road is reported).
        check: its self-diagnosis (sensor_check.InnovationCheck), whose INCONSISTENT state the
            composer reports as ``status`` 3, or None.
        reference: (f_ref Hz, zeta_ref) of the common-mode reference its road carries, which
            road_height_est takes off (road_profile.Profiler), or None.
        z_shift: m added to z_s and z_u for z_s_est and z_u_est (the KF family's lag of its
            reference), or None.

    The composer calls ``checked_step``, then ``feed_back_mass`` (with ``mass_estimator`` 1), then
    ``finish_step``, and reads
    the attributes after that; the defaults below suit an estimator that only implements ``step``.
    """

    x: list[float]
    road_variance: float = 0.0
    nis: float = 0.0
    mass: float | None = None
    h: float | None = None
    model_builds: int = 0
    road_class: int | None = None  # ISO class 1..8 the estimator itself identified (road_class_est), or None
    check = None
    reference: tuple[float, float] | None = None
    z_shift: float | None = None
    # the mass feedback (feed_back_mass): the sprung mass last given (kg; None: the nominal), how
    # many times one was given, and when (s)
    m_model: float | None = None
    mass_rebuilds: int = 0
    _mass_given_at: float = -math.inf

    def __init__(self, cfg: "EstimatorConfig"):
        self.cfg = cfg
        self.x = [0.0] * len(STATE)

    def step(self, z: np.ndarray, rows: np.ndarray | None, speed: float, h: float) -> None:
        """One sample z = [acc_sprung (m/s^2), acc_unsprung (m/s^2), deflection (m)].

        ``rows`` None: every channel is valid; else the indices of the valid ones (possibly none:
        predict only). ``speed`` m/s, finite and >= 0. ``h`` s since the previous sample, already
        snapped to ``self.h`` by the caller when it differs from it by rounding only."""
        raise NotImplementedError

    def checked_step(self, z: np.ndarray, rows: np.ndarray | None, speed: float, h: float,
                     ds: float) -> tuple[np.ndarray | None, bool]:
        """``step``, then ``reset`` when the estimate is not finite. ``ds``: m travelled in the
        step (0 while the car stands). Returns (the rows the update used, None for all; whether
        the estimator re-initialised): the composer's ``status``."""
        self.step(z, rows, speed, h)
        if math.isfinite(sum(state_list(self.x)) + float(self.road_variance)):
            return rows, False
        self.reset()
        return rows, True

    def finish_step(self, h: float, ds: float) -> None:
        """After the composer's mass feedback for this step (``set_mass``); nothing by default."""

    def missing_speed(self, last: float) -> float:
        """The speed (m/s) for a sample whose speed is not finite: ``last``, the last finite one."""
        return last

    def substitutes(self) -> tuple[float, float]:
        """The body acceleration (m/s^2) and deflection (m) the mass regression takes for a
        left-out sample (it feeds only its filters with them): by default none (0) and the
        state's z_s - z_u."""
        x = state_list(self.x)
        return 0.0, x[IZS] - x[IZU]

    def restart(self) -> None:
        """The car moves off for the first time, having stood since the start: the estimate
        restarts from rest (``reset`` by default)."""
        self.reset()

    def feed_back_mass(self, me: "MassEstimator", h: float, speed: float, time: float) -> None:
        """The composer's ``mass_estimator`` 1 (mass.MassEstimator) took this step's sample: take
        its since-change mass through ``set_mass`` when it disagrees with the mass last given, at
        most every ``mass_rebuild_interval`` s (the KF family re-filters the change instead:
        kf_road.KFRoad). ``speed`` m/s, ``time`` s since the start."""
        t = self.cfg.tuning
        if not (self.cfg.mass_feedback and me.samples * h >= t.mass_warmup):
            return
        given = float(self.cfg.m_s_nominal) if self.m_model is None else self.m_model
        m, _, agree = me.agrees_with(given, t.mass_rebuild_tol, t.mass_rebuild_sigma, h)
        if not agree and time - self._mass_given_at >= t.mass_rebuild_interval:
            self.m_model, self._mass_given_at = m, time
            self.mass_rebuilds += 1
            self.set_mass(m)

    def set_mass(self, m_s: float) -> None:
        """The sprung mass (kg) the composer's mass estimator identified; ignored by default."""

    def set_road_class(self, road_class: int) -> None:
        """The ISO class (1..8) the composer's classifier identified online (road_class.py), each
        time it changes. Ignored by default."""

    def reset(self) -> None:
        """Back to the start state (the composer calls it after a non-finite estimate)."""
        raise NotImplementedError


@dataclass(frozen=True)
class Code:
    """One code of ``road_estimator`` or ``mass_estimator``: ``name`` for messages (the
    contract's short name); ``factory`` "module:Class" of a ``RoadFilter`` in this package, or
    None for ``SuspensionEstimator``'s own KF family; ``roads``: for a joint mass estimator, the
    road codes it goes with (None: any)."""

    name: str
    factory: str | None = None
    roads: tuple[int, ...] | None = None


# the codes, their names and meanings are the contract's (suspension_fmi/contract.py); here only
# what implements each code beyond the KF family, and which road codes a joint estimator takes
KF_FAMILY = {"road_estimator": (0, 1, 2), "mass_estimator": (0, 1)}
_ROAD_FACTORIES = {3: "airspring_observers:NonlinearRoadFilter", 4: "vb_akf:VBRoadFilter",
                   5: "airspring_observers:UKFRoadFilter"}
_MASS_FACTORIES = {2: ("imm_filter:IMMRoad", (0,)), 3: ("airspring_observers:DualObserverFilter", (3, 5)),
                   4: ("imm_filter:MovingIMMRoad", (0,))}
ROAD_ESTIMATORS: dict[int, Code] = {k: Code(name, _ROAD_FACTORIES.get(k))
                                    for k, (name, _) in contract.ROAD_ESTIMATORS.items()}
MASS_ESTIMATORS: dict[int, Code] = {k: Code(name, *_MASS_FACTORIES.get(k, (None, None)))
                                    for k, (name, _) in contract.MASS_ESTIMATORS.items()}


def unimplemented_codes() -> list[str]:
    """The contract's codes that nothing implements (neither the KF family nor a factory here),
    and factories of codes the contract does not list: empty when the two agree."""
    out = []
    for what, codes, factories in (("road_estimator", ROAD_ESTIMATORS, _ROAD_FACTORIES),
                                   ("mass_estimator", MASS_ESTIMATORS, _MASS_FACTORIES)):
        out += [f"{what} {k}" for k, c in codes.items() if c.factory is None and k not in KF_FAMILY[what]]
        out += [f"{what} {k} (not in the contract)" for k in factories if k not in codes]
    return out


def code_problems(road: int, mass: int) -> list[str]:
    """Messages for an unknown code or a combination that does not go together."""
    msgs = []
    for name, val, codes in (("road_estimator", road, ROAD_ESTIMATORS), ("mass_estimator", mass, MASS_ESTIMATORS)):
        if val not in codes:
            msgs.append(f"{name} = {val!r} is outside the allowed values "
                        f"{{{', '.join(f'{k} = {c.name}' for k, c in sorted(codes.items()))}}}")
    if not msgs:
        m = MASS_ESTIMATORS[mass]
        if m.roads is not None and road not in m.roads:
            msgs.append(f"mass_estimator = {mass} ({m.name}) gives the road itself and needs road_estimator in "
                        f"{{{', '.join(str(r) for r in m.roads)}}}, not {road}")
    return msgs


def composed_factory(road: int, mass: int) -> type[RoadFilter] | None:
    """The ``RoadFilter`` class the codes select (a joint mass estimator's first), else None."""
    spec = MASS_ESTIMATORS[mass].factory or ROAD_ESTIMATORS[road].factory
    if spec is None:
        return None
    module, cls = spec.split(":")
    return getattr(importlib.import_module(f".{module}", __package__), cls)


def preload() -> None:
    """Import every registered estimator's module now (``suspension.py`` calls it when it is
    imported). A host may delete the folder it unpacked an FMU into while another instance of the
    same FMU, which shares these modules, runs on (FMPy's ``simulate_fmu`` does): a module first
    imported after that is not found."""
    for c in (*ROAD_ESTIMATORS.values(), *MASS_ESTIMATORS.values()):
        if c.factory is not None:
            importlib.import_module(f".{c.factory.split(':')[0]}", __package__)


def state_list(x: Sequence[float]) -> list[float]:
    """A state as the 6 plain floats of ``STATE`` (a longer state keeps its first six)."""
    return [float(v) for v in list(x)[:len(STATE)]]
