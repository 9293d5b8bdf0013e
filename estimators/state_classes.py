"""Every class whose objects the estimator core holds: the only classes a saved
SuspensionEstimator FMU state may name (fmu_src/suspension_fmi/state.py). A class a core starts
to hold is added here; saving a state that holds another fails and says which."""
from __future__ import annotations

from ..plant.iri import IRIMeter
from ..plant.profile_band import DistanceHighpass
from ..plant.sensors import DelayLine, SensorErrors
from ..plant.suspension_forces import AirSpring, BumpStops, PiecewiseDamper
from ..plant.vehicle import Vehicle
from .anchored_road import AnchoredRoad, Blend
from .airspring_observers import (EKF, UKF, DualObserver, DualObserverFilter, FilterpyUKF, NonlinearModel,
                                  NonlinearRoadFilter, UKFRoadFilter, _FilterpyEKF)
from .bias_step import BiasStep
from .imm import IMM, MassIMM, MovingMassIMM
from .imm_filter import IMMRoad, MovingIMMRoad
from .kf_road import KFRoad
from .kalman import MMEKF, LinearKF
from .mass import ForgettingRLS, MassEstimator, StateVariableFilter
from .model import DiscreteModel, ModelNoise, RoadModel
from .response_class import ResponseClassifier
from .road_class import RoadClassifier
from .road_profile import Profiler, Unreference
from .sensor_check import InnovationCheck
from .standstill_bias import StandstillBias
from .suspension import EstimatorConfig, SuspensionEstimator
from .tuning import Tuning
from .vb_akf import VBAKF, VBRoadFilter

STATE_CLASSES: tuple[type, ...] = (
    SuspensionEstimator, EstimatorConfig, Tuning, KFRoad, AnchoredRoad, Blend, BiasStep, LinearKF, MMEKF, DiscreteModel,
    ModelNoise, RoadModel, MassEstimator, ForgettingRLS, StateVariableFilter, RoadClassifier, ResponseClassifier,
    IMM, MassIMM, MovingMassIMM, IMMRoad, MovingIMMRoad, VBAKF, VBRoadFilter, NonlinearModel, EKF, UKF,
    FilterpyUKF, _FilterpyEKF, DualObserver, NonlinearRoadFilter, UKFRoadFilter, DualObserverFilter,
    Vehicle, IRIMeter, AirSpring, PiecewiseDamper, BumpStops, SensorErrors, DelayLine,
    DistanceHighpass, StandstillBias, Unreference, Profiler, InnovationCheck)
