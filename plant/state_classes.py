"""Every class whose objects the plant FMUs' cores hold: the only classes a saved QuarterCar,
HalfCar or ISORoad FMU state may name (fmu_src/suspension_fmi/state.py). The road itself is not saved: it
is a function of ISORoad's parameters, rebuilt on restore."""
from __future__ import annotations

from .half_car import HalfCar, HalfCarParams
from .iri import IRIMeter
from .nonlinear_car import NonlinearQuarterCar
from .quarter_car import QuarterCar, SensorNoise
from .sensors import DelayLine, SensorErrors
from .suspension_forces import AirSpring, BumpStops, PiecewiseDamper
from .vehicle import Vehicle

QUARTER_CAR_STATE: tuple[type, ...] = (QuarterCar, NonlinearQuarterCar, Vehicle, SensorNoise, SensorErrors,
                                       DelayLine, AirSpring, PiecewiseDamper, BumpStops)
HALF_CAR_STATE: tuple[type, ...] = (HalfCar, HalfCarParams, SensorNoise)
ISO_ROAD_STATE: tuple[type, ...] = (IRIMeter,)
