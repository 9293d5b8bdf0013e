"""Plain-Python physics of the project: vehicle parameters, the ISO 8608 road and the quarter car.

Nothing here imports an FMI library; the FMUs in ``fmu_src/`` are thin adapters over it.
"""
