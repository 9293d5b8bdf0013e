"""How the plant's road moves over a step (plant.quarter_car.HELD, LINEAR): the linear plant's
exact discretisation against an independent solver, and what the held road's staircase does to a
point-sampled wheel acceleration."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from suspension_estimation.estimators.steady_state import plant_transfer
from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
from suspension_estimation.plant.quarter_car import HELD, LINEAR, QuarterCar, SensorNoise, state_matrices
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE as V

QUIET = SensorNoise(0.0, 0.0, 0.0)


@pytest.mark.parametrize("road_input", [HELD, LINEAR])
def test_exact_discretisation_matches_an_ode_solver(road_input):
    """A random road at 10 ms: the plant against DOP853 (rtol 1e-11) on the same road, held over each
    step or moving linearly from the last input to this one."""
    h = 0.01
    road = np.random.default_rng(4).normal(0.0, 0.01, 60)
    A, B = state_matrices(V)
    car = QuarterCar(V, QUIET, road_input=road_input)
    car.settle(0.0)
    y, r0 = np.zeros(4), 0.0
    for r in road:
        u = (lambda t, r=r: r) if road_input == HELD else (lambda t, r=r, r0=r0: r0 + (r - r0) * t / h)
        y = solve_ivp(lambda t, x: A @ x + B * u(t), (0.0, h), y, method="DOP853", rtol=1e-11, atol=1e-14).y[:, -1]
        car.step(r, h)
        r0 = r
        np.testing.assert_allclose(car.x, y, rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(y))))
        np.testing.assert_allclose(car.acc_true, (A @ y + B * r)[[1, 3]], rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("plant", ["linear", "air spring"])
def test_a_held_road_biases_the_point_sampled_wheel_acceleration_on_a_grade(plant):
    """On a constant grade the car rises at v_r and accelerates at nothing. The held road jumps by
    v_r h at each step and the tyre's force is a sawtooth about the force that carries the wheel;
    sampled at the step's end, just before the next jump, the wheel acceleration reads
    -k_t v_r h / (2 m_u) (1.41 m/s2 for a 3 % grade at 72 km/h at 1 kHz): a wheel-accelerometer bias
    three times the range of a real sensor's, which only the plant's staircase makes. The road
    moving linearly over the step reads 0."""
    h, v_r = 1e-3, 0.03 * 20.0
    make = (lambda ri: QuarterCar(V, QUIET, road_input=ri)) if plant == "linear" else (
        lambda ri: NonlinearQuarterCar(V, noise=QUIET, road_input=ri))
    mean = {}
    for ri in (HELD, LINEAR):
        car = make(ri)
        car.settle(0.0)
        a_u = []
        for k in range(4000):  # 4 s: the start's transient (wheel hop, body) has died out by 3 s
            car.step(v_r * (k + 1) * h, h)
            a_u.append(car.acc_true[1])
        mean[ri] = float(np.mean(a_u[3000:]))
    expected = -V.k_t * v_r * h / (2.0 * V.m_u)
    assert mean[HELD] == pytest.approx(expected, rel=0.03)
    assert abs(mean[LINEAR]) < 0.01 * abs(expected)


def test_an_unknown_road_input_is_refused():
    with pytest.raises(ValueError, match="road_input"):
        QuarterCar(V, road_input="cubic")


@pytest.mark.parametrize("road_input", [HELD, LINEAR])
@pytest.mark.parametrize("acc_sampling", [0, 1])
def test_steady_state_plant_transfer_is_the_plants_response_to_a_sampled_sinusoid(road_input, acc_sampling):
    """estimators.steady_state.plant_transfer, which the steady-state scores and road_height_std's
    band ratio use, against the plant driven with r_k = cos(w t_k) at 10 ms (amplitude and phase of
    each channel, fitted by least squares once the start's transient has died out)."""
    h = 0.01
    for f in (1.3, 11.0, 31.0):
        w = 2 * np.pi * f
        car = QuarterCar(V, QUIET, acc_sampling=acc_sampling, road_input=road_input)
        car.settle(0.0)
        t = np.arange(1, 1501) * h
        y = np.empty((t.size, 3))
        for k, tk in enumerate(t):
            car.step(np.cos(w * tk), h)
            y[k] = car.measured
        late = t > 10.0
        basis = np.column_stack([np.cos(w * t[late]), np.sin(w * t[late])])
        coef = np.linalg.lstsq(basis, y[late], rcond=None)[0]  # y = Re(G e^{i w t}) = Re G cos - Im G sin
        got = coef[0] - 1j * coef[1]
        G = plant_transfer(V, h, np.array([np.exp(-1j * w * h)]), acc_sampling, road_input)[0]
        np.testing.assert_allclose(got, G, rtol=1e-6, atol=1e-9 * np.max(np.abs(G)))


@pytest.mark.parametrize("spring_model", [0, 1])
def test_the_plant_fmus_road_input_is_the_cores(dist, spring_model):
    """QuarterCar.fmu with road_input 1 behind ISORoad (Gauss-Seidel: the road at the step's end
    is the plant's input) equals the core plant with LINEAR fed the same road, and differs from
    the held road's; linear and air-spring plants."""
    from suspension_estimation.harness.cosim import CoSimulation
    from suspension_estimation.harness.ssp import ROAD_PLANT, ensure_system_ssp, read_ssp
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER

    system = read_ssp(ensure_system_ssp(dist, ROAD_PLANT), fmu_dir=dist)
    h, v = 1e-3, 20.0
    rec = ["ISORoad.road_height", "QuarterCar.acc_unsprung_true", "QuarterCar.z_s"]
    runs = {}
    for ri in (0, 1):
        p = {"ISORoad.road_class": 4, "QuarterCar.road_input": ri,
             "QuarterCar.spring_model": spring_model, "QuarterCar.damper_model": spring_model}
        with CoSimulation(system, parameters=p, inputs={"vehicle_speed": v}, record=rec) as sim:
            runs[ri] = sim.run(0.5, h)
    r = runs[1]
    car = (QuarterCar(V, road_input=LINEAR) if spring_model == 0 else
           NonlinearQuarterCar(V, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, road_input=LINEAR))
    car.settle(r["ISORoad.road_height"][0])
    acc = [car.acc_true[1]]
    for zr in r["ISORoad.road_height"][1:]:
        car.step(float(zr), h)
        acc.append(car.acc_true[1])
    assert np.allclose(r["QuarterCar.acc_unsprung_true"], acc, rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(runs[0]["QuarterCar.acc_unsprung_true"] - acc)) > 0.01 * np.ptp(acc)
