"""Ecos (``ecospy``, a C++ co-simulation engine from NTNU's Ecos project) as a third master for the
tests: an SSP file or single FMUs, stepped at a fixed step, with the values of named variables
recorded after every step. The same interface as libcosim_driver.Libcosim; names are
"Instance.variable" here as there (Ecos writes "instance::variable"). Ecos needs Debian's
libtbb12, which tools/setup.sh installs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from ecospy import EcosSimulation, EcosSimulationStructure

# Simulations are never freed, as libcosim's executions are not (libcosim_driver): freeing one
# unloads the pythonfmu binaries, whose unload releases the interpreter a second time
_KEEP: list = []


def _ecos(name: str) -> str:
    inst, var = name.split(".", 1)
    return f"{inst}::{var}"


class Ecos:
    """One Ecos simulation: ``Ecos.from_ssp(path, h)`` or ``Ecos.from_fmus({name: fmu}, h)``.

    ``set_initial("Instance.variable", value)`` before the first step, ``set_input`` between
    steps; ``run(n, names)`` steps n times and returns an (n, len(names)) array of the values
    after each step."""

    def __init__(self, simulation: EcosSimulation, keep=()):
        _KEEP.append((simulation, *keep))
        self.simulation = simulation
        self.initial: dict[str, float] = {}
        self.started = False

    @classmethod
    def from_ssp(cls, ssp: Path, step: float) -> Ecos:
        return cls(EcosSimulation(step_size=step, ssp_path=str(Path(ssp).resolve())))

    @classmethod
    def from_fmus(cls, fmus: dict[str, Path], step: float) -> Ecos:
        structure = EcosSimulationStructure()
        for name, fmu in fmus.items():
            structure.add_model(name, str(Path(fmu).resolve()))
        return cls(EcosSimulation(step_size=step, structure=structure), (structure,))

    def set_initial(self, name: str, value: float) -> None:
        self.initial[name] = value

    def _start(self) -> None:
        if not self.started:
            for name, value in self.initial.items():
                self.set_input(name, value)
            self.simulation.init()
            self.started = True

    def set_input(self, name: str, value: float) -> None:
        self.simulation.set_real(_ecos(name), float(value))

    def run(self, n: int, names: list[str], inputs: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """n steps; ``inputs`` gives Real inputs one value per step (set before it)."""
        self._start()
        getters = [self._getter(_ecos(name)) for name in names]
        rows = np.empty((n, len(names)))
        for k in range(n):
            for name, values in (inputs or {}).items():
                self.set_input(name, values[k])
            self.simulation.step(1)
            rows[k] = [get() for get in getters]
        return rows

    def _getter(self, ident: str):
        """The getter of the variable's type: Ecos has one per FMI type and refuses the others."""
        sim = self.simulation
        for get in (sim.get_real, sim.get_integer, sim.get_bool):
            try:
                get(ident)
            except Exception:
                continue
            return lambda get=get: float(get(ident))
        raise KeyError(f"Ecos knows no variable {ident}")

    @property
    def time(self) -> float:
        """Simulated time in s."""
        return self.simulation.get_time()
