"""A minimal single-FMU driver for tests: parameters by name, inputs per step, logged messages."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from suspension_estimation.harness.cosim import STATUS, LogSink


class Driven:
    """One instance of an FMU, with every logged message kept in ``messages``."""

    def __init__(self, fmu: Path, parameters: dict | None = None, name: str = "inst"):
        self.md = read_model_description(str(fmu))
        self.dir = extract(str(fmu), unzipdir=tempfile.mkdtemp())
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.log = LogSink()  # the harness's per-instance sink: FMPy's logger proxy is process-wide
        self.fmu.instantiate(loggingOn=True, callbacks=self.log.callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for k, v in (parameters or {}).items():
            self.set(k, v)
        self.fmu.exitInitializationMode()
        self.t = 0.0

    @property
    def messages(self) -> list[tuple[int, str]]:
        """(fmi2Status number, text) of every message this instance logged."""
        return [(STATUS.index(label), text) for label, text in self.log.messages]

    def set(self, name: str, value) -> None:
        var = self.vars[name]
        vr = [var.valueReference]
        {"Real": lambda: self.fmu.setReal(vr, [float(value)]),
         "Integer": lambda: self.fmu.setInteger(vr, [int(value)]),
         "Boolean": lambda: self.fmu.setBoolean(vr, [bool(value)]),
         "String": lambda: self.fmu.setString(vr, [str(value)])}[var.type]()

    def get(self, name: str):
        var = self.vars[name]
        vr = [var.valueReference]
        return {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger,
                "Boolean": self.fmu.getBoolean, "String": self.fmu.getString}[var.type](vr)[0]

    def step(self, h: float, **inputs) -> None:
        for k, v in inputs.items():
            self.set(k, v)
        self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def run(self, h: float, n: int, outputs: list[str], **inputs) -> np.ndarray:
        """n steps of h with fixed inputs; returns an (n, len(outputs)) array of the outputs after each step."""
        refs = [self.vars[o].valueReference for o in outputs]
        out = np.empty((n, len(outputs)))
        for k, v in inputs.items():
            self.set(k, v)
        for i in range(n):
            self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
            self.t += h
            out[i] = self.fmu.getReal(refs)
        return out

    def close(self) -> None:
        try:
            self.fmu.terminate()
        except FMICallException:
            pass
        self.fmu.freeInstance()
        self.log.close()
        shutil.rmtree(self.dir, ignore_errors=True)
