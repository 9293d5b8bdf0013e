"""SuspensionEstimator FMU: road profile (robust KF, KF, MME&KF, EKF, UKF), sprung mass (RLS, dual
observer) and ISO class online."""
from __future__ import annotations

import math

from pythonfmu.enums import Fmi2Status

from suspension_estimation.estimators.state_classes import STATE_CLASSES
from suspension_estimation.estimators.suspension import EstimatorConfig, SuspensionEstimator as Core
from suspension_estimation.suspension_fmi.contract import SUSPENSION_ESTIMATOR
from suspension_estimation.suspension_fmi.slave import ContractSlave

# every contract parameter of this FMU configures the core under the same name
# (tests/test_interface.py: the same names and defaults as EstimatorConfig)
_CONFIG = tuple(v.name for v in SUSPENSION_ESTIMATOR if v.causality == "parameter")
# the measurement inputs: no range in the contract, a non-finite sample is skipped by the core
# (vehicle_speed has a range: the slave refuses a non-finite or out-of-range speed at the step)
_MEASURED = ("acc_sprung", "acc_unsprung", "susp_deflection")


class SuspensionEstimator(ContractSlave):
    description = ("Road-profile (robust KF, KF, MME&KF; EKF, UKF on the nonlinear model), sprung-mass "
                   "(forgetting-factor RLS, dual observer) and ISO 8608 class estimation from body and wheel "
                   "accelerations and suspension deflection")
    state_attributes = ("core", "_skipped")
    state_classes = STATE_CLASSES

    def setup(self) -> None:
        # the core validates its configuration and raises one message naming every bad parameter
        self.core = Core(EstimatorConfig(**{name: getattr(self, name) for name in _CONFIG}))
        self.sprung_mass_est = float(self.m_s_nominal)
        self.mass_std = float(self.m_s_nominal)
        # per measurement: non-finite samples skipped since it last was finite (0: it is finite)
        self._skipped = dict.fromkeys(_MEASURED, 0)

    def step(self, t: float, h: float) -> None:
        a_s, a_u, d = self.acc_sprung, self.acc_unsprung, self.susp_deflection
        # the sum of finite samples is finite (but for an overflow, which only costs the check below)
        if not math.isfinite(a_s + a_u + d) or any(self._skipped.values()):
            self._log_non_finite(t)
        # the core leaves a non-finite measurement out of the update (status 1)
        # the outputs are plain attributes of this object (the contract's names)
        self.__dict__.update(self.core.step(a_s, a_u, d, self.vehicle_speed, h))

    def _log_non_finite(self, t: float) -> None:
        """One warning when a measurement turns non-finite, one line when it is finite again."""
        for name, n in self._skipped.items():
            value = getattr(self, name)
            if not math.isfinite(value):
                if n == 0:
                    self.log(f"SuspensionEstimator at t = {t:.6g} s: {name} = {value!r} is not finite; "
                             "its samples are left out of the update until it is finite again",
                             Fmi2Status.warning)
                self._skipped[name] = n + 1
            elif n:
                self.log(f"SuspensionEstimator at t = {t:.6g} s: {name} is finite again after {n} "
                         f"non-finite sample{'s' if n > 1 else ''} left out", Fmi2Status.ok)
                self._skipped[name] = 0
