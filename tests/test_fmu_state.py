"""FMU state through FMPy: get/set, serialize/deserialize (also into a second instance), reset."""
from __future__ import annotations

import numpy as np
import pytest

from fmu_driver import Driven

H = 1e-3


def feed(name: str):
    """Inputs for step k of each FMU: a varying speed, a road, plant-like measurements."""
    rng = np.random.default_rng(3)
    road = np.cumsum(rng.normal(0, 1e-4, 4000))
    if name == "ISORoad":
        return lambda k: {"vehicle_speed": 8.0 + 4.0 * np.sin(k / 200)}
    if name == "QuarterCar":
        return lambda k: {"road_height": road[k], "sprung_mass": 410.0 if k < 1500 else 500.0}
    if name == "HalfCar":
        return lambda k: {"road_height_front": road[k], "road_height_rear": road[k - 135] if k >= 135 else 0.0,
                          "sprung_mass": 672.0 if k < 1500 else 760.0, "force_front": 300.0 * np.sin(k / 50),
                          "force_rear": -100.0 if k > 2000 else 0.0}
    acc = rng.normal(0, 1.0, (4000, 3)) * [1.0, 10.0, 0.01]
    return lambda k: {"acc_sprung": acc[k, 0], "acc_unsprung": acc[k, 1], "susp_deflection": acc[k, 2]}


OUTPUTS = {
    "ISORoad": ["road_height", "road_velocity", "distance"],
    "QuarterCar": ["acc_sprung", "acc_unsprung", "susp_deflection", "z_s", "v_u", "tire_force"],
    "SuspensionEstimator": ["road_height_est", "road_height_std", "v_s_est", "sprung_mass_est", "nis"],
    "HalfCar": ["acc_body_front", "acc_unsprung_rear", "susp_deflection_rear", "pitch", "v_u_front",
                "tire_force_rear"],
}


def advance(d: Driven, name: str, k0: int, k1: int) -> np.ndarray:
    inputs = feed(name)
    out = []
    for k in range(k0, k1):
        d.step(H, **inputs(k))
        out.append([d.get(o) for o in OUTPUTS[name]])
    return np.array(out)


@pytest.mark.parametrize("name", list(OUTPUTS))
def test_state_restored_replays_bit_identically(dist, name):
    d = Driven(dist / f"{name}.fmu", {})
    try:
        advance(d, name, 0, 1000)
        t1 = d.t
        state = d.fmu.getFMUstate()
        first = advance(d, name, 1000, 2500)
        d.fmu.setFMUstate(state)
        d.t = t1
        again = advance(d, name, 1000, 2500)
        assert np.array_equal(first, again)
        # serialized, into the same instance and into a second one
        blob = d.fmu.serializeFMUstate(state)
        d.fmu.freeFMUstate(state)
        restored = d.fmu.deSerializeFMUstate(blob)
        d.fmu.setFMUstate(restored)
        d.t = t1
        assert np.array_equal(advance(d, name, 1000, 2500), first)
        other = Driven(dist / f"{name}.fmu", {}, name="other")
        try:
            other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(blob))
            other.t = t1
            assert np.array_equal(advance(other, name, 1000, 2500), first)
        finally:
            other.close()
    finally:
        d.close()


@pytest.mark.parametrize("name", list(OUTPUTS))
def test_reset_behaves_like_a_fresh_instance(dist, name):
    params = {"ISORoad": {"road_class": 5, "seed": 9}, "QuarterCar": {"noise_seed": 4},
              "SuspensionEstimator": {"road_class": 4}, "HalfCar": {"noise_seed": 4, "c_r": 0.0}}[name]
    fresh = Driven(dist / f"{name}.fmu", params, name="fresh")
    used = Driven(dist / f"{name}.fmu", params, name="used")
    try:
        reference = advance(fresh, name, 0, 800)
        advance(used, name, 0, 1300)
        used.fmu.reset()
        used.fmu.setupExperiment(startTime=0.0)
        used.fmu.enterInitializationMode()
        for k, v in params.items():
            used.set(k, v)
        used.fmu.exitInitializationMode()
        used.t = 0.0
        assert np.array_equal(advance(used, name, 0, 800), reference)
    finally:
        fresh.close()
        used.close()
