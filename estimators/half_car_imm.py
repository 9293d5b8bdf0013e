"""Paper 002's observers on the half car: KF, AKF, IMMKF, IMMAKF3 and IMMAKF5 (eqs. 18-44).

All five run the model of ``half_car_kf`` with the actuator forces as a known input. The paper
builds each observer on the closed loop A - B K of its LQR (eqs. 15-16), which holds for one gain
only (and its gains change with the working condition, Table A.1); with the forces an input the
same observer serves any controller, and its sub-models differ only in what the paper's differ in
besides the gain: the sprung mass (eq. 21's A_i, B_i) and the road grade (Q, eq. 40).

    KF        one filter at ``m_s_nominal`` on a road of class ``road_class`` (the paper's KF: 20 m/s,
              ISO C, 400 kg);
    AKF       the same filter, Q switched to the ISO class identified online (eqs. 33-37);
    IMMKF     an IMM (eqs. 18-32, estimators/imm.py) of ``imm_models`` filters at sprung masses
              evenly spread over [imm_mass_min, imm_mass_max], on a road of class ``road_class``;
    IMMAKF3/5 a bank of IMMs, one per road grade, each of 3 (5) mass sub-models over the same
              range (the paper's 300, 400, 500 kg and 300..500 kg by 50), the IMM of the grade
              identified online in use. The grade IMMs share their sub-models' A_i, B_i and H and
              differ in Q only, so switching the grade is switching Q under the running IMM: its
              states, covariances and probabilities carry over.

The grade is identified from the estimated front road (Step 5) by estimators/road_class.py (eq. 37
corrected, Welch, hysteresis); ``road_class_est`` is that class for every code (``road_class``
until the first window is full), and the adaptive codes switch Q with it.

The sprung mass is the probability-weighted mass of the bank, sum_i mu_i m_i (eq. 31 applied to
the masses), and its spread sqrt(sum_i mu_i (m_i - m)^2) its std; for KF and AKF the nominal
mass, std 0. The paper takes the most probable model over a 500-step window (Table 4).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ..plant.half_car import DEFAULT_HALF_CAR, HalfCarParams
from ..plant.quarter_car import SensorNoise
from ..plant.step_size import same_step
from .half_car_kf import (ESTIMATES, IQF, ROAD_NOISE_RULES, HalfCarKF, HalfCarModel, equilibrium, estimate_matrix,
                          has_force_errors, measurement_noise, state_count)
from .imm import IMM, transition_matrix
from .kalman import LinearKF, stationary_covariance
from .road_class import RoadClassifier
from .sensor_check import CONSISTENT, InnovationRatio

# code -> (mass sub-models: 0 = one filter, None = imm_models; Q switched by the identified grade)
CODES: dict[int, tuple[int | None, bool]] = {0: (0, False), 1: (0, True), 2: (None, False), 3: (3, True),
                                             4: (5, True)}
_NOISE = SensorNoise()


@dataclass(frozen=True)
class ObserverSettings:
    """The observer's settings besides the vehicle (``HalfCarParams``, whose m_s is ignored:
    ``m_s_nominal`` is the model's). Units: kg, m/s^2, m, m/s."""

    estimator: int = 4  # CODES: IMMAKF5, the paper's best
    sensors: int = 0  # 0 = accelerations and deflections (a real car), 1 = the paper's velocities
    m_s_nominal: float = DEFAULT_HALF_CAR.m_s  # the KF's and AKF's sprung mass
    # a side's payload from empty to fully laden: +-200 kg about the nominal mass
    imm_mass_min: float = DEFAULT_HALF_CAR.m_s - 200.0
    imm_mass_max: float = DEFAULT_HALF_CAR.m_s + 200.0
    imm_models: int = 5  # IMMKF's sub-models (the paper's IMMKF: 5)
    imm_stay: float = 0.999  # probability of keeping a sub-model per step
    road_class: int = 3  # ISO class the KF and IMMKF assume and the others start from (the paper's C)
    road_noise: int = 0  # 0 = eq. 5's ISO intensity at the speed, 1 = eqs. 38-40 (ROAD_NOISE_RULES)
    acc_sprung_noise_std: float = _NOISE.acc_sprung
    acc_unsprung_noise_std: float = _NOISE.acc_unsprung
    defl_noise_std: float = _NOISE.deflection
    velocity_noise_std: float = 0.01  # m/s (rad/s for the pitch rate): the paper's R = 0.01^2
    # N^2/s: intensity of the random walk of each axle's force error (half_car_kf's module doc);
    # 0 = the paper's model, whose velocities feed an LQR a negative spring when the springs are
    # softer than the model's
    force_error_q: float = 100.0

    def problems(self) -> list[str]:
        """What the contract's ranges cannot say: the mass range must be a range."""
        if self.estimator in CODES and CODES[self.estimator][0] != 0 and not self.imm_mass_min < self.imm_mass_max:
            return [f"imm_mass_min = {self.imm_mass_min!r} kg must be below imm_mass_max = {self.imm_mass_max!r} kg"]
        return []


class MassBank:
    """An IMM over sub-models at ``masses`` (kg), Q set per road class and speed (the grade IMMs
    of IMMAKF share everything else, module doc)."""

    def __init__(self, params: HalfCarParams, masses: np.ndarray, h: float, sensors: int, R: np.ndarray,
                 stay: float, x0: np.ndarray, P0: np.ndarray, force_error_q: float = 0.0):
        self.params, self.masses, self.sensors = params, np.asarray(masses, float), int(sensors)
        self.force_error_q = float(force_error_q)
        self._set_models(h)
        M = transition_matrix(len(self.masses), stay)
        self.imm = IMM([m.Phi for m in self.models], [np.zeros_like(m.Phi) for m in self.models],
                       [m.C for m in self.models], R, M, x=x0, P=P0)
        self.key: tuple[int, float, str] | None = None

    def _set_models(self, h: float) -> None:
        self.models = [HalfCarModel.build(self.params.with_(m_s=float(m)), h, self.sensors, self.force_error_q)
                       for m in self.masses]
        self.Bd = np.array([m.Bd for m in self.models])  # (r, n, 2)
        self.D = np.array([m.D for m in self.models])  # (r, m, 2)

    def set_step(self, h: float) -> None:
        self._set_models(h)
        self.imm.Phi = np.array([m.Phi for m in self.models])
        self.key = None

    def step(self, y: np.ndarray | None, u: np.ndarray, road_class: int, speed: float, rule: str) -> None:
        imm = self.imm
        key = (road_class, max(speed, 0.0), rule)
        if key != self.key:
            imm.Q = np.array([m.process_noise(road_class, speed, rule) for m in self.models])
            self.key = key
        bu = self.Bd @ u
        if y is None:
            imm.predict_only(bu)
            return
        imm.predict(bu)
        imm.update(y[None, :] - self.D @ u)  # each sub-model's own feed-through of the forces

    @property
    def x(self) -> np.ndarray:
        return self.imm.x

    @property
    def P(self) -> np.ndarray:
        return self.imm.P

    @property
    def nis(self) -> float:
        """The sub-models' normalised innovation squared of the last update, weighted by their
        probabilities before it (eq. 24's c-bar: the update's own likelihoods would favour the
        model that fits best)."""
        return float(self.imm.cbar @ self.imm.quad)

    @property
    def mass(self) -> float:
        return float(self.imm.mu @ self.masses)

    @property
    def mass_std(self) -> float:
        return float(math.sqrt(max(self.imm.mu @ (self.masses - self.mass) ** 2, 0.0)))


class HalfCarObserver:
    """One of paper 002's observers (``ObserverSettings.estimator``) on the half car ``params``.

    ``step(measured, forces, speed, h)`` takes the measurements of the sensor set at the end of a
    step (``half_car_kf.SENSORS``), the actuator forces held over it (N) and the speed (m/s),
    and returns the estimates: ``ESTIMATES`` with ``_est`` and their ``_std``, the sprung mass
    and its std, the road class, the most probable sub-model and its probability, the
    ``InnovationRatio`` and the status (0 = updated, 1 = a measurement was not finite: predicted
    only, 3 = the innovations are more than ``InnovationRatio.limit`` times what the model
    expects: the car or a sensor is not the model's). The stds are the filter's times
    ``InnovationRatio.std_scale``: on a car that is not the model the filter's own covariance
    understates the errors 2-40 times (docs/half-car-estimator.md).
    """

    def __init__(self, params: HalfCarParams = DEFAULT_HALF_CAR, settings: ObserverSettings = ObserverSettings(),
                 forces: tuple[float, float] = (0.0, 0.0)):
        s = settings
        if s.estimator not in CODES:
            raise ValueError(f"estimator = {s.estimator!r} is not one of {sorted(CODES)}")
        if problems := params.with_(m_s=s.m_s_nominal).problems() + s.problems():
            raise ValueError("; ".join(problems))
        self.params = params.with_(m_s=s.m_s_nominal)
        self.settings = s
        self.rule = ROAD_NOISE_RULES[s.road_noise]
        models, self.adaptive = CODES[s.estimator]
        self.R = measurement_noise(s.sensors, s.acc_sprung_noise_std, s.acc_unsprung_noise_std, s.defl_noise_std,
                                   s.velocity_noise_std)
        n = state_count(has_force_errors(s.sensors, s.force_error_q))
        self.T = estimate_matrix(self.params, n)
        self.x0 = equilibrium(self.params, forces, n)
        self.road_class = int(s.road_class)  # the class Q is built for
        self.classifier = RoadClassifier()
        self.distance = 0.0  # m travelled
        self.h: float | None = None
        self.n_models = s.imm_models if models is None else models
        self.filter: HalfCarKF | MassBank | None = None  # built at the first step, for its h
        self.check = InnovationRatio()

    def _build(self, h: float, speed: float) -> None:
        nominal = self._model(self.params, h)
        if self.n_models == 0:
            self.filter = HalfCarKF(nominal, self.R, self.x0)
            return
        # every sub-model starts from the nominal filter's steady-state covariance
        ss = stationary_covariance(nominal.Phi, nominal.process_noise(self.road_class, speed, self.rule),
                                   nominal.C, self.R)
        P0 = ss[1] if ss is not None else np.eye(len(self.x0)) * 1e-4
        masses = np.linspace(self.settings.imm_mass_min, self.settings.imm_mass_max, self.n_models)
        self.filter = MassBank(self.params, masses, h, self.settings.sensors, self.R, self.settings.imm_stay,
                               self.x0, P0, self.settings.force_error_q)

    def _model(self, params: HalfCarParams, h: float) -> HalfCarModel:
        return HalfCarModel.build(params, h, self.settings.sensors, self.settings.force_error_q)

    def step(self, measured, forces, speed: float, h: float) -> dict[str, float]:
        if self.filter is None:
            self._build(h, speed)
            self.h = h
        elif (h := same_step(h, self.h)) != self.h:
            f = self.filter
            if isinstance(f, HalfCarKF):
                f.set_model(self._model(self.params, h))
            else:
                f.set_step(h)
            self.h = h
        y = np.asarray(measured, float)
        ok = bool(np.all(np.isfinite(y)))
        self.filter.step(y if ok else None, np.asarray(forces, float), self.road_class, speed, self.rule)
        consistent = not ok or self.check.update(self.filter.nis, len(y), h) == CONSISTENT
        self.distance += abs(speed) * h
        identified = self.classifier.update(self.distance, float(self.filter.x[IQF]), speed)
        if identified and self.adaptive:
            self.road_class = identified
        return self._outputs(identified or self.settings.road_class, 1 if not ok else 0 if consistent else 3)

    def _outputs(self, road_class: int, status: int) -> dict[str, float]:
        f = self.filter
        est = self.T @ f.x
        std = self.check.std_scale * np.sqrt(np.maximum(np.sum((self.T @ f.P) * self.T, axis=1), 0.0))
        out = {f"{name}_est": float(v) for name, v in zip(ESTIMATES, est)}
        # the roads' variance is that of the level no sensor sees (module doc of half_car_kf): no std
        out.update({f"{name}_std": float(v) for name, v in zip(ESTIMATES[:8], std[:8])})
        if isinstance(f, MassBank):
            k = int(np.argmax(f.imm.mu))
            out.update(sprung_mass_est=f.mass, sprung_mass_std=f.mass_std, mass_model=k + 1,
                       mass_model_probability=float(f.imm.mu[k]))
        else:
            out.update(sprung_mass_est=float(self.params.m_s), sprung_mass_std=0.0, mass_model=0,
                       mass_model_probability=1.0)
        out.update(road_class_est=int(road_class), innovation_ratio=self.check.ratio, status=status)
        return out


SETTINGS = tuple(f.name for f in fields(ObserverSettings))

# every class whose objects an observer holds: the classes a saved HalfCarEstimator FMU state may name
STATE_CLASSES: tuple[type, ...] = (HalfCarObserver, ObserverSettings, HalfCarParams, HalfCarKF, HalfCarModel,
                                   LinearKF, MassBank, IMM, RoadClassifier, InnovationRatio)
