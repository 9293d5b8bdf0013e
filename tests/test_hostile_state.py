"""A saved FMU state is data: hostile, corrupt and foreign states through FMPy's
fmi2DeSerializeFMUstate + fmi2SetFMUstate are refused with a logged reason naming the field, run
nothing, and leave the instance stepping exactly as one that was never handed them; every
estimator code round-trips bit for bit."""
from __future__ import annotations

import base64
import copy
import json
import pickle

import numpy as np
import pytest

from fmu_driver import Driven
from suspension_estimation.suspension_fmi.contract import MASS_ESTIMATORS, ROAD_ESTIMATORS
from suspension_estimation.estimators.interface import code_problems

H = 1e-3
ERROR = 3
OUT = ["road_height_est", "road_height_std", "v_s_est", "sprung_mass_est", "nis", "mass_std"]


def feed(k: int) -> dict:
    """Plant-like measurements for step k (deterministic)."""
    rng = np.random.default_rng(k)
    a = rng.normal(0.0, 1.0, 3) * [1.0, 10.0, 0.003]
    return {"acc_sprung": a[0], "acc_unsprung": a[1], "susp_deflection": a[2], "vehicle_speed": 11.0}


def run(d: Driven, k0: int, k1: int) -> np.ndarray:
    out = []
    for k in range(k0, k1):
        d.step(H, **feed(k))
        out.append([d.get(o) for o in OUT])
    return np.array(out)


class _Marker:
    """Unpickling this creates ``path``: a stand-in for any code a pickle can run."""

    def __init__(self, path: str):
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


CODES = [(r, m) for r in ROAD_ESTIMATORS for m in MASS_ESTIMATORS if not code_problems(r, m)]
NONLINEAR = {"spring_model": 1, "damper_model": 1}


@pytest.mark.parametrize("road,mass,laws", [(r, m, {}) for r, m in CODES]
                         + [(r, m, NONLINEAR) for r, m in CODES if r in (3, 5) and m in (0, 3)])
def test_every_estimator_code_round_trips_bit_identically(dist, road, mass, laws):
    """get/set and serialize/deserialize into a second instance replay the run exactly (the
    nonlinear filters also on the air spring and the piecewise damper)."""
    params = {"road_estimator": road, "mass_estimator": mass, **laws}
    d = Driven(dist / "SuspensionEstimator.fmu", params)
    other = Driven(dist / "SuspensionEstimator.fmu", params, name="other")
    try:
        run(d, 0, 150)
        t = d.t
        state = d.fmu.getFMUstate()
        first = run(d, 150, 300)
        d.fmu.setFMUstate(state)
        d.t = t
        assert np.array_equal(run(d, 150, 300), first)
        other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(d.fmu.serializeFMUstate(state)))
        other.t = t
        assert np.array_equal(run(other, 150, 300), first)
        assert not [m for s, m in d.messages + other.messages if s >= ERROR]
    finally:
        d.close()
        other.close()


@pytest.fixture(scope="module")
def saved(dist):
    """(serialized state at step 200 as a JSON object, the outputs of steps 200-400 after it)."""
    d = Driven(dist / "SuspensionEstimator.fmu", {})
    try:
        run(d, 0, 200)
        blob = bytes(d.fmu.serializeFMUstate(d.fmu.getFMUstate()))
        return json.loads(blob), run(d, 200, 400)
    finally:
        d.close()


def _field(state: dict, *path):
    """The node at ``path`` below state["core"]["core"]["fields"] (objects' fields followed)."""
    node = state["core"]["core"]
    for key in path:
        node = node["fields"][key] if "obj" in node else node[key]
    return node


def _array_of(values, shape=None) -> dict:
    a = np.asarray(values, "<f8")
    return {"nd": "<f8", "shape": list(a.shape if shape is None else shape),
            "data": base64.b64encode(a.tobytes()).decode()}


def _mutations(tmp_path) -> dict:
    """name -> (function of the JSON state returning the bytes handed to the FMU, a word the
    refusal must contain)."""
    marker = tmp_path / "ran"

    def edit(fn):
        def apply(state):
            s = copy.deepcopy(state)
            fn(s)
            return json.dumps(s).encode()
        return apply

    def set_field(path, value):
        def fn(s):
            _field(s, *path[:-1])["fields"][path[-1]] = value
        return fn

    pickled = base64.b64encode(pickle.dumps(_Marker(str(marker)))).decode()
    return {
        "pickle (the old format)": (lambda s: json.dumps({"model": "SuspensionEstimator", "pickle": pickled}).encode(),
                                   "fields"),
        "pickle as array data": (edit(lambda s: _field(s, "road", "kf")["fields"].update(
            x={"nd": "<f8", "shape": [6], "data": pickled})), "kf"),
        "pickle as an object node": (edit(set_field(["road", "kf", "x"], {"pickle": pickled})), "tag"),
        "truncated": (lambda s: json.dumps(s).encode()[: len(json.dumps(s)) // 2], "JSON"),
        "garbled bytes": (lambda s: bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8)), "JSON"),
        "a JSON list": (lambda s: b"[1, 2, 3]", "object"),
        "another FMU": (edit(lambda s: s.update(model="QuarterCar")), "model"),
        "an older format version": (edit(lambda s: s.update(version=0)), "version"),
        "another format": (edit(lambda s: s.update(format="pickle")), "format"),
        "missing variable": (edit(lambda s: s["variables"].pop("m_s_nominal")), "m_s_nominal"),
        "variable of the wrong type": (edit(lambda s: s["variables"].update(m_s_nominal="heavy")), "m_s_nominal"),
        "parameter out of range": (edit(lambda s: s["variables"].update(m_s_nominal=-5.0)), "m_s_nominal"),
        "a class not in the table": (edit(set_field(["road", "kf"], {"obj": "posix.system", "fields": {}})),
                                     "state class"),
        "a class node": (edit(set_field(["time"], {"cls": "subprocess.Popen"})), "state class"),
        "missing field": (edit(lambda s: _field(s, "road", "kf")["fields"].pop("P")), "P"),
        "unknown field": (edit(set_field(["road", "kf", "step"], 1.0)), "step"),
        "wrong type": (edit(set_field(["time"], "noon")), "time"),
        "wrong shape": (edit(set_field(["road", "kf", "P"], _array_of(np.eye(3)))), "kf.P"),
        "array data short of its shape": (edit(set_field(["road", "kf", "x"], _array_of(np.zeros(6), [9]))), "kf.x"),
        "huge array": (edit(set_field(["road", "kf", "x"], _array_of(np.zeros(6), [10 ** 12]))), "kf.x"),
        "NaN in the filter state": (edit(set_field(["road", "kf", "x"], _array_of([np.nan] * 9))), "kf.x"),
        "dangling reference": (edit(set_field(["road", "kf", "x"], {"ref": 10 ** 6})), "reference"),
        "deep nesting": (edit(set_field(["road", "kf", "x"], json.loads('{"list": [' * 60 + "]}" * 60))), "deeper"),
        "core missing": (edit(lambda s: s.update(core={})), "core"),
    }



def test_hostile_states_are_refused_naming_the_field(dist, saved, tmp_path):
    """Each hostile state: deserialize and set return (no fmi2Fatal, the host alive), an error
    logged naming the field, nothing run (the pickle's marker file not created), and the
    instance steps on exactly as if the state had never been handed to it."""
    state, after = saved
    mutations = _mutations(tmp_path)
    d = Driven(dist / "SuspensionEstimator.fmu", {})
    try:
        run(d, 0, 200)
        keep = d.fmu.getFMUstate()
        for name, (make, word) in mutations.items():
            before = len(d.messages)
            d.fmu.setFMUstate(d.fmu.deSerializeFMUstate(make(state)))
            new = [m for s, m in d.messages[before:] if s >= ERROR]
            assert len(new) == 1 and "refuses the FMU state" in new[0] and word in new[0], (name, new)
            assert not (tmp_path / "ran").exists(), name
            d.t = 0.2
            assert np.array_equal(run(d, 200, 230), after[:30]), name
            d.fmu.setFMUstate(keep)
        assert not [m for s, m in d.messages if s > ERROR]
    finally:
        d.close()


@pytest.mark.parametrize("name", ["ISORoad", "QuarterCar", "HalfCar"])
def test_a_pickle_state_runs_nothing_on_the_other_fmus(dist, name, tmp_path):
    marker = tmp_path / "ran"
    blob = json.dumps({"model": name, "pickle": base64.b64encode(pickle.dumps(_Marker(str(marker)))).decode()})
    d = Driven(dist / f"{name}.fmu", {})
    try:
        d.fmu.setFMUstate(d.fmu.deSerializeFMUstate(blob.encode()))
        assert not marker.exists()
        assert any("refuses the FMU state" in m for s, m in d.messages if s == ERROR)
        d.step(H)
    finally:
        d.close()


def test_a_state_of_one_configuration_restores_into_another(dist, saved):
    """A state carries its parameters: set on an instance configured otherwise (the KF, class
    D), the run goes on as the saved one (the default estimator), checked against a core built
    from the state's own parameters."""
    state, after = saved
    d = Driven(dist / "SuspensionEstimator.fmu", {"road_estimator": 0, "road_class": 4})
    try:
        d.fmu.setFMUstate(d.fmu.deSerializeFMUstate(json.dumps(state).encode()))
        d.t = 0.2
        assert np.array_equal(run(d, 200, 260), after[:60])
        assert d.get("road_estimator") == 2
    finally:
        d.close()
