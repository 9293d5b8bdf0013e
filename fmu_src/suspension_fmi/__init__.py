"""FMI adapter layer shared by the project's FMUs: the variable contract and the slave base class.

Bundled into every FMU under this unique name; it is the only place that imports pythonfmu.
"""
