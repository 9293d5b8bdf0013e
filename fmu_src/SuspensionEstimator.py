"""SuspensionEstimator FMU: road profile (robust KF, KF, MME&KF, EKF, UKF), sprung mass (RLS, dual
observer) and ISO class online."""
from __future__ import annotations

from suspension_estimation.estimators.suspension import EstimatorConfig, SuspensionEstimator as Core
from suspension_estimation.suspension_fmi.contract import SUSPENSION_ESTIMATOR
from suspension_estimation.suspension_fmi.slave import ContractSlave

# every contract parameter of this FMU configures the core under the same name
# (tests/test_interface.py: the same names and defaults as EstimatorConfig)
_CONFIG = tuple(v.name for v in SUSPENSION_ESTIMATOR if v.causality == "parameter")


class SuspensionEstimator(ContractSlave):
    description = ("Road-profile (robust KF, KF, MME&KF; EKF, UKF on the nonlinear model), sprung-mass "
                   "(forgetting-factor RLS, dual observer) and ISO 8608 class estimation from body and wheel "
                   "accelerations and suspension deflection")
    state_attributes = ("core",)

    def setup(self) -> None:
        # the core validates its configuration and raises one message naming every bad parameter
        self.core = Core(EstimatorConfig(**{name: getattr(self, name) for name in _CONFIG}))
        self.sprung_mass_est = float(self.m_s_nominal)
        self.mass_std = float(self.m_s_nominal)

    def step(self, t: float, h: float) -> None:
        # the measurements have no range in the contract: the core rejects non-finite ones (status 1)
        # the outputs are plain attributes of this object (the contract's names)
        self.__dict__.update(self.core.step(self.acc_sprung, self.acc_unsprung, self.susp_deflection,
                                            self.vehicle_speed, h))
