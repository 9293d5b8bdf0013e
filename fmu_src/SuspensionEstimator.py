"""SuspensionEstimator FMU: road profile (robust KF, KF or MME&KF), sprung mass (RLS) and ISO class online."""
from __future__ import annotations

from suspension_estimation.estimators.suspension import EstimatorConfig, SuspensionEstimator as Core
from suspension_estimation.suspension_fmi.slave import ContractSlave

# contract parameters that configure the core under the same name
_CONFIG = ("m_s_nominal", "m_u", "k_s", "k_t", "c_s", "road_estimator", "mass_estimator", "mass_feedback",
           "forgetting_factor", "road_class", "acc_sprung_noise_std", "acc_unsprung_noise_std", "defl_noise_std",
           "acc_sampling", "iri_segment", "imm_mass_min", "imm_mass_max", "imm_models", "imm_stay")


class SuspensionEstimator(ContractSlave):
    description = ("Road-profile (robust KF, KF, MME&KF), sprung-mass (forgetting-factor RLS) and ISO 8608 class "
                   "estimation from body and wheel accelerations and suspension deflection")
    state_attributes = ("core",)

    def setup(self) -> None:
        # the core validates its configuration and raises one message naming every bad parameter
        self.core = Core(EstimatorConfig(**{name: getattr(self, name) for name in _CONFIG}))
        self.sprung_mass_est = float(self.m_s_nominal)

    def step(self, t: float, h: float) -> None:
        # the measurements have no range in the contract: the core rejects non-finite ones (status 1)
        # the outputs are plain attributes of this object (the contract's names)
        self.__dict__.update(self.core.step(self.acc_sprung, self.acc_unsprung, self.susp_deflection,
                                            self.vehicle_speed, h))
