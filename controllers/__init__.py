"""Active-suspension control laws of the half car (paper 002): the LQR of its eqs. 10-14 on the
relative states, its weight schedule from the NSGA-II of eq. 17, and the passive and skyhook
baselines. Plain Python, no FMI: ``fmu_src/SuspensionController.py`` wraps ``controller``."""
