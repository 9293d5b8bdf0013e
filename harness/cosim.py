"""A fixed-step (or per-step variable) co-simulation master over ``fmpy.fmi2.FMU2Slave``.

The FMUs are stepped Gauss-Seidel in a declared order: before its ``doStep`` every FMU gets
the outputs the FMUs before it computed *in this step*, so a connection that points forward
in the order does not lag a step. Inputs of the system (a speed profile, a payload schedule)
are sampled at the start of each step and held over it.

Times are in s. Recorded variables are named ``"instance.variable"``; the result is a numpy
structured array with a ``time`` column first, row 0 holding the values after initialization.

    system = System(components={"ISORoad": "dist/ISORoad.fmu", "QuarterCar": "dist/QuarterCar.fmu"},
                    connections=[("ISORoad.road_height", "QuarterCar.road_height")])
    with CoSimulation(system, parameters={"ISORoad.road_class": 3},
                      record=["ISORoad.road_height", "QuarterCar.acc_sprung"]) as sim:
        result = sim.run(stop_time=1.0, step_size=1e-3)
"""
from __future__ import annotations

import itertools
import shutil
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from ctypes import byref
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, defaultCallbacks, fmi2Boolean, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE,
                       fmi2Integer, fmi2Real, fmi2True, fmi2ValueReference)
from fmpy.logging import addLoggerProxy

STATUS = ("ok", "warning", "discard", "error", "fatal", "pending")
_TYPES = ("Real", "Integer", "Boolean")  # what can be wired and recorded; String only as a parameter

# An input of the system: a constant, a function of time (s), or one value per step.
InputValue = float | int | bool | Callable[[float], float] | np.ndarray
GAUSS_SEIDEL, JACOBI = "gauss-seidel", "jacobi"  # CoSimulation(coupling=...)


class SimulationError(RuntimeError):
    """An FMU refused (fmi2Discard, fmi2Error or fmi2Fatal, or an error logged while initializing).

    ``instance`` is the FMU instance's name, ``time`` the start of the failed step in s,
    ``messages`` what that instance logged (status, text), and ``result`` the record up to the
    last completed step (a structured array, possibly only the initial row or empty).
    """

    def __init__(self, instance: str, time: float, what: str, messages: list[tuple[str, str]],
                 result: np.ndarray | None = None):
        self.instance, self.time, self.what, self.messages, self.result = instance, time, what, messages, result
        errors = [m for s, m in messages if s in ("error", "fatal", "discard")] or [m for _, m in messages]
        reason = errors[-1] if errors else "no message logged"
        super().__init__(f"{instance} {what} at t = {time:.6g} s: {reason}")


@dataclass
class System:
    """What to simulate: FMU instances and the connections between them.

    ``components`` maps an instance name to its FMU file. ``connections`` are
    ``(start, end)`` pairs of ``"instance.variable"`` names; a start without a dot is an input
    of the system (e.g. ``"vehicle_speed"``) fed by ``CoSimulation(inputs=...)``. ``order`` is
    the stepping order (default: the components in an order that makes every connection point
    forward when the connections allow it, else their declared order).
    """

    components: dict[str, Path]
    connections: list[tuple[str, str]] = field(default_factory=list)
    order: list[str] | None = None
    name: str = "System"

    def __post_init__(self) -> None:
        self.components = {k: Path(v) for k, v in self.components.items()}
        if self.order is None:
            self.order = _forward_order(list(self.components), self.connections)
        if sorted(self.order) != sorted(self.components):
            raise ValueError(f"order {self.order} must list each component once: {list(self.components)}")

    @property
    def inputs(self) -> list[str]:
        """Names of the system's inputs (connection starts without an instance)."""
        return list(dict.fromkeys(s for s, _ in self.connections if "." not in s))


def model_variables(system: System) -> dict[str, dict]:
    """``{instance: {variable name: fmpy ScalarVariable}}`` from the model descriptions."""
    mds: dict[Path, dict] = {}
    out = {}
    for name, fmu in system.components.items():
        if fmu not in mds:
            if not fmu.is_file():
                raise FileNotFoundError(f"{name}: FMU {fmu} does not exist")
            mds[fmu] = {v.name: v for v in read_model_description(str(fmu), validate=False).modelVariables}
        out[name] = mds[fmu]
    return out


def _forward_order(names: list[str], connections: Iterable[tuple[str, str]]) -> list[str]:
    """A topological order of the components (stable), or ``names`` if there is a cycle."""
    deps = {n: set() for n in names}
    for start, end in connections:
        if "." in start:
            src, dst = start.split(".", 1)[0], end.split(".", 1)[0]
            if src in deps and dst in deps and src != dst:
                deps[dst].add(src)
    order: list[str] = []
    while len(order) < len(names):
        ready = [n for n in names if n not in order and deps[n] <= set(order)]
        if not ready:
            return list(names)
        order.append(ready[0])
    return order


def _split(name: str) -> tuple[str, str]:
    if "." not in name:
        raise ValueError(f"{name!r} is not of the form 'instance.variable'")
    inst, var = name.split(".", 1)
    return inst, var


# FMPy's native logger proxy (``addLoggerProxy``) forwards every instance's messages to the
# Python logger registered *last*, process-wide. So all instances share one logger, and each
# instance's callbacks carry its own componentEnvironment, by which the messages are sorted.
_SINKS: dict[int, list[tuple[str, str]]] = {}
_ENVIRONMENTS = itertools.count(1)


def _dispatch(env, instance, status, category, message) -> None:
    sink = _SINKS.get(env or 0)
    if sink is not None:
        label = STATUS[status] if 0 <= status < len(STATUS) else str(status)
        sink.append((label, message.decode("utf-8", errors="replace")))


_LOGGER = fmi2CallbackLoggerTYPE(_dispatch)


def _claim_logger() -> None:
    """Make ``_dispatch`` the process-wide target of FMPy's logger proxy again (other code, e.g.
    ``fmpy.simulate_fmu``, may have registered its own logger since)."""
    cb = fmi2CallbackFunctions()
    cb.logger = _LOGGER
    addLoggerProxy(byref(cb))


class LogSink:
    """FMI callbacks for one FMU instance, with every message it logs kept in ``messages`` as
    (status name, text). Pass ``callbacks`` to ``FMU2Slave.instantiate``; ``close()`` when done."""

    def __init__(self):
        self.messages: list[tuple[str, str]] = []
        self.env = next(_ENVIRONMENTS)
        _SINKS[self.env] = self.messages
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = _LOGGER
        self.callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self.callbacks.freeMemory = defaultCallbacks.freeMemory
        self.callbacks.componentEnvironment = self.env
        addLoggerProxy(byref(self.callbacks))

    def close(self) -> None:
        _SINKS.pop(self.env, None)


class _Instance:
    """One FMU instance with its model description, a logger that keeps its messages, and the
    pre-resolved value references of what the master sets and gets every step."""

    def __init__(self, name: str, fmu: Path, unzipdir: str):
        self.name = name
        self.md = read_model_description(str(fmu), validate=False)
        if self.md.coSimulation is None:
            raise ValueError(f"{name}: {fmu.name} does not support co-simulation")
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=unzipdir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.log = LogSink()
        self.messages, self.callbacks = self.log.messages, self.log.callbacks
        self.instantiated = False
        self.initialized = False
        # Unloading a pythonfmu binary (dlclose) corrupts the heap of the host process, seen as an
        # abort at exit ("corrupted double-linked list") in about one run in four: keep it loaded.
        self.keep_library = (self.md.generationTool or "").startswith("PythonFMU")
        # per type: (value references, buffer indices) set before / got after each step
        self.sets: list[tuple[Callable, list[int], list[int]]] = []
        self.gets: list[tuple[Callable, list[int], list[int]]] = []
        self.do_step = self.fast_do_step()  # (t, h): what the step loop calls

    def var(self, name: str, causalities: Sequence[str] | None = None):
        v = self.vars.get(name)
        if v is None:
            raise KeyError(f"{self.name} has no variable {name!r}")
        if causalities is not None and v.causality not in causalities:
            raise ValueError(f"{self.name}.{name} is a {v.causality}, expected {' or '.join(causalities)}")
        return v

    def set_values(self, values: Mapping[str, object]) -> None:
        """Set variables by name, each with the setter of its type."""
        for name, value in values.items():
            v = self.var(name)
            vr = [v.valueReference]
            if v.type == "Real":
                self.fmu.setReal(vr, [float(value)])
            elif v.type in ("Integer", "Enumeration"):
                if isinstance(value, bool) or int(value) != value:
                    raise ValueError(f"{self.name}.{name} is an Integer, got {value!r}")
                self.fmu.setInteger(vr, [int(value)])
            elif v.type == "Boolean":
                if not isinstance(value, (bool, np.bool_)) and value not in (0, 1):
                    raise ValueError(f"{self.name}.{name} is a Boolean, got {value!r}")
                self.fmu.setBoolean(vr, [bool(value)])
            elif v.type == "String":
                self.fmu.setString(vr, [str(value)])
            else:
                raise ValueError(f"{self.name}.{name}: type {v.type} is not supported")

    def setter(self, vtype: str) -> Callable:
        return {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger, "Boolean": self.fmu.setBoolean}[vtype]

    def getter(self, vtype: str) -> Callable:
        return {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger, "Boolean": self.fmu.getBoolean}[vtype]

    # The step loop's calls. FMPy's setReal/getReal build two ctypes arrays and go through a
    # logging dispatcher on every call; these make the arrays once and call the FMI function
    # directly, with FMPy's status check (FMICallException above fmi2Warning). They fall back to
    # FMPy's methods if its internals are not as expected.
    def _c_function(self, name: str):
        return getattr(self.fmu, "_functions", {}).get(name)

    def fast_setter(self, vtype: str, vrs: Sequence[int]) -> Callable:
        """``f(vrs, values)`` that sets ``values`` to these ``vrs`` (the first argument is ignored)."""
        name = f"fmi2Set{vtype}"
        c_fun = self._c_function(name)
        if c_fun is None:
            return self.setter(vtype)
        n, fmu = len(vrs), self.fmu
        vr = (fmi2ValueReference * n)(*vrs)
        val = ({"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}[vtype] * n)()

        whole = vtype != "Real"  # a system input's table holds floats

        def set_values(_vrs, values) -> None:
            val[:] = [int(v) for v in values] if whole else values
            status = c_fun(fmu.component, vr, n, val)
            if status > 1:
                raise FMICallException(function=name, status=status)
        return set_values

    def fast_getter(self, vtype: str, vrs: Sequence[int]) -> Callable:
        """``f(vrs)`` that returns the values of these ``vrs`` as a list (the argument is ignored)."""
        name = f"fmi2Get{vtype}"
        c_fun = self._c_function(name)
        if c_fun is None:
            return self.getter(vtype)
        n, fmu = len(vrs), self.fmu
        vr = (fmi2ValueReference * n)(*vrs)
        val = ({"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}[vtype] * n)()

        def get_values(_vrs) -> list:
            status = c_fun(fmu.component, vr, n, val)
            if status > 1:
                raise FMICallException(function=name, status=status)
            return val[:]
        return get_values

    def fast_do_step(self) -> Callable[[float, float], None]:
        """``f(t, h)``: ``doStep(t, h)``."""
        c_fun = self._c_function("fmi2DoStep")
        fmu = self.fmu
        if c_fun is None:
            return lambda t, h: fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

        def do_step(t: float, h: float) -> None:
            status = c_fun(fmu.component, t, h, fmi2True)
            if status > 1:
                raise FMICallException(function="fmi2DoStep", status=status)
        return do_step


class CoSimulation:
    """Instantiates the FMUs of a ``System``, initializes them with ``parameters`` and steps them.

    parameters  ``{"instance.variable": value}`` set before initialization, type-aware
                (Real, Integer, Boolean, String from the model description)
    inputs      ``{system input or "instance.variable": value}``; a value is a constant, a
                function of time (s) sampled at each step start, or an array with one value
                per step (length = number of steps)
    record      ``"instance.variable"`` names to record (Real, Integer or Boolean)
    coupling    GAUSS_SEIDEL (default: each FMU, in the system's order, steps on the outputs its
                predecessors wrote this step) or JACOBI (every FMU on the values of the previous
                communication point, as FMPy's SSP runner and libcosim do: every connection lags
                a step)
    rates       ``{instance: n}``: that instance steps every n-th communication step, over the n
                steps at once, on its inputs at their end: an estimator fed by a logger that
                samples the plant's outputs at 1 / (n h), the plant and road stepped at h. Its
                outputs hold in between (score them at its own steps: rows n, 2n, ... of the record).
                Gauss-Seidel only, a constant step size, a run a whole number of n steps; an
                entry with n = 1 changes nothing (its instance need not be in the system).

    Use as a context manager (or call ``close()``): the FMUs are freed and their extracted
    files removed.
    """

    def __init__(self, system: System, parameters: Mapping[str, object] | None = None,
                 inputs: Mapping[str, InputValue] | None = None, record: Sequence[str] = (),
                 start_time: float = 0.0, coupling: str = "gauss-seidel", rates: Mapping[str, int] | None = None):
        self.system = system
        if coupling not in (GAUSS_SEIDEL, JACOBI):
            raise ValueError(f"coupling = {coupling!r} must be {GAUSS_SEIDEL!r} or {JACOBI!r}")
        self.coupling = coupling
        self.rates = {k: v for k, v in (rates or {}).items() if v != 1}
        for name, n in self.rates.items():
            if name not in system.components:
                raise KeyError(f"rates: no instance {name!r} in {system.name}")
            if not (isinstance(n, (int, np.integer)) and n >= 1):
                raise ValueError(f"rates[{name!r}] = {n!r} must be a whole number >= 1")
        if self.rates and coupling != GAUSS_SEIDEL:
            raise ValueError("rates need the Gauss-Seidel coupling")
        self.parameters = dict(parameters or {})
        self.inputs = dict(inputs or {})
        self.record = list(dict.fromkeys(record))
        self.start_time = float(start_time)
        self._tmp = Path(tempfile.mkdtemp(prefix="harness-"))
        self.instances: dict[str, _Instance] = {}
        self._used = False  # a run has begun since construction or the last reset()
        try:
            self._load()
            self._resolve()
        except BaseException:
            self.close()
            raise

    # -- set-up -------------------------------------------------------------------------------
    def _load(self) -> None:
        unzipped: dict[Path, str] = {}  # extract each FMU file once
        for name in self.system.order:
            fmu = self.system.components[name]
            if not fmu.is_file():
                raise FileNotFoundError(f"{name}: FMU {fmu} does not exist")
            key = fmu.resolve()
            if key not in unzipped:
                unzipped[key] = extract(str(fmu), unzipdir=str(self._tmp / f"{len(unzipped)}_{fmu.stem}"))
            self.instances[name] = _Instance(name, fmu, unzipped[key])

    def _check_parameters(self) -> None:
        for key in self.parameters:
            inst, var = _split(key)
            if inst not in self.instances:
                raise KeyError(f"parameter {key!r}: no instance {inst!r} in {self.system.name}")
            self.instances[inst].var(var)

    def _resolve(self) -> None:
        """Check every name and pre-resolve the value references of the step loop.

        All exchanged values live in one flat list ``self._buf``: first the system inputs and
        per-instance inputs from ``inputs``, then every output some connection or the record
        reads (one slot per ``instance.variable``).
        """
        self._check_parameters()
        for inst in self.instances.values():
            inst.sets, inst.gets = [], []

        slots: dict[str, int] = {}

        def slot(name: str) -> int:
            return slots.setdefault(name, len(slots))

        # external inputs: system inputs (no dot) and direct inputs ("instance.variable")
        feeds: dict[str, list[str]] = {}  # "instance.variable" input -> source slot name
        for start, end in self.system.connections:
            e_inst, e_var = _split(end)
            if e_inst not in self.instances:
                raise KeyError(f"connection {start} -> {end}: no instance {e_inst!r}")
            self.instances[e_inst].var(e_var, ("input",))
            if "." in start:
                s_inst, s_var = _split(start)
                if s_inst not in self.instances:
                    raise KeyError(f"connection {start} -> {end}: no instance {s_inst!r}")
                self.instances[s_inst].var(s_var, ("output", "calculatedParameter", "local", "parameter"))
            feeds.setdefault(end, []).append(start)
        for end, starts in feeds.items():
            if len(starts) > 1:
                raise ValueError(f"{end} is fed by more than one connection: {starts}")
        for key in self.inputs:
            if "." in key:
                inst, var = _split(key)
                if inst not in self.instances:
                    raise KeyError(f"input {key!r}: no instance {inst!r}")
                self.instances[inst].var(var, ("input",))
                if key in feeds:
                    raise ValueError(f"input {key!r} is already fed by the connection from {feeds[key][0]}")
                feeds[key] = [key]
            elif key not in self.system.inputs:
                raise KeyError(f"input {key!r}: {self.system.name} has no such input (inputs: {self.system.inputs})")
        self._external = [slot(k) for k in self.inputs]  # slots 0..len(inputs)-1, in dict order
        self._external_names = list(self.inputs)
        # unfed system inputs are left at the FMUs' start values
        feeds = {end: starts for end, starts in feeds.items() if "." in starts[0] or starts[0] in self.inputs}

        # what each instance reads after its step: outputs feeding a connection, and recorded ones
        wanted: dict[str, list[str]] = {n: [] for n in self.instances}
        for starts in feeds.values():
            if "." in starts[0] and starts[0] not in self.inputs:
                inst, var = _split(starts[0])
                wanted[inst].append(var)
        for key in self.record:
            inst, var = _split(key)
            if inst not in self.instances:
                raise KeyError(f"record {key!r}: no instance {inst!r}")
            v = self.instances[inst].var(var)
            if v.type not in _TYPES:
                raise ValueError(f"record {key!r}: a {v.type} cannot be recorded")
            wanted[inst].append(var)

        for name, inst in self.instances.items():
            for vtype in _TYPES:
                ins = [(end.split(".", 1)[1], starts[0]) for end, starts in feeds.items()
                       if end.split(".", 1)[0] == name and inst.vars[end.split(".", 1)[1]].type == vtype]
                if ins:
                    vrs = [inst.vars[v].valueReference for v, _ in ins]
                    inst.sets.append((inst.fast_setter(vtype, vrs), vrs, [slot(s) for _, s in ins]))
                outs = list(dict.fromkeys(v for v in wanted[name] if inst.vars[v].type == vtype))
                if outs:
                    vrs = [inst.vars[v].valueReference for v in outs]
                    inst.gets.append((inst.fast_getter(vtype, vrs), vrs, [slot(f"{name}.{v}") for v in outs]))
        self._buf: list = [0.0] * len(slots)
        self._record_slots = [slots[k] for k in self.record]
        self._record_types = [self.instances[_split(k)[0]].vars[_split(k)[1]].type for k in self.record]

    # -- run ------------------------------------------------------------------------------------
    def _input_table(self, times: np.ndarray) -> np.ndarray:
        """Values of the external inputs at each step start, shape (steps, inputs)."""
        n = len(times) - 1
        table = np.empty((n, len(self.inputs)))
        for j, (key, value) in enumerate(self.inputs.items()):
            if callable(value):
                try:  # vectorized if it can be
                    col = np.broadcast_to(np.asarray(value(times[:-1]), dtype=float), (n,))
                except (TypeError, ValueError):
                    col = np.array([value(t) for t in times[:-1]], dtype=float)
            elif np.ndim(value) == 0:
                col = np.full(n, float(value))
            else:
                col = np.asarray(value, dtype=float)
                if col.shape != (n,):
                    raise ValueError(f"input {key!r}: {col.shape[0]} values for {n} steps")
            table[:, j] = col
        return table

    def _fail(self, inst: _Instance, time: float, what: str, rows: np.ndarray, k: int,
              times: np.ndarray) -> SimulationError:
        return SimulationError(inst.name, time, what, list(inst.messages), self._result(rows[:k], times[:k]))

    def _result(self, rows: np.ndarray, times: np.ndarray) -> np.ndarray:
        dtype = [("time", np.float64)] + [
            (k, {"Real": np.float64, "Integer": np.int64, "Boolean": np.bool_}[t])
            for k, t in zip(self.record, self._record_types)]
        out = np.empty(len(times), dtype=dtype)
        out["time"] = times
        for j, k in enumerate(self.record):
            out[k] = rows[:, j]
        return out

    def _step_instances(self, order: list[_Instance], t: float, h: float,
                        spans: Sequence[tuple[float, float]] | None = None) -> tuple[_Instance, str] | None:
        """One Gauss-Seidel step from t (s) by h (s): each instance in order reads its inputs from
        the wiring buffer, steps, and writes its outputs there. ``spans``: per instance, its own
        step (start s, size s), ending at t + h (``rates``). Returns (instance, why) if one
        refused the step, else None."""
        buf = self._buf
        if self.coupling == JACOBI:
            return self._step_jacobi(order, t, h)
        for j, inst in enumerate(order):
            for setter, vrs, idx in inst.sets:
                setter(vrs, [buf[i] for i in idx])
            try:
                if spans is None:
                    inst.do_step(t, h)
                else:
                    inst.do_step(*spans[j])
            except FMICallException as e:
                return inst, f"refused the step ({STATUS[e.status]})"
            for getter, vrs, idx in inst.gets:
                for i, v in zip(idx, getter(vrs)):
                    buf[i] = v
        return None

    def _step_jacobi(self, order: list[_Instance], t: float, h: float) -> tuple[_Instance, str] | None:
        """One Jacobi step: every instance reads its inputs, then every instance steps, then every
        instance writes its outputs."""
        buf = self._buf
        for inst in order:
            for setter, vrs, idx in inst.sets:
                setter(vrs, [buf[i] for i in idx])
        for inst in order:
            try:
                inst.do_step(t, h)
            except FMICallException as e:
                return inst, f"refused the step ({STATUS[e.status]})"
        for inst in order:
            for getter, vrs, idx in inst.gets:
                for i, v in zip(idx, getter(vrs)):
                    buf[i] = v
        return None

    def _initialize(self, inst: _Instance, t0: float) -> str | None:
        """Instantiate (once) and initialize one instance at t0 (s): parameters, then its inputs
        from the wiring buffer; its outputs go into the buffer. Returns why it failed, or None."""
        buf = self._buf
        try:
            if not inst.instantiated:
                inst.fmu.instantiate(loggingOn=True, callbacks=inst.callbacks)
                inst.instantiated = True
            inst.fmu.setupExperiment(startTime=t0)
            inst.fmu.enterInitializationMode()
            prefix = inst.name + "."
            inst.set_values({k[len(prefix):]: v for k, v in self.parameters.items() if k.startswith(prefix)})
            for setter, vrs, idx in inst.sets:
                setter(vrs, [buf[i] for i in idx])
            inst.fmu.exitInitializationMode()
            inst.initialized = True
            for getter, vrs, idx in inst.gets:
                for i, v in zip(idx, getter(vrs)):
                    buf[i] = v
        except FMICallException as e:
            return f"failed to initialize ({STATUS[e.status]} from {e.function})"
        if any(s in ("error", "fatal") for s, _ in inst.messages):
            return "refused to initialize"
        return None

    def run(self, stop_time: float | None = None, step_size: float | Sequence[float] = 1e-3,
            progress: Callable[[int], None] | None = None) -> np.ndarray:
        """Initialize and step to ``stop_time`` (s) with ``step_size`` (s).

        ``step_size`` is a constant, or a sequence with the size of every step (then
        ``stop_time`` may be omitted). ``progress(n)`` is called with the number of steps done
        since its last call, about every 1 % of the run. Returns the record; on a refusal
        raises ``SimulationError`` carrying the record so far. A second ``run()`` begins with
        ``reset()``.
        """
        t0 = self.start_time
        if np.ndim(step_size) == 0:
            h = float(step_size)
            if not h > 0:
                raise ValueError(f"step size {h!r} s must be > 0")
            if stop_time is None or not stop_time > t0:
                raise ValueError(f"stop time {stop_time!r} s must be after the start time {t0} s")
            n = int(round((stop_time - t0) / h))
            if n < 1 or abs(t0 + n * h - stop_time) > 1e-9 * max(1.0, abs(stop_time)):
                raise ValueError(f"stop time {stop_time} s is not a whole number of {h} s steps from {t0} s")
            times = t0 + h * np.arange(n + 1)
            steps = np.full(n, h)
        else:
            steps = np.asarray(step_size, dtype=float)
            if steps.ndim != 1 or len(steps) == 0 or not np.all(steps > 0):
                raise ValueError("step sizes must be a non-empty sequence of values > 0")
            times = np.concatenate([[t0], t0 + np.cumsum(steps)])
            n = len(steps)
            if stop_time is not None and abs(times[-1] - stop_time) > 1e-9 * max(1.0, abs(stop_time)):
                raise ValueError(f"step sizes add up to {times[-1] - t0} s, not to stop time {stop_time} s")
            if self.rates:
                raise ValueError("rates need a constant step size")
        for name, r in self.rates.items():
            if n % r:
                raise ValueError(f"{n} steps are not a whole number of the {r} steps of {name!r} (rates)")
        table = self._input_table(times)
        rows = np.zeros((n + 1, len(self.record)))
        buf = self._buf
        ext = self._external
        rec = self._record_slots
        order = [self.instances[k] for k in self.system.order]
        rated = [(inst, self.rates.get(inst.name, 1)) for inst in order] if self.rates else None

        if self._used:
            self.reset()
        self._used = True
        _claim_logger()
        # initialization: each instance in order, with its parameters and the inputs at t0
        first = table[0] if n else []
        for j, s in enumerate(ext):
            buf[s] = first[j]
        for inst in order:
            if (what := self._initialize(inst, t0)) is not None:
                raise self._fail(inst, t0, what, rows, 0, times)
        rows[0] = [buf[i] for i in rec]

        # the step loop: Gauss-Seidel in the declared order
        every = max(1, n // 100)
        done = 0
        k = 0
        try:
            for k in range(n):
                t = times[k]
                h = steps[k]
                vals = table[k]
                for j, s in enumerate(ext):
                    buf[s] = vals[j]
                if rated is None:
                    refusal = self._step_instances(order, t, h)
                else:  # those whose step ends here, each from its own step's start
                    due = [(inst, r) for inst, r in rated if (k + 1) % r == 0]
                    refusal = self._step_instances([i for i, _ in due], t, h,
                                                   [(times[k + 1 - r], r * h) for _, r in due])
                if refusal is not None:
                    raise self._fail(refusal[0], t, refusal[1], rows, k + 1, times)
                rows[k + 1] = [buf[i] for i in rec]
                if progress is not None and (k + 1) % every == 0:
                    progress(k + 1 - done)
                    done = k + 1
        finally:
            if progress is not None and k + 1 > done:
                progress(k + 1 - done)
        return self._result(rows, times)

    def reset(self, parameters: Mapping[str, object] | None = None,
              inputs: Mapping[str, InputValue] | None = None) -> None:
        """Make the next ``run()`` start afresh on the same instances (FMPy's parameter-variation
        pattern: extract and instantiate once, reset between runs).

        Every instantiated FMU gets ``fmi2Reset`` (back to its state after instantiation, its
        variables at their start values; pythonfmu re-runs the slave's ``__init__``) and its log
        is cleared. ``parameters`` and ``inputs``, when given, replace those of the constructor
        (same meaning; ``record`` stays). An instance that refuses the reset is freed and
        instantiated again by the next run.
        """
        if parameters is not None:
            self.parameters = dict(parameters)
        if inputs is not None:
            inputs = dict(inputs)
            same = list(inputs) == list(self.inputs)
            self.inputs = inputs
            if not same:  # other external inputs: resolve the wiring again
                self._resolve()
        self._check_parameters()
        for inst in self.instances.values():
            if inst.instantiated:
                try:
                    inst.fmu.reset()
                except FMICallException:  # e.g. after fmi2Fatal: start over with a new instance
                    try:
                        inst.fmu.fmi2FreeInstance(inst.fmu.component)
                    except Exception:  # noqa: BLE001 - a new instance is made either way
                        pass
                    inst.instantiated = False
            inst.initialized = False
            inst.messages.clear()
        self._used = False

    # -- tear-down ------------------------------------------------------------------------------
    def close(self) -> None:
        """Terminate and free every instance, remove the extracted FMUs. The binaries of
        pythonfmu FMUs stay loaded until the process ends (see ``_Instance.keep_library``)."""
        for inst in self.instances.values():
            if inst.initialized:
                try:
                    inst.fmu.terminate()
                except FMICallException:
                    pass
            try:
                if inst.instantiated:
                    inst.fmu.fmi2FreeInstance(inst.fmu.component)
                if not inst.keep_library:
                    inst.fmu.freeLibrary()
            except Exception:  # noqa: BLE001 - freeing must not mask the real error
                pass
            inst.log.close()
        self.instances = {}
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> CoSimulation:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_csv(path: Path | str, result: np.ndarray) -> Path:
    """Write a record as CSV: a header of quoted names (FMPy's convention), then one row per time.

    Reals are written with 17 significant digits, so reading back gives the same numbers.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = result.dtype.names
    fmts = ["%d" if np.issubdtype(result.dtype[n], np.integer) or result.dtype[n] == np.bool_ else "%.17g"
            for n in names]
    table = np.column_stack([result[n].astype(np.int64) if f == "%d" else result[n] for n, f in zip(names, fmts)]) \
        if len(result) else np.empty((0, len(names)))
    header = ",".join(f'"{n}"' for n in names)
    with open(path, "w", newline="") as f:
        f.write(header + "\n")
        if len(result):
            np.savetxt(f, table, fmt=fmts, delimiter=",")
    return path


def read_csv(path: Path | str) -> np.ndarray:
    """Read a CSV written by ``write_csv`` (or FMPy) into a structured array of float64 columns.

    Raises ``ValueError`` for a file with a header and no rows (what a run refused at
    initialization used to leave): there is no result in it to read.
    """
    path = Path(path)
    with open(path) as f:
        names = [n.strip().strip('"') for n in f.readline().rstrip("\n").split(",")]
        if not any(line.strip() for line in f):
            raise ValueError(f"{path} holds no result rows (only a header): the run that wrote it failed "
                             "before its first step, e.g. an FMU refused to initialize; see that run's error")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.shape[0] == 0:
        raise ValueError(f"{path} holds a header and no rows (a run refused at initialization)")
    out = np.empty(data.shape[0], dtype=[(n, np.float64) for n in names])
    for j, n in enumerate(names):
        out[n] = data[:, j]
    return out
