"""libcosim (the Open Simulation Platform's co-simulation engine, through ``libcosimpy``) as a
second master for the tests: an SSP file or single FMUs, stepped at a fixed step, with the
values of named variables recorded after every step."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from libcosimpy.CosimEnums import CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

NS = 1_000_000_000  # libcosim counts time in integer nanoseconds
# Executions are never freed: freeing one unloads the pythonfmu binaries, whose unload destructor
# releases the interpreter a second time (PythonFMU #229); the tests leave with os._exit.
_KEEP: list[CosimExecution] = []

log_output_level(CosimLogLevel.WARNING)


class Libcosim:
    """One libcosim execution: ``Libcosim.from_ssp(path)`` or ``Libcosim.from_fmus({name: fmu}, h)``.

    ``set_initial("Instance.variable", value)`` before the first step, ``set_input`` between
    steps; ``run(n, names)`` steps n times and returns an (n, len(names)) array of the values
    after each step."""

    def __init__(self, execution: CosimExecution):
        _KEEP.append(execution)
        self.execution = execution
        self.index = {i.name.decode(): i.index for i in execution.slave_infos()}
        self.variables = {name: {v.name.decode(): v for v in execution.slave_variables(i)}
                          for name, i in self.index.items()}
        self.observer = CosimObserver.create_last_value()
        execution.add_observer(self.observer)
        self.override = CosimManipulator.create_override()
        execution.add_manipulator(self.override)

    @classmethod
    def from_ssp(cls, ssp: Path, step: float | None = None) -> Libcosim:
        """The system of an .ssp, at its default experiment's step unless ``step`` (s) is given."""
        ns = None if step is None else round(step * NS)
        return cls(CosimExecution.from_ssp_file(str(Path(ssp).resolve()), ns))

    @classmethod
    def from_fmus(cls, fmus: dict[str, Path], step: float) -> Libcosim:
        execution = CosimExecution.from_step_size(round(step * NS))
        for name, fmu in fmus.items():
            execution.add_local_slave(CosimLocalSlave(str(Path(fmu).resolve()), name))
        return cls(execution)

    def _ref(self, name: str):
        inst, var = name.split(".", 1)
        return self.index[inst], self.variables[inst][var]

    def set_initial(self, name: str, value: float) -> None:
        i, v = self._ref(name)
        if v.type == CosimVariableType.REAL.value:
            self.execution.real_initial_value(i, v.reference, float(value))
        else:
            self.execution.integer_initial_value(i, v.reference, int(value))

    def set_input(self, name: str, value: float) -> None:
        """Override a Real input from the next step on (libcosim's override manipulator)."""
        i, v = self._ref(name)
        self.override.slave_real_values(i, [v.reference], [float(value)])

    def run(self, n: int, names: list[str], inputs: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """n steps; ``inputs`` gives Real inputs one value per step (set before it)."""
        refs = [self._ref(n) for n in names]
        rows = np.empty((n, len(names)))
        for k in range(n):
            for name, values in (inputs or {}).items():
                self.set_input(name, values[k])
            if not self.execution.step(1):
                raise RuntimeError(f"libcosim step {k} failed: {self.execution.status()}")
            for j, (i, v) in enumerate(refs):
                get = (self.observer.last_real_values if v.type == CosimVariableType.REAL.value
                       else self.observer.last_integer_values)
                rows[k, j] = get(i, [v.reference])[0]
        return rows

    @property
    def time(self) -> float:
        """Simulated time in s."""
        return self.execution.status().current_time / NS
