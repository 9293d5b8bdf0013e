"""The half car, its core (plant/half_car.py) and HalfCar.fmu through FMPy: against scipy's DOP853
on the equations of motion written force by force, its modes against the mass and stiffness
matrices of the springs' elongations, paper 002's eq. 4 as printed, rest, lifted wheels, bad input."""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eig, eigh

from fmpy.fmi1 import FMICallException
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.half_car import (DEFAULT_HALF_CAR, HalfCar, HalfCarParams, input_matrix,
                                                  mass_matrix, natural_frequencies, state_matrices,
                                                  stiffness_matrix)
from suspension_estimation.plant.quarter_car import SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.suspension_forces import G

P = DEFAULT_HALF_CAR
H = 1e-3  # s
SPEED = 20.0  # m/s
QUIET = {"acc_sprung_noise_std": 0.0, "acc_unsprung_noise_std": 0.0, "defl_noise_std": 0.0}
INPUTS = ["road_height_front", "road_height_rear", "force_front", "force_rear"]
# what is compared with the reference (the tyre forces less their static loads)
OUT = ["heave", "pitch", "z_u_front", "z_u_rear", "heave_velocity", "pitch_rate", "v_u_front", "v_u_rear",
       "acc_body_front_true", "acc_body_rear_true", "acc_unsprung_front_true", "acc_unsprung_rear_true",
       "susp_deflection_front_true", "susp_deflection_rear_true", "tire_force_front", "tire_force_rear"]
TOLERANCE = 1e-6  # of each output's peak (the issue asks 0.1 %; measured: about 2e-14)


# --- the reference: Newton per body, integrated by DOP853 step by step with the inputs held ------
def rhs(p: HalfCarParams, y, u) -> list[float]:
    """x' of the half car written force by force, without its matrices. Pitch nose up: a force
    pushing the body up at the front axle (l_f ahead of the CG) lifts the nose."""
    z, th, zf, zr, vz, vth, vf, vr = y
    qf, qr, ff, fr = u
    front = ff + p.k_f * (zf - (z + p.l_f * th)) + p.c_f * (vf - (vz + p.l_f * vth))  # on the body, up
    rear = fr + p.k_r * (zr - (z - p.l_r * th)) + p.c_r * (vr - (vz - p.l_r * vth))
    return [vz, vth, vf, vr, (front + rear) / p.m_s, (p.l_f * front - p.l_r * rear) / p.pitch_inertia,
            (p.k_tf * (qf - zf) - front) / p.m_uf, (p.k_tr * (qr - zr) - rear) / p.m_ur]


def static_loads(p: HalfCarParams) -> tuple[float, float]:
    """Static tyre loads (N) by the lever rule."""
    L = p.l_f + p.l_r
    return G * (p.m_s * p.l_r / L + p.m_uf), G * (p.m_s * p.l_f / L + p.m_ur)


def reference(p: HalfCarParams, rest, u: np.ndarray, h: float, y0=None) -> np.ndarray:
    """The OUT columns after each step (rows of ``u``: [q_f, q_r, f_f, f_r] held over the step),
    from rest on the road heights ``rest`` without forces (or from the state ``y0``); tyre forces
    dynamic."""
    if y0 is None:
        L, (qf, qr) = p.l_f + p.l_r, rest
        y0 = [(p.l_r * qf + p.l_f * qr) / L, (qf - qr) / L, qf, qr, 0, 0, 0, 0]
    y = np.asarray(y0, dtype=float)
    rows = []
    for k, uk in enumerate(u):
        y = solve_ivp(lambda t, s: rhs(p, s, uk), (k * h, (k + 1) * h), y, method="DOP853",
                      rtol=1e-10, atol=1e-13).y[:, -1]
        a = rhs(p, y, uk)[4:]
        z, th, zf, zr = y[:4]
        rows.append([*y, a[0] + p.l_f * a[1], a[0] - p.l_r * a[1], a[2], a[3],
                     z + p.l_f * th - zf, z - p.l_r * th - zr, p.k_tf * (uk[0] - zf), p.k_tr * (uk[1] - zr)])
    return np.array(rows)


def bump_inputs(t_end: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(rest, steps): a 30 mm, 1 m long (1 - cos) bump 3 m ahead met by the front and then the
    rear tyre at 20 m/s, and actuator force steps (front +800 N from 1.0 s, rear -500 N from 1.2 s)."""
    t = (np.arange(round(t_end / H)) + 1) * H
    s = SPEED * t

    def bump(x):
        return np.where((x > 3.0) & (x < 4.0), 0.015 * (1 - np.cos(2 * np.pi * (x - 3.0))), 0.0)

    steps = np.column_stack([bump(s), bump(s - P.wheelbase), np.where(t > 1.0, 800.0, 0.0),
                             np.where(t > 1.2, -500.0, 0.0)])
    return np.zeros(2), steps


def iso_d_inputs(t_end: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(rest, steps): ISO 8608 class D (plant/road.py, seed 3) at 20 m/s under both tyres, the rear
    a wheelbase behind (on the road's negative distances at first); over each step the height at
    its end, as ISORoad gives it."""
    road = SyntheticRoad(iso8608.class_psd_n0(4), seed=3)
    s = SPEED * np.arange(round(t_end / H) + 1) * H
    q = np.array([[road.height(x), road.height(x - P.wheelbase)] for x in s])
    return q[0], np.column_stack([q[1:], np.zeros((len(s) - 1, 2))])


@lru_cache(maxsize=None)
def case(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rest, steps, reference outputs) of a named case, computed once."""
    rest, steps = {"bump": bump_inputs, "iso_d": iso_d_inputs}[name]()
    return rest, steps, reference(P, rest, steps, H)


def errors(got: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """max |got - ref| / max |ref| per OUT column."""
    return {name: float(np.max(np.abs(got[:, j] - ref[:, j])) / np.max(np.abs(ref[:, j])))
            for j, name in enumerate(OUT)}


def run_core(p: HalfCarParams, rest, steps, h: float = H) -> np.ndarray:
    car = HalfCar(p, SensorNoise(0.0, 0.0, 0.0))
    car.settle(*rest)
    sf, sr = p.static_tyre_loads()
    rows = []
    for qf, qr, ff, fr in steps:
        car.step(qf, qr, h, force_front=ff, force_rear=fr)
        tf, tr = car.tire_force
        rows.append([*car.x, *car.acc_true, *car.deflection_true, tf - sf, tr - sr])
    return np.array(rows)


def run_fmu(d, steps, h: float = H, outputs=OUT) -> np.ndarray:
    refs = [d.vars[o].valueReference for o in outputs]
    vin = [d.vars[i].valueReference for i in INPUTS]
    out = np.empty((len(steps), len(outputs)))
    for k, u in enumerate(steps):
        d.fmu.setReal(vin, list(map(float, u)))
        d.fmu.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        out[k] = d.fmu.getReal(refs)
    return out


# --- paper 002's matrices and the modes -------------------------------------------------------
def printed_eq4(p: HalfCarParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """B, C, D of paper 002's eq. 4 (A x'' + B x + C q + D f_c = 0) exactly as printed."""
    kf, kr, lf, lr = p.k_f, p.k_r, p.l_f, p.l_r
    B = np.array([[kf + kr, kf * lf - kr * lr, -kf, -kr],
                  [kr * lr - kf * lf, -kf * lf ** 2 - kr * lr ** 2, kf * lf, -kr * lr],
                  [-kf, -kf * lf, p.k_tf + kf, 0],
                  [-kr, kr * lr, 0, p.k_tr + kr]])
    C = np.array([[0, 0], [0, 0], [-p.k_tf, 0], [0, -p.k_tr]])
    D = np.array([[-1, -1], [lf, -lr], [1, 0], [0, 1]])
    return B, C, D


def test_eq4_as_printed_diverges_and_with_its_pitch_row_negated_is_ours():
    B, C, D = printed_eq4(P)
    M = mass_matrix(P)
    assert not np.allclose(B, B.T)
    # x'' = -M^-1 B x: a positive real eigenvalue of -M^-1 B is a mode growing as exp(sqrt(mu) t)
    assert np.max(np.linalg.eigvals(-np.linalg.solve(M, B)).real) > 1.0
    flip = np.diag([1.0, -1.0, 1.0, 1.0])
    assert np.array_equal(stiffness_matrix(P), flip @ B)
    K = stiffness_matrix(P)
    assert np.array_equal(K, K.T) and np.all(np.linalg.eigvalsh(K) > 0)
    assert np.array_equal(input_matrix(P), -np.hstack([C, flip @ D]))


def _spring_matrices(p: HalfCarParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M, K and C from the energies: the springs' elongations are J q (front and rear suspension:
    body point above the axle minus wheel; the tyres: the wheels)."""
    J = np.array([[1.0, p.l_f, -1.0, 0.0], [1.0, -p.l_r, 0.0, -1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    K = J.T @ np.diag([p.k_f, p.k_r, p.k_tf, p.k_tr]) @ J
    C = J[:2].T @ np.diag([p.c_f, p.c_r]) @ J[:2]
    return np.diag([p.m_s, p.pitch_inertia, p.m_uf, p.m_ur]), K, C


def modal_frequencies() -> dict[str, np.ndarray]:
    """Ours (eigenvalues of the state matrix) and the independent derivation (eigh of the spring
    matrices; the damped car: the quadratic eigenvalue problem), Hz, the modes ascending."""
    undamped = P.with_(c_f=0.0, c_r=0.0)
    M, K, C = _spring_matrices(P)
    lam = eig(np.block([[np.zeros((4, 4)), np.eye(4)], [-K, -C]]),
              np.block([[np.eye(4), np.zeros((4, 4))], [np.zeros((4, 4)), M]]), right=False)
    return {"undamped": natural_frequencies(undamped),
            "undamped, eigh(K, M)": np.sqrt(eigh(K, M, eigvals_only=True)) / (2 * np.pi),
            "damped": natural_frequencies(P),
            "damped, quadratic": np.sort(lam[lam.imag > 0].imag) / (2 * np.pi)}


def test_modal_frequencies_match_the_spring_matrices():
    f = modal_frequencies()
    assert np.allclose(f["undamped"], f["undamped, eigh(K, M)"], rtol=1e-9)
    assert np.allclose(f["damped"], f["damped, quadratic"], rtol=1e-9)
    lam = np.linalg.eigvals(state_matrices(P.with_(c_f=0.0, c_r=0.0))[0])
    assert np.max(np.abs(lam.real)) < 1e-6 * np.max(np.abs(lam))  # undamped: no decay, no growth
    assert np.max(np.linalg.eigvals(state_matrices(P)[0]).real) < 0  # damped: every mode decays
    # a passenger car: body heave and pitch near 1-1.5 Hz, wheel hop near 10-12 Hz
    body, hop = f["undamped"][:2], f["undamped"][2:]
    assert np.all((body > 1.0) & (body < 1.5)) and np.all((hop > 10.0) & (hop < 13.0))


# --- the core against the reference ----------------------------------------------------------
@pytest.mark.parametrize("name", ["bump", "iso_d"])
def test_core_matches_dop853_within_a_tenth_of_a_percent_of_the_peak(name):
    rest, steps, ref = case(name)
    err = errors(run_core(P, rest, steps), ref)
    assert max(err.values()) < TOLERANCE, err


def test_core_at_rest_reads_zero_deflection_on_any_road_level():
    car = HalfCar(P, SensorNoise(0.0, 0.0, 0.0))
    car.settle(1234.5, 1233.9)  # absolute elevations of a measured profile, on a slope
    for _ in range(100):
        car.step(1234.5, 1233.9, H)
    assert car.deflection_true == (0.0, 0.0) and car.acc_true == (0.0, 0.0, 0.0, 0.0)
    assert car.tire_force == pytest.approx(static_loads(P), rel=1e-15)
    assert sum(car.tire_force) == pytest.approx((P.m_s + P.m_uf + P.m_ur) * G, rel=1e-12)
    z, th, zf, zr = car.x[:4]
    assert (zf, zr) == (1234.5, 1233.9) and th == pytest.approx(0.6 / P.wheelbase, rel=1e-9)
    assert z + P.l_f * th == pytest.approx(1234.5, abs=1e-12)


def test_core_settles_with_actuator_forces_and_keeps_the_static_tyre_loads():
    car = HalfCar(P, SensorNoise(0.0, 0.0, 0.0))
    car.settle(0.0, 0.0, 600.0, -400.0)
    for _ in range(200):
        car.step(0.0, 0.0, H, force_front=600.0, force_rear=-400.0)
    assert np.array_equal(car.dx, np.zeros(8))
    df, dr = car.deflection_true
    assert df == pytest.approx(600.0 / P.k_f, rel=1e-9) and dr == pytest.approx(-400.0 / P.k_r, rel=1e-9)
    assert car.tire_force == pytest.approx(static_loads(P), rel=1e-12)


def test_sprung_mass_may_change_during_a_run():
    rest, steps, ref = case("iso_d")
    heavy = P.with_(m_s=800.0)
    ref2 = reference(heavy, None, steps[1000:], H, y0=ref[999, :8])
    car = HalfCar(P, SensorNoise(0.0, 0.0, 0.0))
    car.settle(*rest)
    rows = []
    for k, (qf, qr, ff, fr) in enumerate(steps):
        car.step(qf, qr, H, m_s=P.m_s if k < 1000 else heavy.m_s)
        rows.append([*car.x, *car.acc_true])
    assert car.discretisations == 2
    got, want = np.array(rows)[1000:], ref2[:, :12]
    assert np.max(np.abs(got - want) / np.max(np.abs(want), axis=0)) < TOLERANCE
    # the static load follows the mass (the suspension levelled), and the heavier body does respond otherwise
    assert car.tire_force[0] - static_loads(heavy)[0] == pytest.approx(P.k_tf * (steps[-1, 0] - car.x[2]))
    assert np.max(np.abs(want[:, 8] - ref[1000:, 8])) > 0.05 * np.max(np.abs(want[:, 8]))


def test_noise_is_seeded_with_the_std_of_each_channel_kind():
    noise = SensorNoise(0.05, 0.5, 2e-4)
    a, b = HalfCar(P, noise, noise_seed=7), HalfCar(P, noise, noise_seed=7)
    rest, steps, _ = case("bump")
    for car in (a, b):
        car.settle(*rest)
    e = []
    for qf, qr, ff, fr in np.tile(steps, (3, 1)):
        for car in (a, b):
            car.step(qf, qr, H, force_front=ff, force_rear=fr)
        assert a.measured == b.measured
        e.append(np.subtract(a.measured, [*a.acc_true, *a.deflection_true]))
    std = np.std(e, axis=0) / [0.05, 0.05, 0.5, 0.5, 2e-4, 2e-4]
    assert np.allclose(std, 1.0, atol=0.03), std
    assert np.max(np.abs(np.corrcoef(np.array(e).T) - np.eye(6))) < 0.05


# --- HalfCar.fmu --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["bump", "iso_d"])
def test_fmu_matches_dop853_within_a_tenth_of_a_percent_of_the_peak(driven, name):
    rest, steps, ref = case(name)
    d = driven("HalfCar", **QUIET, road_height_front=rest[0], road_height_rear=rest[1])
    got = run_fmu(d, steps)
    sf, sr = static_loads(P)
    got[:, -2:] -= [sf, sr]
    err = errors(got, ref)
    assert max(err.values()) < TOLERANCE, err
    assert not d.messages


def test_fmu_on_isoroad_with_a_wheelbase_matches_dop853(driven):
    """The road FMU feeds both tyres: road_height_rear a wheelbase behind road_height."""
    rest, steps, ref = case("iso_d")
    road = driven("ISORoad", road_class=4, seed=3, wheelbase=P.wheelbase)
    q = np.vstack([[road.get("road_height"), road.get("road_height_rear")],
                   road.run(H, len(steps), ["road_height", "road_height_rear"], vehicle_speed=SPEED)])
    assert np.max(np.abs(q[:, 0] - np.r_[rest[0], steps[:, 0]])) < 1e-9
    assert np.max(np.abs(q[:, 1] - np.r_[rest[1], steps[:, 1]])) < 1e-9
    d = driven("HalfCar", **QUIET, road_height_front=q[0, 0], road_height_rear=q[0, 1])
    got = run_fmu(d, np.column_stack([q[1:], np.zeros((len(steps), 2))]))
    got[:, -2:] -= static_loads(P)
    err = errors(got, ref)
    assert max(err.values()) < TOLERANCE, err


def test_fmu_at_rest_reads_static_loads_and_zero_deflections(driven):
    d = driven("HalfCar", **QUIET, road_height_front=250.0, road_height_rear=250.0)
    out = run_fmu(d, np.tile([250.0, 250.0, 0.0, 0.0], (50, 1)),
                  outputs=["susp_deflection_front", "susp_deflection_rear", "acc_body_front", "acc_body_rear",
                           "tire_force_front", "tire_force_rear", "heave", "pitch"])
    assert np.array_equal(out[:, :4], np.zeros((50, 4)))
    assert np.allclose(out[:, 4:6], static_loads(P), rtol=1e-15)
    assert np.allclose(out[:, 6], 250.0, rtol=1e-15, atol=0.0) and np.array_equal(out[:, 7], np.zeros(50))
    assert d.get("tire_contact_front") == 1 and d.get("tire_contact_rear") == 1


# --- bad input (issue point 6) --------------------------------------------------------------
@pytest.mark.parametrize("params, name", [
    ({"m_uf": 0.0}, "m_uf"), ({"m_ur": -39.0}, "m_ur"), ({"pitch_inertia": 0.0}, "pitch_inertia"),
    ({"pitch_inertia": -968.0}, "pitch_inertia"), ({"k_f": 0.0}, "k_f"), ({"k_r": -17000.0}, "k_r"),
    ({"k_tf": 0.0}, "k_tf"), ({"k_tr": math.nan}, "k_tr"), ({"c_f": -1.0}, "c_f"), ({"c_r": -2000.0}, "c_r"),
    ({"l_f": -0.5}, "l_f"), ({"l_r": math.inf}, "l_r"), ({"sprung_mass": 0.0}, "sprung_mass"),
])
def test_unphysical_parameters_are_refused_naming_the_variable_and_its_range(driven, params, name):
    d = driven("HalfCar", **params)
    assert any(s == 3 and name in m and "range" in m for s, m in d.messages), d.messages
    with pytest.raises(FMICallException, match="discard"):
        d.step(H)


def test_a_zero_wheelbase_is_refused_naming_both_lengths(driven):
    d = driven("HalfCar", l_f=0.0, l_r=0.0)
    assert any(s == 3 and "l_f + l_r" in m and "positive" in m for s, m in d.messages), d.messages
    with pytest.raises(FMICallException, match="discard"):
        d.step(H)


def test_the_papers_car_without_dampers_is_accepted(driven):
    d = driven("HalfCar", c_f=0.0, c_r=0.0, **QUIET)
    rest, steps, _ = case("bump")
    out = run_fmu(d, steps[:500], outputs=["heave", "pitch"])
    assert np.all(np.isfinite(out)) and np.max(np.abs(out)) > 1e-3 and not d.messages


ALL_REALS = OUT + ["acc_body_front", "acc_body_rear", "acc_unsprung_front", "acc_unsprung_rear",
                   "susp_deflection_front", "susp_deflection_rear"]


def run_with_contact(d, steps, h: float = H) -> tuple[np.ndarray, np.ndarray]:
    """(every Real output in ALL_REALS, [tire_contact_front, tire_contact_rear]) after each step."""
    reals, contact = [], []
    for u in steps:
        d.step(h, **dict(zip(INPUTS, map(float, u))))
        reals.append([d.get(o) for o in ALL_REALS])
        contact.append([d.get("tire_contact_front"), d.get("tire_contact_rear")])
    return np.array(reals), np.array(contact)


@pytest.mark.parametrize("c", [0.0, 2000.0])
@pytest.mark.parametrize("h", [1e-3, 1.0, 1e6])
def test_saturated_actuator_forces_lift_the_wheels_and_every_output_stays_finite(driven, c, h):
    """The actuators at the ends of their range (+-1e6 N), switching: the linear tyres pull (the
    wheels would lift) while the car swings, the outputs stay finite, undamped (the paper's car) or
    not, at any step (over a step of 1e6 s the damped car reaches its equilibrium, where internal
    forces leave the tyre loads static)."""
    d = driven("HalfCar", c_f=c, c_r=c)
    n = 200
    sign = np.where(np.arange(n) // 37 % 2, 1.0, -1.0)
    reals, contact = run_with_contact(d, np.column_stack([np.zeros(n), np.zeros(n), 1e6 * sign, -1e6 * sign]), h)
    assert np.all(np.isfinite(reals))
    tyres = reals[:, [ALL_REALS.index("tire_force_front"), ALL_REALS.index("tire_force_rear")]]
    assert np.array_equal(contact == 0, tyres <= 0)
    assert np.any(contact == 0) or (c > 0 and h == 1e6)
    assert not [m for s, m in d.messages if s >= 2]


def test_a_wheel_lifted_by_a_drop_in_the_road_reports_a_pulling_tyre(driven):
    d = driven("HalfCar", **QUIET)
    reals, contact = run_with_contact(d, np.tile([-0.2, 0.0, 0.0, 0.0], (300, 1)))  # a 0.2 m drop at the front
    assert np.all(np.isfinite(reals))
    front = reals[:, ALL_REALS.index("tire_force_front")]
    assert front[0] < 0 and list(contact[0]) == [0, 1]  # the linear tyre pulls the wheel down at once
    assert np.array_equal(contact[:, 0] == 0, front <= 0) and contact[-1, 0] == 1  # and lands again


@pytest.mark.parametrize("value", [2e6, -1e7, math.inf, math.nan])
def test_a_force_beyond_the_actuator_range_is_refused_at_its_step_only(driven, value):
    d = driven("HalfCar")
    d.step(H, force_front=100.0)
    before = d.get("heave")
    with pytest.raises(FMICallException, match="discard"):
        d.step(H, force_front=value)
    assert any("force_front" in m and "[-1e+06, 1e+06]" in m for _, m in d.messages), d.messages
    assert d.get("heave") == before
    d.step(H, force_front=100.0)  # the next step with a valid force goes on
    assert math.isfinite(d.get("heave")) and d.get("heave") != before


@pytest.mark.parametrize("h", [math.inf, math.nan, 0.0, -1e-3])
def test_a_step_that_is_not_finite_and_positive_is_refused_at_that_step_only(driven, h):
    d = driven("HalfCar")
    d.step(H, force_front=100.0)
    before = d.get("heave")
    with pytest.raises(FMICallException, match="discard"):
        d.fmu.doStep(currentCommunicationPoint=d.t, communicationStepSize=h)
    assert any("communication step size" in m and "(0, inf)" in m for _, m in d.messages), d.messages
    assert d.get("heave") == before
    d.step(H, force_front=100.0)
    assert math.isfinite(d.get("heave")) and d.get("heave") != before
