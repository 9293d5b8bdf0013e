"""Chunked stepping over ``harness.cosim.CoSimulation``, for runs too long to record in memory.

``CoSimulation.run`` builds the input table and the record of the whole run up front (one row
per step). ``Stepper`` initializes the same system the same way and then advances it chunk by
chunk: each ``advance(n)`` returns only that chunk's recorded rows, so memory stays flat over
an hour at 1 kHz. Same Gauss-Seidel order, same wiring and the same refusal handling as
``CoSimulation.run``; the inputs are constants or functions of time (s) sampled at each step
start (no per-step arrays: their length would fix the run's length).

    with Stepper(system, parameters=..., inputs={"vehicle_speed": 11.1}, record=[...]) as sim:
        sim.initialize()
        for _ in range(60):
            rows = sim.advance(1000, 1e-3)    # (1000, len(record)) floats, times in sim.times(rows)
"""
from __future__ import annotations

import numpy as np

from .cosim import CoSimulation, SimulationError, _claim_logger


class Stepper(CoSimulation):
    """A ``CoSimulation`` stepped in chunks: ``initialize()`` once, then ``advance(n, h)``."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.rates:
            raise ValueError("Stepper steps every instance at every step (no rates)")
        for key, value in self.inputs.items():
            if not (callable(value) or np.ndim(value) == 0):
                raise ValueError(f"input {key!r}: Stepper takes constants or functions of time, not arrays")
        self.time = self.start_time  # s, the end of the last completed step
        self.steps_done = 0
        self._order = [self.instances[k] for k in self.system.order]
        self._h: float | None = None  # the step size of every step so far (nan once it changed)

    def _inputs_at(self, t: float) -> list[float]:
        return [float(v(t)) if callable(v) else float(v) for v in self.inputs.values()]

    def _error(self, inst, what: str) -> SimulationError:
        return SimulationError(inst.name, self.time, what, list(inst.messages), None)

    def initialize(self) -> np.ndarray:
        """Instantiate and initialize every FMU in order (parameters, inputs at the start time);
        returns the recorded values after initialization (1-D, in ``record`` order)."""
        _claim_logger()
        buf = self._buf
        for s, v in zip(self._external, self._inputs_at(self.time)):
            buf[s] = v
        for inst in self._order:
            if (what := self._initialize(inst, self.time)) is not None:
                raise self._error(inst, what)
        return np.array([buf[i] for i in self._record_slots], dtype=float)

    def advance(self, n: int, h: float) -> np.ndarray:
        """Step n times by h (s); returns an (n, len(record)) float array of the recorded values
        after each step (Integers and Booleans as floats). Raises ``SimulationError`` on a refusal."""
        if not h > 0:
            raise ValueError(f"step size {h!r} s must be > 0")
        buf, ext, rec, order = self._buf, self._external, self._record_slots, self._order
        timed = any(callable(v) for v in self.inputs.values())
        if not timed:
            for s, v in zip(ext, self._inputs_at(self.time)):
                buf[s] = v
        if self._h is None:
            self._h = h
        elif self._h != h:
            self._h = float("nan")  # steps of different sizes: times accumulate from here on
        rows = np.empty((n, len(rec)))
        for j in range(n):
            t = self.time
            if timed:
                for s, v in zip(ext, self._inputs_at(t)):
                    buf[s] = v
            if (refusal := self._step_instances(order, t, h)) is not None:
                raise self._error(*refusal)
            rows[j] = [buf[i] for i in rec]
            self.steps_done += 1
            # while every step had size h, times are start + k h exactly (no rounding drift over
            # millions of steps), as in CoSimulation.run
            self.time = self.start_time + self.steps_done * h if self._h == h else t + h
        return rows

    def instance(self, name: str):
        """The ``fmpy.fmi2.FMU2Slave`` of an instance (e.g. to get its FMU state)."""
        return self.instances[name].fmu
