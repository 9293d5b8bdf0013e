"""HalfCar FMU: the linear half car (pitch plane, paper 002) with seeded sensor noise."""
from __future__ import annotations

from suspension_estimation.plant.half_car import HalfCar as Plant, HalfCarParams
from suspension_estimation.plant.quarter_car import SensorNoise
from suspension_estimation.plant.state_classes import HALF_CAR_STATE
from suspension_estimation.suspension_fmi.slave import ContractSlave

_PARAMS = ("pitch_inertia", "l_f", "l_r", "m_uf", "m_ur", "k_f", "k_r", "c_f", "c_r", "k_tf", "k_tr")


class HalfCar(ContractSlave):
    description = ("Half-car plant (pitch plane): body heave and pitch on front and rear suspensions and tyres, "
                   "with actuator forces, measured with noise")
    state_attributes = ("plant",)
    state_classes = HALF_CAR_STATE

    def setup(self) -> None:
        params = HalfCarParams(m_s=self.sprung_mass, **{name: getattr(self, name) for name in _PARAMS})
        noise = SensorNoise(self.acc_sprung_noise_std, self.acc_unsprung_noise_std, self.defl_noise_std)
        self.plant = Plant(params, noise, self.noise_seed)
        # start at rest on the road it stands on, not with a step from zero at the first step
        self.plant.settle(self.road_height_front, self.road_height_rear, self.force_front, self.force_rear)
        self._output()

    def _output(self) -> None:
        p = self.plant
        (self.acc_body_front, self.acc_body_rear, self.acc_unsprung_front, self.acc_unsprung_rear,
         self.susp_deflection_front, self.susp_deflection_rear) = p.measured
        (self.acc_body_front_true, self.acc_body_rear_true,
         self.acc_unsprung_front_true, self.acc_unsprung_rear_true) = p.acc_true
        self.susp_deflection_front_true, self.susp_deflection_rear_true = p.deflection_true
        self.tire_deflection_front_true, self.tire_deflection_rear_true = p.tire_deflection_true
        (self.heave, self.pitch, self.z_u_front, self.z_u_rear,
         self.heave_velocity, self.pitch_rate, self.v_u_front, self.v_u_rear) = p.x.tolist()
        self.tire_force_front, self.tire_force_rear = p.tire_force
        self.tire_contact_front, self.tire_contact_rear = p.tire_contact

    def step(self, t: float, h: float) -> None:
        self.plant.step(self.road_height_front, self.road_height_rear, h, self.sprung_mass,
                        self.force_front, self.force_rear)
        self._output()
