"""An FMU state as plain data: what ``fmi2SerializeFMUstate`` writes and ``fmi2DeSerializeFMUstate``
reads, and the checks a state passes before ``fmi2SetFMUstate`` assigns anything.

A state is a JSON object::

    {"format": "suspension-fmu-state", "version": 1, "model": "<FMU>",
     "variables": {<every contract variable>: value},
     "refusal": null | "<why the parameters were refused>",
     "core": {<state attribute>: node}}

Values are JSON numbers, strings, booleans and null, and tagged nodes:
``{"float": "nan" | "inf" | "-inf"}``, ``{"f8" | "i8" | "b1": value}`` (numpy scalars),
``{"nd": "<f8" | "<i8" | "|b1", "shape": [...], "data": base64 of the little-endian bytes}``,
``{"list" | "tuple": [...]}``, ``{"deque": [...], "maxlen": n | null}``, ``{"dict": [[key, value], ...]}``,
``{"obj": NAME, "fields": {...}}`` and ``{"cls": NAME}`` with NAME the name of one of the FMU's
``state_classes`` (a closed table of this project's classes, declared by each FMU: nothing else
can be named), ``{"rng": "PCG64",
"state": {...}}`` (numpy's generator), and ``{"ref": n}`` for the n-th container or object met
before (shared references and identity survive a round trip, so a restored run replays bit for bit).

Decoding runs no code of the classes it rebuilds: an object is made with ``object.__new__`` and
its fields set from decoded data, nothing is imported, called or evaluated by name. Every node
is checked (tag, type, shape against its data's length, depth at most ``MAX_DEPTH``) and the
decoded core against a core built from the state's own parameters (``check_against``: the same
class, the same fields, arrays of the same dtype and shape, finite where that core's are) before
the FMU assigns anything; a failure raises ``StateError`` naming the field.
"""
from __future__ import annotations

import base64
import binascii
import collections
import inspect
import json
import math
from typing import Any

import numpy as np


FORMAT = "suspension-fmu-state"
VERSION = 1
MAX_DEPTH = 48  # nesting of nodes; the estimator's deepest is 9
MAX_BYTES = 1 << 30  # a serialized state larger than this is refused unread

_DTYPES = {"<f8": np.dtype("<f8"), "<i8": np.dtype("<i8"), "|b1": np.dtype("|b1")}
_SCALARS = {"f8": (np.float64, float), "i8": (np.int64, int), "b1": (np.bool_, bool)}
_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


class StateError(ValueError):
    """A state that cannot be restored; the message names the field and the reason."""


# --- writing ------------------------------------------------------------------------------------
def _float(x: float) -> Any:
    return x if math.isfinite(x) else {"float": "nan" if x != x else ("inf" if x > 0 else "-inf")}


def table(classes: tuple[type, ...]) -> dict[str, type]:
    """{name: class} of an FMU's ``state_classes``; the names must be unique."""
    out = {c.__name__: c for c in classes}
    if len(out) != len(classes):
        raise ValueError("state classes with the same name")
    return out


class _Encoder:
    def __init__(self, classes: dict[str, type]):
        self.names = {c: n for n, c in classes.items()}
        self.seen: dict[int, int] = {}
        self.keep: list = []  # keeps every object met alive, so that no id() is reused meanwhile

    def node(self, x: Any, path: str) -> Any:
        if x is None or isinstance(x, (bool, str)):
            return x
        t = type(x)
        if t is int:
            return x
        if t is float:
            return _float(x)
        if t in (np.float64, np.int64, np.bool_):
            tag = {np.float64: "f8", np.int64: "i8", np.bool_: "b1"}[t]
            v = _SCALARS[tag][1](x)
            return {tag: _float(v) if tag == "f8" else v}
        if isinstance(x, type):
            if x not in self.names:
                raise StateError(f"{path}: class {x.__qualname__} is not a state class")
            return {"cls": self.names[x]}
        if id(x) in self.seen:
            return {"ref": self.seen[id(x)]}
        self.seen[id(x)] = len(self.seen)
        self.keep.append(x)
        if t is np.ndarray:
            a = np.ascontiguousarray(x)
            dt = a.dtype.newbyteorder("<") if a.dtype.kind in "fi" else a.dtype
            if dt.str not in _DTYPES:
                raise StateError(f"{path}: array of dtype {a.dtype} cannot be saved")
            return {"nd": dt.str, "shape": list(a.shape),
                    "data": base64.b64encode(a.astype(dt, copy=False).tobytes()).decode("ascii")}
        if t in (list, tuple):
            return {t.__name__: [self.node(v, f"{path}[{i}]") for i, v in enumerate(x)]}
        if t is collections.deque:
            return {"deque": [self.node(v, f"{path}[{i}]") for i, v in enumerate(x)], "maxlen": x.maxlen}
        if t is dict:
            return {"dict": [[self.node(k, f"{path} key"), self.node(v, f"{path}[{k!r}]")] for k, v in x.items()]}
        if t is np.random.Generator:
            bg = x.bit_generator
            if type(bg) is not np.random.PCG64:
                raise StateError(f"{path}: random generator {type(bg).__name__} cannot be saved")
            return {"rng": "PCG64", "state": bg.state}
        if t in self.names and not hasattr(t, "__slots__"):
            return {"obj": self.names[t], "fields": {k: self.node(v, f"{path}.{k}") for k, v in vars(x).items()}}
        raise StateError(f"{path}: {t.__module__}.{t.__qualname__} is not a state class")


def encode(variables: dict[str, Any], refusal: str | None, core: dict[str, Any], model: str,
           classes: dict[str, type]) -> dict:
    """The state of FMU ``model`` as plain data (see the module doc). Raises StateError for a
    value it cannot write (an object of a class not in ``classes``)."""
    enc = _Encoder(classes)
    return {"format": FORMAT, "version": VERSION, "model": model,
            "variables": {k: enc.node(v, k) for k, v in variables.items()},
            "refusal": refusal, "core": {k: enc.node(v, k) for k, v in core.items()}}


def to_bytes(state: dict) -> bytes:
    return json.dumps(state, allow_nan=False, separators=(",", ":")).encode("utf-8")


def from_bytes(data: bytes) -> dict:
    """The JSON object of a serialized state, or ``{"invalid": reason}`` (deserialization cannot
    refuse in pythonfmu: an exception there is fmi2Fatal; the reason is logged when the state is set)."""
    if len(data) > MAX_BYTES:
        return {"invalid": f"serialized state of {len(data)} bytes exceeds {MAX_BYTES}"}
    try:
        state = json.loads(bytes(data).decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        return {"invalid": f"serialized state is not JSON: {str(e)[:200]}"}
    if not isinstance(state, dict):
        return {"invalid": f"serialized state is a JSON {type(state).__name__}, not an object"}
    return state


# --- reading ------------------------------------------------------------------------------------
class _Decoder:
    def __init__(self, classes: dict[str, type]):
        self.classes = classes
        self.made: list = []

    def _register(self, x: Any) -> Any:
        self.made.append(x)
        return x

    def node(self, n: Any, path: str, depth: int = 0) -> Any:
        if depth > MAX_DEPTH:
            raise StateError(f"{path}: nested deeper than {MAX_DEPTH}")
        if n is None or isinstance(n, (bool, str, int)):
            return n
        if isinstance(n, float):
            return n
        if not isinstance(n, dict) or len(n) == 0:
            raise StateError(f"{path}: {type(n).__name__} is not a state value")
        tag = next(iter(n))
        body = n[tag]
        d = depth + 1
        if tag == "float":
            if len(n) != 1 or body not in _NONFINITE:
                raise StateError(f"{path}: bad non-finite float {body!r}")
            return _NONFINITE[body]
        if tag in _SCALARS:
            kind, plain = _SCALARS[tag]
            v = self.node(body, path, d) if tag == "f8" else body
            if len(n) != 1 or type(v) is not plain and not (plain is float and type(v) is int):
                raise StateError(f"{path}: {tag} scalar {body!r} is not a {plain.__name__}")
            try:
                return kind(v)
            except OverflowError:
                raise StateError(f"{path}: {tag} scalar {body!r} is out of range") from None
        if tag == "ref":
            if len(n) != 1 or type(body) is not int or not 0 <= body < len(self.made):
                raise StateError(f"{path}: reference {body!r} to nothing met before")
            return self.made[body]
        if tag == "cls":
            if len(n) != 1 or not isinstance(body, str) or body not in self.classes:
                raise StateError(f"{path}: {body!r} is not a state class")
            return self.classes[body]
        if tag == "nd":
            return self._register(_array(n, path))
        if tag in ("list", "tuple", "deque"):
            if not isinstance(body, list) or set(n) != ({"deque", "maxlen"} if tag == "deque" else {tag}):
                raise StateError(f"{path}: malformed {tag}")
            if tag == "tuple":
                slot = len(self.made)
                self.made.append(None)  # a tuple exists only once its items do
                t = tuple(self.node(v, f"{path}[{i}]", d) for i, v in enumerate(body))
                self.made[slot] = t
                return t
            maxlen = n.get("maxlen")
            if maxlen is not None and (type(maxlen) is not int or maxlen < 0):
                raise StateError(f"{path}: bad deque maxlen {maxlen!r}")
            out = self._register([] if tag == "list" else collections.deque(maxlen=maxlen))
            out.extend(self.node(v, f"{path}[{i}]", d) for i, v in enumerate(body))
            return out
        if tag == "dict":
            if len(n) != 1 or not isinstance(body, list):
                raise StateError(f"{path}: malformed dict")
            out = self._register({})
            for i, kv in enumerate(body):
                if not isinstance(kv, list) or len(kv) != 2:
                    raise StateError(f"{path}: dict item {i} is not a [key, value] pair")
                key = self.node(kv[0], f"{path} key {i}", d)
                try:
                    hash(key)
                except TypeError:
                    raise StateError(f"{path}: dict key {i} is not hashable") from None
                out[key] = self.node(kv[1], f"{path}[{key!r}]", d)
            return out
        if tag == "rng":
            if set(n) != {"rng", "state"} or body != "PCG64" or not isinstance(n["state"], dict):
                raise StateError(f"{path}: only a PCG64 generator state can be restored")
            bg = np.random.PCG64()
            try:
                bg.state = n["state"]
            except (TypeError, ValueError, KeyError, OverflowError) as e:
                raise StateError(f"{path}: bad PCG64 state ({e})") from None
            return self._register(np.random.Generator(bg))
        if tag == "obj":
            cls = self.classes.get(body) if isinstance(body, str) else None
            fields = n.get("fields")
            if cls is None or set(n) != {"obj", "fields"} or not isinstance(fields, dict):
                raise StateError(f"{path}: {body!r} is not a state class")
            obj = self._register(object.__new__(cls))
            values = {k: self.node(v, f"{path}.{k}", d) for k, v in fields.items()}
            vars(obj).update(values)  # no __setattr__: frozen dataclasses too, no code of the class runs
            return obj
        raise StateError(f"{path}: unknown tag {tag!r}")


def _array(n: dict, path: str) -> np.ndarray:
    dt = _DTYPES.get(n.get("nd"))
    shape, data = n.get("shape"), n.get("data")
    if (dt is None or set(n) != {"nd", "shape", "data"} or not isinstance(shape, list) or not isinstance(data, str)
            or not all(type(s) is int and s >= 0 for s in shape)):
        raise StateError(f"{path}: malformed array")
    count = math.prod(shape)
    if len(data) != 4 * math.ceil(count * dt.itemsize / 3):
        raise StateError(f"{path}: array data of {len(data)} characters does not hold shape {tuple(shape)}")
    try:
        raw = base64.b64decode(data, validate=True)
    except (binascii.Error, ValueError):
        raise StateError(f"{path}: array data is not base64") from None
    if len(raw) != count * dt.itemsize:
        raise StateError(f"{path}: array data does not hold shape {tuple(shape)}")
    return np.frombuffer(raw, dtype=dt).reshape(shape).astype(dt.newbyteorder("="), copy=True)


def decode(nodes: dict[str, Any], classes: dict[str, type]) -> dict[str, Any]:
    """The core objects of a state's ``core`` (fresh objects, shared with nothing), objects only
    of ``classes``. Raises StateError."""
    if not isinstance(nodes, dict):
        raise StateError("core: not an object")
    dec = _Decoder(classes)
    try:
        return {k: dec.node(v, k) for k, v in nodes.items()}
    except RecursionError:
        raise StateError("core: nested too deeply") from None


def load(data: bytes, classes: tuple[type, ...]) -> dict[str, Any]:
    """A serialized state's variables and core objects, {name: value} (for reading a saved
    state, e.g. the filter's covariance; the FMU checks more before it restores one). Raises
    StateError."""
    state = from_bytes(data)
    if "invalid" in state or not isinstance(state.get("variables"), dict):
        raise StateError(str(state.get("invalid", "no variables")))
    out = {k: decode_value(v, k) for k, v in state["variables"].items()}
    out.update(decode(state.get("core"), table(classes)))
    return out


def decode_value(node: Any, path: str) -> Any:
    """One variable's value (a number, string, boolean, or non-finite float). Raises StateError."""
    if isinstance(node, dict) and set(node) == {"float"}:
        return _Decoder({}).node(node, path)
    if node is None or isinstance(node, (dict, list)):
        raise StateError(f"{path}: {type(node).__name__} is not a variable's value")
    return node


def check_against(got: Any, ref: Any, path: str) -> None:
    """``got`` (decoded) has the structure of ``ref`` (a core built from the same parameters):
    objects of the same class with the same fields, arrays of the same dtype and shape and finite
    where ``ref``'s are, containers of the same kind, numbers where numbers are. None stands for
    a part not made yet on either side (filters made at the first step). Raises StateError."""
    _check(got, ref, path, set())


def _check(got: Any, ref: Any, path: str, seen: set) -> None:
    if got is None or ref is None:
        return
    if isinstance(ref, (bool, np.bool_)):
        if not isinstance(got, (bool, np.bool_)):
            raise StateError(f"{path}: {type(got).__name__} where a boolean is expected")
        return
    if isinstance(ref, (int, float, np.integer, np.floating)):
        if isinstance(got, (bool, np.bool_)) or not isinstance(got, (int, float, np.integer, np.floating)):
            raise StateError(f"{path}: {type(got).__name__} where a number is expected")
        return
    if isinstance(ref, type) or isinstance(got, type):
        if got is not ref and not (isinstance(got, type) and isinstance(ref, type)):
            raise StateError(f"{path}: {got!r} where a class is expected")
        return
    if type(got) is not type(ref):
        raise StateError(f"{path}: {type(got).__name__} where {type(ref).__name__} is expected")
    if id(got) in seen:
        return
    seen.add(id(got))
    if isinstance(ref, np.ndarray):
        if got.dtype != ref.dtype or got.shape != ref.shape:
            raise StateError(f"{path}: array {got.dtype}{got.shape} where {ref.dtype}{ref.shape} is expected")
        if got.dtype.kind == "f" and not np.all(np.isfinite(got[np.isfinite(ref)])):
            raise StateError(f"{path}: non-finite values")
        return
    if isinstance(ref, (list, tuple)):
        if len(got) == len(ref):
            for i, (g, r) in enumerate(zip(got, ref)):
                _check(g, r, f"{path}[{i}]", seen)
        return
    if hasattr(ref, "__dict__"):
        have, want = set(vars(got)), set(vars(ref))
        # a field the data has beyond ref's may only stand for a data default of the class
        # (RoadFilter.nis = 0.0), never shadow a method or property
        extra = sorted(k for k in have - want if not _class_default(type(ref), k))
        missing = sorted(want - have)
        if extra or missing:
            raise StateError(f"{path}: fields " + "; ".join(
                s for s in (f"missing {missing}" if missing else "", f"unknown {extra}" if extra else "") if s))
        for k in sorted(have):
            _check(vars(got)[k], vars(ref)[k] if k in want else getattr(type(ref), k), f"{path}.{k}", seen)


def _class_default(cls: type, name: str) -> bool:
    v = inspect.getattr_static(cls, name, _ABSENT)
    return v is not _ABSENT and not callable(v) and not hasattr(v, "__get__")


_ABSENT = object()
