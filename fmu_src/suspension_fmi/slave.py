"""Base class of the project's FMUs: registers the contract, declares units, refuses bad input.

pythonfmu turns an exception into fmi2Fatal and cannot return fmi2Error, so nothing here
raises to the host: a bad parameter is logged (error status, naming the variable and its
allowed range) when initialization ends, and every ``doStep`` afterwards returns fmi2Discard
with the reason logged again; a bad input is refused the same way at the step. A call that
pythonfmu can only answer with fmi2OK is refused by an error message and has no effect: a get
or set of an unknown value reference or of the wrong type (a get returns NaN, 0, False or ""),
a state that fails its checks (state.py), a state that cannot be saved.
"""
from __future__ import annotations

import datetime
import math
import os
import sys
import uuid
from xml.etree.ElementTree import Element, SubElement, tostring

from pythonfmu import Boolean, DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from . import quick_exit, state as fmu_state
from .contract import CONTRACTS, DEPENDENCIES, MAX_STEP, UNITS, Var, problem

quick_exit.install()  # opt-in (SUSPENSION_FMU_QUICK_EXIT=1): see quick_exit.py

_TYPES = {"Real": Real, "Integer": Integer, "Boolean": Boolean, "String": String}
_ZERO = {"Real": 0.0, "Integer": 0, "Boolean": False, "String": ""}
_REFUSED = {"Real": math.nan, "Integer": 0, "Boolean": False, "String": ""}  # what a refused get returns
_PLAIN = {"Real": (int, float), "Integer": (int,), "Boolean": (bool,), "String": (str,)}


class ContractSlave(Fmi2Slave):
    """Registers the variables of ``CONTRACTS[model identifier]`` as attributes of the same name.

    Subclasses implement ``setup()`` (build the core from the parameters; raise ValueError with
    a message naming the variable for a problem the contract's ranges cannot express) and
    ``step(t, h)`` (advance the core, write the outputs).
    """

    author = "suspension-estimation FMU project"
    license = "MIT"
    # the step the FMUs are made for and tested at (s); any other step works
    default_experiment = DefaultExperiment(start_time=0.0, step_size=1e-3)
    # attributes beyond the contract's variables that make up the FMU state (the cores), and the
    # only classes a saved state may hold objects of (state.py)
    state_attributes: tuple[str, ...] = ()
    state_classes: tuple[type, ...] = ()
    # state attributes that setup() rebuilds from the parameters alone (nothing of a run in
    # them): not saved, rebuilt on restore
    derived_attributes: tuple[str, ...] = ()

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.contract: tuple[Var, ...] = CONTRACTS[type(self).__name__]
        # why doStep refuses (None: it steps): until initialization ends, then refused
        # parameters or a failed core
        self._refusal: str | None = "it is not initialized: fmi2ExitInitializationMode first"
        # the longest step, finite so that one comparison also refuses an infinite step
        self._max_step = min(MAX_STEP[type(self).__name__], sys.float_info.max)
        self._checked_inputs: list[Var] = []
        # value reference -> attribute name, per type: the fast accessors below
        self._names: dict[str, dict[int, str]] = {t: {} for t in _TYPES}
        for var in self.contract:
            setattr(self, var.name, _ZERO[var.type] if var.start is None else var.start)
            if var.causality == "parameter":
                variability = Fmi2Variability.fixed
            elif var.type == "Real":
                variability = Fmi2Variability.continuous
            else:
                variability = Fmi2Variability.discrete
            self.register_variable(_TYPES[var.type](
                var.name, causality=getattr(Fmi2Causality, var.causality), variability=variability,
                description=var.description, start=var.start))
            self._names[var.type][len(self.vars) - 1] = var.name
            if var.causality == "input" and var.type == "Real" and var.allowed is not None:
                self._checked_inputs.append(var)
        self._input_bounds = [(v, *((float(v.allowed[0]), float(v.allowed[1]))
                                    if isinstance(v.allowed, tuple) else (math.inf, -math.inf)))
                              for v in self._checked_inputs]

    # -- hooks for subclasses ---------------------------------------------------------------
    def setup(self) -> None:
        """Build the core from the parameters."""

    def step(self, t: float, h: float) -> None:
        """Advance the core by h seconds and write the outputs."""
        raise NotImplementedError

    def input_problems(self) -> list[str]:
        """Messages for inputs outside their ranges (non-finite included)."""
        out = []
        for var, lo, hi in self._input_bounds:
            value = getattr(self, var.name)
            # strictly inside the range is allowed whatever its ends (NaN is not): the full
            # check only for the rest
            if not lo < value < hi and (msg := problem(var, value)) is not None:
                out.append(msg)
        return out

    # -- FMI --------------------------------------------------------------------------------
    # pythonfmu's accessors look up each variable object, check its type and call its getter
    # lambda; these read the attribute directly. An unknown value reference or one of another
    # type is refused with a logged error (pythonfmu would raise: fmi2Fatal).
    def _get(self, kind: str, cast, vrs: list[int]) -> list:
        names = self._names[kind]
        try:
            return [cast(getattr(self, names[vr])) for vr in vrs]
        except KeyError:
            bad = [vr for vr in vrs if vr not in names]
            self.log(f"get{kind}: value reference(s) {bad} are not {kind} variables of {type(self).__name__}",
                     Fmi2Status.error)
            return [cast(getattr(self, names[vr])) if vr in names else _REFUSED[kind] for vr in vrs]

    def _set(self, kind: str, vrs: list[int], values: list) -> None:
        names = self._names[kind]
        bad = [vr for vr in vrs if vr not in names]
        if bad:
            self.log(f"set{kind}: value reference(s) {bad} are not {kind} variables of {type(self).__name__};"
                     " nothing set", Fmi2Status.error)
            return
        for vr, value in zip(vrs, values):
            setattr(self, names[vr], value)

    def get_real(self, vrs):
        return self._get("Real", float, vrs)

    def get_integer(self, vrs):
        return self._get("Integer", int, vrs)

    def get_boolean(self, vrs):
        return self._get("Boolean", bool, vrs)

    def get_string(self, vrs):
        return self._get("String", str, vrs)

    def set_real(self, vrs, values):
        self._set("Real", vrs, values)

    def set_integer(self, vrs, values):
        self._set("Integer", vrs, values)

    def set_boolean(self, vrs, values):
        self._set("Boolean", vrs, values)

    def set_string(self, vrs, values):
        self._set("String", vrs, values)

    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category: str | None = None, debug=None):
        # FMI 2.0 loggers take the message as a printf format: a literal % must be doubled
        super().log(msg.replace("%", "%%"), status, category)

    def exit_initialization_mode(self):
        self._refusal = None
        problems = [msg for var in self.contract if var.causality == "parameter"
                    and (msg := problem(var, getattr(self, var.name))) is not None]
        problems += self.input_problems()
        if not problems:
            try:
                self.setup()
            except Exception as e:  # noqa: BLE001 - reported to the host, never raised into it
                problems.append(str(e) or type(e).__name__)
        if problems:
            self._refusal = "; ".join(problems)
            self.log(f"{type(self).__name__} refuses its parameters: {self._refusal}", Fmi2Status.error)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._refusal is not None:
            self.log(f"{type(self).__name__} cannot step: {self._refusal}", Fmi2Status.error)
            return False
        if not 0 < step_size <= self._max_step:
            longest = MAX_STEP[type(self).__name__]
            bound = f"{longest:g}]" if math.isfinite(longest) else "inf)"
            self.log(f"communication step size = {step_size!r} s is outside the allowed range (0, {bound} s",
                     Fmi2Status.error)
            return False
        problems = self.input_problems()
        if problems:
            self.log(f"{type(self).__name__} at t = {current_time:.6g} s refuses its inputs: "
                     + "; ".join(problems), Fmi2Status.error)
            return False
        try:
            self.step(current_time, step_size)
        except Exception as e:  # noqa: BLE001
            # the core may have moved part way: no step more from it (never silent garbage)
            self._refusal = (f"its core failed at t = {current_time:.6g} s ({e}); reset the instance or set a "
                             "saved state")
            self.log(f"{type(self).__name__} at t = {current_time:.6g} s: {e}", Fmi2Status.error)
            return False
        return True

    # -- FMU state -------------------------------------------------------------------------
    # A state is plain data (state.py), also in memory: fmi2GetFMUstate and fmi2SetFMUstate go
    # through the same writing and checks as a serialized state, so every round trip tests them.
    def _get_fmu_state(self) -> dict:
        """Every variable and the whole core (filter x and P, RLS matrices, road position, plant
        states, noise generator) as plain data; ``{"invalid": reason}`` if it cannot be written."""
        try:
            steps = self._refusal is None  # an instance that does not step saves no core
            core = {n: getattr(self, n) if steps else None
                    for n in self.state_attributes if n not in self.derived_attributes}
            return fmu_state.encode({v.name: getattr(self, v.name) for v in self.contract}, self._refusal, core,
                                    type(self).__name__, fmu_state.table(self.state_classes))
        except Exception as e:  # noqa: BLE001 - never raised into the host
            self.log(f"{type(self).__name__}: the FMU state cannot be saved: {e}", Fmi2Status.error)
            return {"invalid": f"saved by a {type(self).__name__} that could not write its state: {e}"}

    def _set_fmu_state(self, state: dict) -> None:
        try:
            restore = self._checked_state(state)
        except Exception as e:  # noqa: BLE001 - StateError names the field; anything else is a bad state too
            self.log(f"{type(self).__name__} refuses the FMU state, nothing restored: {e}", Fmi2Status.error)
            return
        self.__dict__.update(restore)

    @staticmethod
    def _fmu_state_to_bytes(state: dict) -> bytes:
        return fmu_state.to_bytes(state)

    @staticmethod
    def _fmu_state_from_bytes(data: bytes) -> dict:
        return fmu_state.from_bytes(data)

    def _checked_state(self, state: dict) -> dict:
        """The attributes to assign for ``state``, every field checked first; raises StateError."""
        Err = fmu_state.StateError
        if not isinstance(state, dict):
            raise Err(f"not a state: {type(state).__name__}")
        if "invalid" in state:
            raise Err(str(state["invalid"]))
        want = {"format", "version", "model", "variables", "refusal", "core"}
        if set(state) != want:
            raise Err(f"fields {sorted(set(state) ^ want)} are wrong (expected {sorted(want)})")
        if state["format"] != fmu_state.FORMAT:
            raise Err(f"format = {state['format']!r} is not {fmu_state.FORMAT!r}")
        if state["version"] != fmu_state.VERSION:
            raise Err(f"version = {state['version']!r}: this FMU reads version {fmu_state.VERSION}")
        if state["model"] != type(self).__name__:
            raise Err(f"model = {state['model']!r}: a state of another FMU cannot be set on {type(self).__name__}")
        refusal = state["refusal"]
        if refusal is not None and not isinstance(refusal, str):
            raise Err("refusal: not a string")
        values, nodes = state["variables"], state["core"]
        if not isinstance(values, dict) or set(values) != {v.name for v in self.contract}:
            extra = sorted(set(values) - {v.name for v in self.contract}) if isinstance(values, dict) else []
            missing = sorted({v.name for v in self.contract} - set(values)) if isinstance(values, dict) else []
            raise Err(f"variables: missing {missing}, unknown {extra}")
        out = {"_refusal": refusal}
        for var in self.contract:
            value = fmu_state.decode_value(values[var.name], var.name)
            if not isinstance(value, _PLAIN[var.type]) or isinstance(value, bool) != (var.type == "Boolean"):
                raise Err(f"variables.{var.name}: {type(value).__name__} where a {var.type} is expected")
            if var.type == "Integer" and not -2 ** 31 <= value < 2 ** 31:
                raise Err(f"variables.{var.name} = {value} is not a 32-bit integer")
            if var.causality == "parameter" and refusal is None and (msg := problem(var, value)) is not None:
                raise Err(f"variables.{msg}")
            out[var.name] = float(value) if var.type == "Real" else value
        saved = [n for n in self.state_attributes if n not in self.derived_attributes]
        if not isinstance(nodes, dict) or set(nodes) != set(saved):
            raise Err(f"core: holds {sorted(nodes) if isinstance(nodes, dict) else nodes!r}, not {sorted(saved)}")
        if refusal is not None:  # an instance that does not step: its core, if any, is not restored
            out.update({n: None for n in self.state_attributes})
            return out
        core = fmu_state.decode(nodes, fmu_state.table(self.state_classes))
        if (missing := sorted(n for n, v in core.items() if v is None)):
            raise Err(f"core: {missing} missing in the state of an instance that steps")
        ref = self._template(out)
        for name in saved:
            fmu_state.check_against(core[name], ref[name], f"core.{name}")
        core.update({n: ref[n] for n in self.derived_attributes})
        out.update(core)
        return out

    def _template(self, values: dict) -> dict:
        """The state attributes ``setup()`` builds from the parameters in ``values`` (on a
        stand-in, this instance untouched): what a restored core is checked against."""
        shadow = object.__new__(type(self))
        shadow.__dict__.update(self.__dict__)
        shadow.__dict__.update(values)
        shadow.log = lambda *a, **k: None
        try:
            type(self).setup(shadow)
        except Exception as e:  # noqa: BLE001
            raise fmu_state.StateError(f"its parameters build no core: {e}") from None
        return {n: getattr(shadow, n, None) for n in self.state_attributes}

    # -- model description ------------------------------------------------------------------
    def to_xml(self, model_options=dict()) -> Element:
        """pythonfmu's description plus units, UnitDefinitions, min/max from the contract's ranges,
        the outputs' dependencies, InitialUnknowns, the project version, a content GUID and the
        generation date (``SOURCE_DATE_EPOCH`` if set, else now)."""
        root = super().to_xml(model_options)
        by_name = {v.name: v for v in self.contract}
        svs = list(root.find("ModelVariables"))
        index = {sv.get("name"): str(i) for i, sv in enumerate(svs, start=1)}
        used = []
        for sv in svs:
            var = by_name[sv.get("name")]
            typed = sv.find(var.type)
            if var.unit is not None:
                typed.set("unit", var.unit)
                used.append(var.unit)
            if var.causality in ("parameter", "input") and (bounds := _min_max(var)) is not None:
                typed.set("min", bounds[0])
                typed.set("max", bounds[1])
        units = Element("UnitDefinitions")
        for name in dict.fromkeys(used):
            SubElement(SubElement(units, "Unit", name=name), "BaseUnit",
                       {k: str(e) for k, e in UNITS[name].items()})
        root.insert(list(root).index(root.find("CoSimulation")) + 1, units)
        structure = root.find("ModelStructure")
        outputs = structure.find("Outputs")
        if outputs is not None:
            depends = DEPENDENCIES[type(self).__name__]
            for unknown in outputs:
                inputs = depends.get(svs[int(unknown.get("index")) - 1].get("name"), ())
                unknown.set("dependencies", " ".join(index[n] for n in inputs))
                unknown.set("dependenciesKind", " ".join("dependent" for _ in inputs))
            initial = SubElement(structure, "InitialUnknowns")
            for unknown in outputs:
                SubElement(initial, "Unknown", index=unknown.get("index"))
        if (version := _project_version()) is not None:
            root.set("version", version)
        # The GUID follows the content (the date excluded), so an unchanged model rebuilds with the same GUID.
        root.set("guid", "")
        root.set("generationDateAndTime", "")
        content = tostring(root)
        root.set("guid", "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, content.decode())) + "}")
        root.set("generationDateAndTime", _generation_date())
        return root


def _min_max(var: Var) -> tuple[str, str] | None:
    """FMI ``min``/``max`` of a variable's allowed range (FMI bounds are inclusive: an open end of
    the range is declared at its limit and still refused by the FMU), or None."""
    a = var.allowed
    if isinstance(a, dict):
        low, high = min(a), max(a)
    elif isinstance(a, tuple):
        low, high = a[:2]
    else:
        return None
    if var.type == "Integer":
        return str(int(low)), str(int(high))
    return repr(float(low)), repr(float(high))


def _project_version() -> str | None:
    """The version of the installed project (pyproject.toml), None when it is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("suspension-estimation-fmu")
    except PackageNotFoundError:
        return None


def _generation_date() -> str:
    """``generationDateAndTime``: ``SOURCE_DATE_EPOCH`` (s, for reproducible builds) if set, else now (UTC)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    t = (datetime.datetime.fromtimestamp(int(epoch), datetime.timezone.utc) if epoch
         else datetime.datetime.now(datetime.timezone.utc))
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")
