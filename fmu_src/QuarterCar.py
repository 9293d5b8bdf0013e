"""QuarterCar FMU: the linear or the nonlinear quarter-car plant with seeded sensor noise."""
from __future__ import annotations

from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
from suspension_estimation.plant.quarter_car import ROAD_INPUTS, QuarterCar as Plant, SensorNoise
from suspension_estimation.plant.sensors import SensorErrors
from suspension_estimation.plant.state_classes import QUARTER_CAR_STATE
from suspension_estimation.plant.suspension_forces import AirSpring, BumpStops, PiecewiseDamper, in_contact
from suspension_estimation.plant.vehicle import Vehicle
from suspension_estimation.suspension_fmi.slave import ContractSlave


class QuarterCar(ContractSlave):
    description = "Quarter-car plant: sprung and unsprung mass on a suspension and a tyre, measured with noise"
    state_attributes = ("plant",)
    state_classes = QUARTER_CAR_STATE

    def _args(self, cls) -> dict:
        """The contract parameters named like the fields of the force law ``cls``."""
        return {name: getattr(self, name) for name in cls.__dataclass_fields__}

    def setup(self) -> None:
        vehicle = Vehicle(m_s=self.sprung_mass, m_u=self.m_u, k_s=self.k_s, k_t=self.k_t, c_s=self.c_s)
        noise = SensorNoise(self.acc_sprung_noise_std, self.acc_unsprung_noise_std, self.defl_noise_std)
        errors = SensorErrors.of(self)
        road_input = ROAD_INPUTS[self.road_input]
        if self.spring_model == 0 and self.damper_model == 0:
            self.plant = Plant(vehicle, noise, self.noise_seed, self.acc_sampling, errors, road_input)
        else:
            spring = AirSpring(**self._args(AirSpring)) if self.spring_model == 1 else None
            damper = PiecewiseDamper(**self._args(PiecewiseDamper)) if self.damper_model == 1 else None
            self.plant = NonlinearQuarterCar(vehicle, spring, damper, BumpStops(**self._args(BumpStops)),
                                             noise, self.noise_seed, self.acc_sampling, errors, road_input)
        # start at rest on the road it stands on, not with a step from zero at the first step
        self.plant.settle(self.road_height)
        self._output()

    def _output(self) -> None:
        p = self.plant
        self.z_s, self.v_s, self.z_u, self.v_u = p.x.tolist()
        self.acc_sprung, self.acc_unsprung, self.susp_deflection = p.measured
        self.acc_sprung_true, self.acc_unsprung_true = p.acc_true
        self.tire_deflection = p.tire_deflection
        self.tire_force = p.tire_force
        if isinstance(p, NonlinearQuarterCar):
            self.tire_contact, self.bump_stop = p.tire_contact, p.bump_stop
        else:
            self.tire_contact = in_contact(p.tire_force, self.sprung_mass, self.m_u)

    def step(self, t: float, h: float) -> None:
        self.plant.step(self.road_height, h, self.sprung_mass)
        self._output()
