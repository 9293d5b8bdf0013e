"""FMI adapter layer shared by the project's FMUs: the variable contract and the slave base class.

Bundled into every FMU inside the FMU's private package (build.py); it is the only place that
imports pythonfmu.
"""
