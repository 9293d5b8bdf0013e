"""QuarterCar.fmu through FMPy against independent solutions, eigenvalues and noise statistics."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from fmpy.fmi1 import FMICallException
from fmu_driver import Driven
from plant.quarter_car import state_matrices
from plant.vehicle import DEFAULT_VEHICLE, Vehicle

OUT = ["z_s", "v_s", "z_u", "v_u", "acc_sprung_true", "acc_unsprung_true", "susp_deflection", "tire_force"]
QUIET = {"acc_sprung_noise_std": 0.0, "acc_unsprung_noise_std": 0.0, "defl_noise_std": 0.0}


@pytest.fixture
def plant(driven):
    return lambda **params: driven("QuarterCar", **params)


def drive(p: Driven, road: np.ndarray, h: float, mass: np.ndarray | None = None) -> np.ndarray:
    out = np.empty((len(road), len(OUT)))
    refs = [p.vars[o].valueReference for o in OUT]
    for k, r in enumerate(road):
        p.set("road_height", r)
        if mass is not None:
            p.set("sprung_mass", mass[k])
        p.fmu.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        out[k] = p.fmu.getReal(refs)
    return out


def reference(v: Vehicle, road: np.ndarray, h: float, x0=None) -> tuple[np.ndarray, np.ndarray]:
    """scipy.signal.lsim at a 10x finer step, the road held over each communication step."""
    A, B = state_matrices(v)
    C = np.vstack([np.eye(4), A[[1, 3]], [[1, 0, -1, 0]], [[0, 0, -v.k_t, 0]]])
    D = np.array([0, 0, 0, 0, B[1], B[3], 0, v.k_t])
    fine = np.repeat(road, 10)
    t = np.arange(len(fine) + 1) * h / 10
    u = np.append(fine, fine[-1])
    _, y, x = signal.lsim((A, B[:, None], C, D[:, None]), u, t, X0=x0, interp=False)
    # the FMU's output after step k is the state at t=(k+1)h with the road of step k
    y_end = y[10::10].copy()
    y_end[:, [4, 5, 7]] = (C[[4, 5, 7]] @ x[10::10].T).T + np.outer(road, D[[4, 5, 7]])
    return y_end, x[-1]


def bump(h: float, t_end: float = 3.0) -> np.ndarray:
    t = np.arange(int(round(t_end / h))) * h
    return np.where((t > 0.5) & (t < 0.6), 0.01 * (1 - np.cos(2 * np.pi * (t - 0.5) / 0.1)), 0.0)  # 20 mm


def sweep(h: float, t_end: float = 10.0) -> np.ndarray:
    t = np.arange(int(round(t_end / h))) * h
    return 0.005 * signal.chirp(t, f0=0.5, t1=t_end, f1=20.0, method="logarithmic")


@pytest.mark.parametrize("h", [0.001, 0.01])
@pytest.mark.parametrize("make_road", [bump, sweep])
def test_response_matches_lsim_within_half_a_percent_of_the_peak(plant, h, make_road):
    road = make_road(h)
    got = drive(plant(**QUIET), road, h)
    ref, _ = reference(DEFAULT_VEHICLE, road, h)
    for j, name in enumerate(OUT):
        err = np.max(np.abs(got[:, j] - ref[:, j])) / np.max(np.abs(ref[:, j]))
        assert err < 0.005, f"{name}: {err:.2e} of the peak"


def test_sprung_mass_may_change_during_a_run(plant):
    h = 0.001
    road = sweep(h, 4.0)
    mass = np.where(np.arange(len(road)) * h < 2.0, 410.0, 590.0)
    got = drive(plant(**QUIET), road, h, mass)
    half = len(road) // 2
    ref1, x1 = reference(DEFAULT_VEHICLE, road[:half], h)
    ref2, _ = reference(DEFAULT_VEHICLE.with_(m_s=590.0), road[half:], h, x0=x1)
    ref = np.vstack([ref1, ref2])
    assert np.max(np.abs(got[:, 0] - ref[:, 0])) < 0.005 * np.max(np.abs(ref[:, 0]))
    # and the heavier body really responds differently from a 410 kg one
    same = drive(plant(**QUIET), road, h)
    assert np.max(np.abs(got[half:, 0] - same[half:, 0])) > 0.05 * np.max(np.abs(same[:, 0]))


def test_body_bounce_and_wheel_hop_frequencies():
    f_body, f_wheel = DEFAULT_VEHICLE.natural_frequencies()  # damped, from the eigenvalues of A
    assert 0.95 < f_body < 1.2 and 10.0 < f_wheel < 12.0
    v = DEFAULT_VEHICLE
    # undamped 2-DOF frequencies in closed form agree with the eigenvalues of the undamped A
    a, b, c = v.m_s * v.m_u, -(v.m_s * (v.k_s + v.k_t) + v.m_u * v.k_s), v.k_s * v.k_t
    w2 = np.sort(np.roots([a, b, c]))
    closed = np.sqrt(w2) / (2 * np.pi)
    eig = np.linalg.eigvals(state_matrices(v.with_(c_s=0.0))[0])
    assert np.allclose(np.sort(np.abs(eig.imag[eig.imag > 0])) / (2 * np.pi), closed, rtol=1e-9)


def test_free_response_of_the_fmu_rings_at_the_eigenfrequencies(plant):
    h, n = 0.001, 40_000
    got = drive(plant(c_s=0.0, **QUIET), np.full(n, 0.01), h)  # undamped, a 10 mm road step
    eig = np.linalg.eigvals(state_matrices(DEFAULT_VEHICLE.with_(c_s=0.0))[0])
    f_modes = np.sort(np.abs(eig.imag[eig.imag > 0])) / (2 * np.pi)
    for col, f_mode in ((0, f_modes[0]), (2, f_modes[1])):
        x = got[:, col] - got[:, col].mean()
        spec = np.abs(np.fft.rfft(x * np.hanning(n)))
        f = np.fft.rfftfreq(n, h)
        band = (f > f_mode / 2) & (f < f_mode * 1.5)
        assert abs(f[band][np.argmax(spec[band])] - f_mode) <= 1.5 / (n * h)


def test_the_car_starts_at_rest_on_the_road_it_stands_on(plant):
    p = plant(**QUIET, road_height=0.05)
    out = p.run(0.001, 500, ["z_s", "z_u", "acc_sprung", "acc_unsprung", "susp_deflection", "tire_force"],
                road_height=0.05)
    assert np.allclose(out[:, :2], 0.05, atol=1e-12)
    assert np.allclose(out[:, 2:], 0.0, atol=1e-9)


def test_sensor_noise_is_seeded_white_with_the_set_std(plant):
    stds = {"acc_sprung_noise_std": 0.05, "acc_unsprung_noise_std": 0.3, "defl_noise_std": 2e-4}
    n = 20_000
    cols = ["acc_sprung", "acc_unsprung", "susp_deflection", "acc_sprung_true", "acc_unsprung_true", "z_s", "z_u"]

    def run(seed):
        p = plant(noise_seed=seed, **stds)
        return p.run(0.001, n, cols, road_height=0.0)

    a, b, c = run(11), run(11), run(12)
    assert np.array_equal(a, b)
    noise = np.column_stack([a[:, 0] - a[:, 3], a[:, 1] - a[:, 4], a[:, 2] - (a[:, 5] - a[:, 6])])
    for j, std in enumerate(stds.values()):
        e = noise[:, j]
        assert abs(e.std() / std - 1) < 0.03
        assert abs(e.mean()) < 4 * std / np.sqrt(n)
        rho = [np.corrcoef(e[:-k], e[k:])[0, 1] for k in range(1, 11)]
        assert max(abs(r) for r in rho) < 4 / np.sqrt(n)
    other = c[:, 0] - c[:, 3]
    assert abs(np.corrcoef(noise[:, 0], other)[0, 1]) < 4 / np.sqrt(n)


@pytest.mark.parametrize("params, name", [
    ({"m_u": -1.0}, "m_u"), ({"k_s": 0.0}, "k_s"), ({"k_t": float("nan")}, "k_t"), ({"c_s": -5.0}, "c_s"),
    ({"acc_sprung_noise_std": -0.1}, "acc_sprung_noise_std"), ({"defl_noise_std": -1e-4}, "defl_noise_std"),
    ({"acc_sampling": 2}, "acc_sampling"), ({"spring_model": 2}, "spring_model"), ({"noise_seed": -3}, "noise_seed"),
])
def test_bad_parameter_is_refused_naming_it_and_its_range(plant, params, name):
    p = plant(**params)
    assert any(status == 3 and name in m and "allowed range" in m for status, m in p.messages), p.messages
    with pytest.raises(FMICallException, match="discard"):
        p.step(0.001)


@pytest.mark.parametrize("inputs, name", [
    ({"road_height": float("nan")}, "road_height"), ({"road_height": float("inf")}, "road_height"),
    ({"sprung_mass": 0.0}, "sprung_mass"), ({"sprung_mass": float("nan")}, "sprung_mass"),
])
def test_bad_input_is_refused_at_the_step(plant, inputs, name):
    p = plant()
    p.step(0.001)
    with pytest.raises(FMICallException, match="discard"):
        p.step(0.001, **inputs)
    assert any(status == 3 and name in m for status, m in p.messages), p.messages
