"""Plain-Python estimator cores of the SuspensionEstimator FMU (no FMI import).

- ``model``: 6-state augmented quarter car + ISO 8608 road shaping filter, exact discretisation
- ``kalman``: Kalman filter (filterpy-identical) and MME&KF
- ``mass``: forgetting-factor RLS sprung-mass estimation on a mass-independent regressor
- ``road_class``: online ISO 8608 class from the PSD of the estimated road
- ``response_class``: ISO 8608 class from the measured response (streaming linear SVM, plain-data model)
- ``road_profile``: the road estimate freed of the filter's common-mode reference (road_height_est)
- ``steady_state``: the filter's steady-state error on an ISO road, in the frequency domain, and its
  low-frequency lag behind the common-mode reference (``reference_lag``)
- ``suspension``: ``SuspensionEstimator``, the object the FMU adapter drives
"""
from .suspension import OUTPUTS, EstimatorConfig, SuspensionEstimator, validate

__all__ = ["OUTPUTS", "EstimatorConfig", "SuspensionEstimator", "validate"]
