"""Random sequences of FMI calls through FMPy against the built FMUs (tests/test_fmi_fuzz.py runs
a short version, benchmarks/fmi_fuzz.py a long one).

A sequence is drawn by hypothesis: gets and sets of any value reference (the FMU's own of every
type, unknown ones) with any value (NaN, +-inf, 1e9, 1e300, strings with format characters),
doStep with any step (<= 0, NaN, inf, 1e9, tiny), get/set/serialize/deserialize of states
(saved ones and garbage), initialization calls out of order, terminate and reset. What must hold
(``check``): no call returns fmi2Fatal and the host lives on, every call refused with fmi2Discard
or fmi2Error logs its reason, every get or set of a value reference the FMU does not have as that
type logs an error, and after reset and a valid initialization the instance gives, bit for bit,
the outputs of a fresh instance.
"""
from __future__ import annotations

import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from hypothesis import strategies as st

from suspension_estimation.harness.cosim import STATUS, LogSink

FATAL = STATUS.index("fatal")
UNKNOWN_VR = 2 ** 31 - 1
REALS = st.one_of(st.sampled_from([math.nan, math.inf, -math.inf, 1e9, -1e9, 1e300, 0.0, -0.0, 5e-324]),
                  st.floats(-1e3, 1e3), st.floats(allow_nan=False, allow_infinity=False))
INTEGERS = st.one_of(st.sampled_from([0, 1, 2, 5, -1, 2 ** 31 - 1, -2 ** 31]), st.integers(-2 ** 31, 2 ** 31 - 1))
STRINGS = st.one_of(st.sampled_from(["", "%s%n%d", "../../etc/passwd", "nonexistent.csv", "\u00e9\u6f22"]),
                    st.text(max_size=40).filter(lambda s: "\x00" not in s))
STEPS = st.one_of(st.sampled_from([1e-3, 1e-3, 1e-3, 2e-3, 0.0, -1e-3, math.nan, math.inf, 1e9, 1e-12, 0.5]),
                  st.floats(1e-6, 0.02))
# valid inputs for the end check and the reference run, per FMU
VALID = {"ISORoad": {"vehicle_speed": 11.0}, "QuarterCar": {"road_height": 0.002, "sprung_mass": 410.0},
         "HalfCar": {"road_height_front": 0.002, "road_height_rear": -0.001, "sprung_mass": 672.0,
                     "force_front": 50.0, "force_rear": -20.0},
         "SuspensionEstimator": {"acc_sprung": 0.3, "acc_unsprung": -2.0, "susp_deflection": 0.001,
                                 "vehicle_speed": 11.0},
         "SuspensionController": {"heave_velocity": 0.05, "pitch_rate": 0.01, "v_u_front": 0.1,
                                  "susp_deflection_front": 0.002, "tire_deflection_front": 0.0005,
                                  "vehicle_speed": 20.0, "sprung_mass": 672.0},
         "HalfCarEstimator": {"acc_body_front": 0.3, "acc_body_rear": -0.2, "acc_unsprung_front": 2.0,
                              "acc_unsprung_rear": -1.5, "susp_deflection_front": 0.001,
                              "susp_deflection_rear": -0.001, "vehicle_speed": 20.0}}


class Unpacked:
    """An FMU extracted once; ``vrs[type]``: its value references of each type."""

    def __init__(self, fmu: Path):
        self.md = read_model_description(str(fmu))
        self.dir = extract(str(fmu), unzipdir=tempfile.mkdtemp())
        self.name = self.md.coSimulation.modelIdentifier
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.vrs = {t: sorted(v.valueReference for v in self.md.modelVariables if v.type == t)
                    for t in ("Real", "Integer", "Boolean", "String")}
        self.outputs = [v.valueReference for v in self.md.modelVariables
                        if v.causality == "output" and v.type == "Real"]
        self.reference = None

    def __repr__(self) -> str:
        return f"<{self.name}.fmu>"

    def new(self, name: str = "fuzz") -> tuple[FMU2Slave, LogSink]:
        fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir, modelIdentifier=self.name, instanceName=name)
        sink = LogSink()
        fmu.instantiate(loggingOn=True, callbacks=sink.callbacks)
        return fmu, sink

    def valid_run(self, fmu: FMU2Slave) -> np.ndarray:
        """Initialize at the start values and run 20 steps of 1 ms on valid inputs: the outputs."""
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        out = []
        for k in range(20):
            for name, value in VALID[self.name].items():
                fmu.setReal([self.vars[name].valueReference], [value])
            fmu.doStep(currentCommunicationPoint=k * 1e-3, communicationStepSize=1e-3)
            out.append(fmu.getReal(self.outputs))
        return np.array(out)

    def fresh(self) -> np.ndarray:
        if self.reference is None:
            fmu, sink = self.new("fresh")
            try:
                self.reference = self.valid_run(fmu)
            finally:
                fmu.terminate()
                fmu.freeInstance()
                sink.close()
        return self.reference

    def close(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)


def calls(u: Unpacked) -> st.SearchStrategy:
    """One FMI call: a tuple (name, arguments...)."""
    def vr(kind: str):
        own = u.vrs[kind]
        other = [v for k, vs in u.vrs.items() if k != kind for v in vs]
        return st.one_of(st.sampled_from(own) if own else st.just(UNKNOWN_VR),
                         st.sampled_from(other + [UNKNOWN_VR, 10 ** 6]))
    values = {"Real": REALS, "Integer": INTEGERS, "Boolean": st.booleans(), "String": STRINGS}
    sets = [st.tuples(st.just("set" + k), st.lists(vr(k), min_size=1, max_size=3), values[k]) for k in values]
    gets = [st.tuples(st.just("get" + k), st.lists(vr(k), min_size=1, max_size=3)) for k in values]
    return st.one_of(
        *sets, *gets,
        st.tuples(st.just("doStep"), STEPS), st.tuples(st.just("doStep"), STEPS), st.tuples(st.just("doStep"), STEPS),
        st.tuples(st.just("getState")), st.tuples(st.just("setState"), st.integers(0, 7)),
        st.tuples(st.just("roundTrip"), st.integers(0, 7)),
        st.tuples(st.just("setBytes"), st.sampled_from([b"", b"{", b"[]", b"null", b'{"model": 1}', b"\xff\xfe",
                                                      b'{"invalid": "x"}', b"1e999"])),
        st.tuples(st.just("setupExperiment")), st.tuples(st.just("enterInitializationMode")),
        st.tuples(st.just("exitInitializationMode")), st.tuples(st.just("terminate")), st.tuples(st.just("reset")))


def check(u: Unpacked, initialized: bool, sequence: list[tuple]) -> dict[str, int]:
    """Run ``sequence`` on a new instance (initialized first if ``initialized``), then reset and
    compare a valid run with a fresh instance's. Asserts what the module doc says; returns counts
    of calls by outcome."""
    fmu, sink = u.new()
    states: list = []
    counts = {"calls": 0, "refused": 0, "errors logged": 0}
    t = 0.0
    try:
        if initialized:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
        for call in sequence:
            name, args = call[0], call[1:]
            before = len(sink.messages)
            must_log = False
            try:
                if name.startswith(("set", "get")) and name[3:] in u.vrs:
                    kind, vrs = name[3:], args[0]
                    must_log = any(v not in u.vrs[kind] for v in vrs)
                    method = getattr(fmu, name)
                    method(vrs, [args[1]] * len(vrs)) if name.startswith("set") else method(vrs)
                elif name == "doStep":
                    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=args[0])
                    t += args[0] if math.isfinite(args[0]) and args[0] > 0 else 0.0
                elif name == "getState":
                    states.append(fmu.getFMUstate())
                elif name == "setState" and states:
                    fmu.setFMUstate(states[args[0] % len(states)])
                elif name == "roundTrip" and states:
                    blob = fmu.serializeFMUstate(states[args[0] % len(states)])
                    fmu.setFMUstate(fmu.deSerializeFMUstate(blob))
                elif name == "setBytes":
                    fmu.setFMUstate(fmu.deSerializeFMUstate(args[0]))
                    must_log = True
                elif name == "setupExperiment":
                    fmu.setupExperiment(startTime=t)
                elif name in ("enterInitializationMode", "exitInitializationMode", "terminate", "reset"):
                    getattr(fmu, name)()
                    if name == "reset":
                        t = 0.0  # the states taken before stay valid (FMI 2.0: until freed)
            except FMICallException as e:
                assert e.status != FATAL, (call, sink.messages[before:])
                counts["refused"] += 1
                must_log = True
            new = [m for s, m in sink.messages[before:] if s in ("warning", "discard", "error", "fatal")]
            assert not [m for s, m in sink.messages[before:] if s == "fatal"], (call, new)
            if must_log:
                assert new, (call, "refused without a logged reason")
                counts["errors logged"] += 1
            counts["calls"] += 1
        fmu.reset()
        assert np.array_equal(u.valid_run(fmu), u.fresh()), sequence
    finally:
        try:
            fmu.terminate()
        except FMICallException:
            pass
        fmu.freeInstance()
        sink.close()
    return counts


def sequences(u: Unpacked) -> st.SearchStrategy:
    return st.tuples(st.booleans(), st.lists(calls(u), min_size=1, max_size=40))
