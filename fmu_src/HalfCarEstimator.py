"""HalfCarEstimator FMU: paper 002's observers (KF, AKF, IMMKF, IMMAKF3, IMMAKF5) on the half car."""
from __future__ import annotations

from suspension_estimation.estimators.half_car_imm import SETTINGS, STATE_CLASSES, HalfCarObserver, ObserverSettings
from suspension_estimation.estimators.half_car_kf import SENSORS
from suspension_estimation.plant.half_car import HalfCarParams
from suspension_estimation.suspension_fmi.slave import ContractSlave

_PARAMS = ("pitch_inertia", "l_f", "l_r", "m_uf", "m_ur", "k_f", "k_r", "c_f", "c_r", "k_tf", "k_tr")


class HalfCarEstimator(ContractSlave):
    description = ("Half-car state observer of paper 002 (KF, AKF, IMMKF, IMMAKF3, IMMAKF5): body, wheel and "
                   "road states, sprung mass and ISO 8608 road class from accelerations and deflections (or "
                   "velocities) and the actuator forces")
    state_attributes = ("core",)
    state_classes = STATE_CLASSES

    def setup(self) -> None:
        params = HalfCarParams(m_s=self.m_s_nominal, **{name: getattr(self, name) for name in _PARAMS})
        settings = ObserverSettings(**{name: getattr(self, name) for name in SETTINGS})
        # the core raises one message naming every parameter the contract's ranges cannot refuse
        self.core = HalfCarObserver(params, settings, (self.force_front, self.force_rear))
        self.sprung_mass_est = float(self.m_s_nominal)
        self.road_class_est = int(self.road_class)

    def step(self, t: float, h: float) -> None:
        measured = [getattr(self, name) for name in SENSORS[self.sensors]]
        # a non-finite measurement is left out by the core (status 1); the outputs carry the contract's names
        self.__dict__.update(self.core.step(measured, (self.force_front, self.force_rear), self.vehicle_speed, h))
