"""SuspensionController FMU: the half car's active suspension (passive, skyhook, paper 002's LQR)."""
from __future__ import annotations

from suspension_estimation.controllers.controller import SuspensionController as Core
from suspension_estimation.controllers.lqr import STATES
from suspension_estimation.plant.half_car import HalfCarParams, HALF_CAR_RANGES
from suspension_estimation.suspension_fmi.contract import CONTRACTS, problem
from suspension_estimation.suspension_fmi.slave import ContractSlave

_ROAD_CLASS = next(v for v in CONTRACTS["SuspensionController"] if v.name == "road_class")


class SuspensionController(ContractSlave):
    description = ("Active suspension of the half car: actuator forces from its relative states, passive, skyhook "
                   "or paper 002's LQR with scheduled weights, saturated at the actuator's limit")
    # memoryless: the core is rebuilt from the parameters (its gain cache with it)
    state_attributes = ("core",)
    derived_attributes = ("core",)

    def setup(self) -> None:
        car = HalfCarParams(m_s=self.sprung_mass, **{name: getattr(self, name) for name in HALF_CAR_RANGES
                                                    if name != "m_s"})
        self.core = Core(car, self.mode, self.force_limit, self.c_sky, (self.q1, self.q2, self.q3))
        # refuse, with the reason, a configuration whose closed loop is not stable
        self.core.check(self.vehicle_speed, self.road_class, self.sprung_mass)
        self.step(0.0, 0.0)

    def input_problems(self) -> list[str]:
        out = super().input_problems()  # the Real inputs; the Integer class here
        if (msg := problem(_ROAD_CLASS, self.road_class)) is not None:
            out.append(msg)
        return out

    def step(self, t: float, h: float) -> None:
        c = self.core.command([getattr(self, name) for name in STATES], self.vehicle_speed, self.road_class,
                              self.sprung_mass)
        self.force_front_demand, self.force_rear_demand = c.demand
        self.force_front, self.force_rear = c.force
        self.saturated = int(c.saturated)
        self.q1_used, self.q2_used, self.q3_used = c.weights
