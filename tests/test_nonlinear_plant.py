"""The nonlinear quarter car (air spring, asymmetric damper, stops, contact loss): core and FMU.

The reference is scipy's DOP853 on equations written here from the public force laws of
plant/suspension_forces.py (not from the plant's inlined right-hand side), the road held over each
communication step as the plant holds it.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from fmpy.fmi1 import FMICallException
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
from suspension_estimation.plant.quarter_car import LINEAR, QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.suspension_forces import (DEFAULT_AIR_SPRING, DEFAULT_BUMP_STOPS, DEFAULT_DAMPER, G, P_ATM,
                                     BumpStops, tyre_force)
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

V = DEFAULT_VEHICLE
QUIET = SensorNoise(0.0, 0.0, 0.0)
QUIET_FMU = {"acc_sprung_noise_std": 0.0, "acc_unsprung_noise_std": 0.0, "defl_noise_std": 0.0}
NONLINEAR = {"spring_model": 1, "damper_model": 1}


def car(**kw) -> NonlinearQuarterCar:
    args = {"spring": DEFAULT_AIR_SPRING, "damper": DEFAULT_DAMPER, "noise": QUIET, **kw}
    return NonlinearQuarterCar(V, **args)


def bump(h: float, height: float, t_end: float = 2.0) -> np.ndarray:
    """A (1 - cos) bump of ``height`` m lasting 0.1 s at t = 0.3 s, sampled at the step ends."""
    t = (np.arange(int(round(t_end / h))) + 1) * h
    return np.where((t > 0.3) & (t < 0.4), 0.5 * height * (1 - np.cos(2 * np.pi * (t - 0.3) / 0.1)), 0.0)


def iso_d(h: float, t_end: float = 3.0, kmh: float = 80.0) -> np.ndarray:
    road = SyntheticRoad(iso8608.class_psd_n0(4), seed=7)
    s = (np.arange(int(round(t_end / h))) + 1) * h * kmh / 3.6
    return np.array([road.height(x) for x in s]) - road.height(0.0)


def reference(road: np.ndarray, h: float, m_s: float = V.m_s, stops: BumpStops = DEFAULT_BUMP_STOPS,
              linear: bool = False):
    """DOP853 (rtol 1e-10) step by step: states, end-of-step accelerations, damper work; the road
    held over each step, or (``linear``) moving linearly from the last input to this one."""
    load = (m_s + V.m_u) * G

    def rhs(t, y, r, r0=None):
        if r0 is not None:
            r = r0 + (r - r0) * t / h
        z_s, v_s, z_u, v_u, _ = y
        d = z_u - z_s
        f_s = DEFAULT_AIR_SPRING.force(d, m_s) + stops.force(d)
        f_d = DEFAULT_DAMPER.force(v_s - v_u)
        f_t = tyre_force(V.k_t, r, z_u, load)
        return [v_s, (f_s - f_d) / m_s, v_u, (f_d - f_s + f_t) / V.m_u, f_d * (v_s - v_u)]

    y = np.zeros(5)
    out = np.empty((len(road), 7))
    r0 = 0.0
    for k, r in enumerate(road):
        y = solve_ivp(rhs, (0.0, h), y, method="DOP853", rtol=1e-10, atol=1e-14,
                      args=(r, r0 if linear else None)).y[:, -1]
        r0 = r
        f = rhs(0.0, y, r)
        out[k] = [*y[:4], f[1], f[3], y[4]]
    return out


def run_core(p: NonlinearQuarterCar, road: np.ndarray, h: float, m_s=None) -> np.ndarray:
    out = np.empty((len(road), 7))
    for k, r in enumerate(road):
        p.step(r, h, m_s)
        out[k] = [*p.x, *p.acc_true, p.dissipated]
    return out


def peak_error(got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """max |got - ref| over time as a fraction of max |ref|, per column."""
    return np.max(np.abs(got - ref), axis=0) / np.max(np.abs(ref), axis=0)


@pytest.mark.parametrize("h", [0.001, 0.01])
@pytest.mark.parametrize("make_road", [lambda h: bump(h, 0.06), iso_d], ids=["bump", "iso_d"])
def test_core_matches_dop853_within_a_tenth_of_a_percent_of_the_peak(h, make_road):
    road = make_road(h)
    p = car()
    p.settle(0.0)
    got = run_core(p, road, h)
    ref = reference(road, h)
    err = peak_error(got[:, :6], ref[:, :6])
    assert np.all(err < 1e-3), dict(zip(["z_s", "v_s", "z_u", "v_u", "a_s", "a_u"], err))
    # acc_sampling 1: the accelerations averaged over the step, (v[k+1] - v[k]) / h
    avg = car(acc_sampling=1)
    avg.settle(0.0)
    ref_avg = np.diff(np.vstack([np.zeros(2), ref[:, [1, 3]]]), axis=0) / h
    assert np.all(peak_error(run_core(avg, road, h)[:, 4:6], ref_avg) < 1e-3)
    # the run is nonlinear: it goes past the damper's knees (0.3 m/s) and the tyre leaves the road
    assert np.max(np.abs(ref[:, 1] - ref[:, 3])) > 0.45
    assert np.any(V.k_t * (road - ref[:, 2]) < -(V.m_s + V.m_u) * G)


@pytest.mark.parametrize("h, make_road", [(0.001, lambda h: bump(h, 0.06)), (0.01, iso_d)], ids=["bump 1 ms", "iso_d 10 ms"])
def test_core_with_the_road_moving_linearly_matches_dop853(h, make_road):
    """road_input LINEAR: the road under the tyre moves linearly from the last input to this one
    over the step; the RK4 substeps against DOP853 on the same road."""
    road = make_road(h)
    p = car(road_input=LINEAR)
    p.settle(0.0)
    got = run_core(p, road, h)[:, :6]
    err = peak_error(got, reference(road, h, linear=True)[:, :6])
    assert np.all(err < 1e-3), dict(zip(["z_s", "v_s", "z_u", "v_u", "a_s", "a_u"], err))
    # ... which is not the held road's: the accelerations differ by 6-47 % of their peak
    assert np.max(peak_error(got, reference(road, h)[:, :6])) > 0.05


def energy_balance(road: np.ndarray, h: float, tyre_pulls: bool = False) -> dict:
    """Run the default car over ``road`` and account for its energy (J).

    Kinetic + air-spring + stop + tyre energy changes by the work of the road minus the damper's.
    With the road held over a step, the road does its work at the step boundaries, where it moves
    under the tyre and changes the tyre's stored energy at fixed z_u. ``tyre_pulls`` accounts the
    tyre as a linear spring (a wrong account once it leaves the road: how much that shows)."""
    m_s = V.m_s
    load = (m_s + V.m_u) * G

    def tyre_energy(e):  # integral of the dynamic tyre force over its compression e = z_r - z_u
        e0 = -math.inf if tyre_pulls else -load / V.k_t
        return 0.5 * V.k_t * e * e if e >= e0 else 0.5 * V.k_t * e0 * e0 - load * (e - e0)

    def energy(x, r):
        z_s, v_s, z_u, v_u = x
        d = z_u - z_s
        return (0.5 * m_s * v_s ** 2 + 0.5 * V.m_u * v_u ** 2 + DEFAULT_AIR_SPRING.energy(d, m_s)
                + DEFAULT_BUMP_STOPS.energy(d) + tyre_energy(r - z_u))

    p = car()
    p.settle(0.0)
    e, road_work, lost = [], 0.0, 0
    r_prev = 0.0
    for r in road:
        road_work += tyre_energy(r - p.x[2]) - tyre_energy(r_prev - p.x[2])
        p.step(r, h)
        e.append(energy(p.x, r))
        r_prev = r
        lost += 1 - p.tire_contact
    return {"road_work": road_work, "dissipated": p.dissipated, "final": e[-1], "peak": max(e),
            "residual": e[-1] - (road_work - p.dissipated), "steps_off_road": lost}


def test_energy_balance_over_iso_d():
    b = energy_balance(iso_d(0.001, 4.0, kmh=100.0), 0.001)
    assert b["steps_off_road"] > 0  # the tyre left the road: the clipped tyre force is in the balance
    assert b["dissipated"] > 10 * b["peak"]  # the damper matters in it
    # RK4's error, falling with the substep; an account without the contact loss is 57 J off
    # (benchmarks/nonlinear_plant.py)
    assert abs(b["residual"]) < 1e-5 * b["dissipated"], b


def test_air_spring_matches_the_paper_law_and_its_linearisation():
    s = DEFAULT_AIR_SPRING
    for m_s in (200.0, 410.0, 900.0):
        p_0 = s.static_pressure(m_s)

        def total(delta):  # paper 003: F = A_e [p_0 (V_0 / (V_0 - A_e delta))^kappa - p_atm]
            return s.air_area * (p_0 * (s.air_volume / (s.air_volume - s.air_area * delta)) ** s.air_kappa - P_ATM)

        assert total(0.0) == pytest.approx(m_s * G, rel=1e-12)  # carries the load at the static point
        for d in (-0.05, 0.02, 0.08):
            assert s.force(d, m_s) == pytest.approx(total(d) - m_s * G, rel=1e-9)
            assert s.energy(d, m_s) == pytest.approx(quad(lambda x: s.force(x, m_s), 0.0, d, epsabs=0)[0], rel=1e-9)
        eps = 1e-6
        fd = (s.force(eps, m_s) - s.force(-eps, m_s)) / (2 * eps)
        assert s.stiffness(m_s) == pytest.approx(fd, rel=1e-8)
    # the defaults linearise to the contract's linear defaults at the default sprung mass (area and
    # volume rounded to the contract's 6 digits)
    assert s.stiffness(V.m_s) == pytest.approx(V.k_s, rel=1e-5)
    assert DEFAULT_DAMPER.damping() == pytest.approx(V.c_s, rel=1e-12)
    assert p_0 < s.air_pressure_max


def test_damper_equivalent_is_the_first_harmonic_of_a_small_motion():
    amp, omega = 0.2, 2 * np.pi * 1.5  # m/s peak, inside both knees
    c_eq = quad(lambda t: DEFAULT_DAMPER.force(amp * math.sin(omega * t)) * math.sin(omega * t), 0, 2 * np.pi / omega,
                points=[np.pi / omega], epsabs=0)[0] * omega / (np.pi * amp)
    assert c_eq == pytest.approx(DEFAULT_DAMPER.damping(), rel=1e-9)
    assert DEFAULT_DAMPER.damper_c_rebound > DEFAULT_DAMPER.damper_c_compression  # asymmetric


@pytest.mark.parametrize("m_s", [300.0, 410.0, 700.0])
def test_small_motion_follows_the_linearised_vehicle(m_s):
    """Air spring alone, 0.2 mm of road: the nonlinear car moves like the linear plant built from
    ``linearisation(m_s)`` (differences of second order in the amplitude)."""
    h, n = 0.001, 3000
    t = (np.arange(n) + 1) * h
    road = 2e-4 * np.sin(2 * np.pi * (0.5 + 3 * t) * t)
    p = car(damper=None)
    p.settle(0.0)
    got = run_core(p, road, h, m_s)
    def linear_run(vehicle):
        lin = QuarterCar(vehicle, QUIET)
        lin.settle(0.0)
        return np.array([(lin.step(r, h), lin.x.copy())[1] for r in road])

    assert np.all(peak_error(got[:, :4], linear_run(p.linearisation(m_s))) < 2e-3)
    # off the default load the air spring is not the default k_s: the levelled pressure stiffens it
    if m_s != V.m_s:
        assert np.max(peak_error(got[:, :4], linear_run(V.with_(m_s=m_s)))) > 0.1


def test_at_rest_it_stays_at_rest_when_the_load_changes():
    """Static equilibrium with gravity: no motion on a level road, also after a payload change
    (the levelling valve keeps the ride height)."""
    p = car()
    p.settle(0.05)
    for k in range(2000):
        p.step(0.05, 0.001, 410.0 if k < 1000 else 650.0)
        assert np.allclose(p.x, [0.05, 0.0, 0.05, 0.0], rtol=0, atol=1e-15)
        assert p.acc_true == (0.0, 0.0) and p.tire_contact == 1 and p.bump_stop == 0


def test_noise_is_drawn_like_the_linear_plant():
    noise = SensorNoise()
    a, b = car(noise=noise, noise_seed=5), QuarterCar(V, noise, noise_seed=5)
    for p in (a, b):
        p.settle(0.0)
    ea, eb = [], []
    for r in bump(0.001, 0.02, 1.0):
        for p, e in ((a, ea), (b, eb)):
            p.step(r, 0.001)
            e.append(np.subtract(p.measured, [*p.acc_true, p.x[0] - p.x[2]]))
    assert np.allclose(ea, eb, rtol=0, atol=1e-12)


# -- through the built FMU ---------------------------------------------------------------------
OUT = ["z_s", "v_s", "z_u", "v_u", "acc_sprung_true", "acc_unsprung_true"]


def drive(p, road: np.ndarray, h: float, outputs: list[str]) -> np.ndarray:
    out = np.empty((len(road), len(outputs)))
    for k, r in enumerate(road):
        p.step(h, road_height=r)
        out[k] = [p.get(o) for o in outputs]
    return out


def test_fmu_runs_the_nonlinear_plant(driven):
    h = 0.01
    road = bump(h, 0.06)
    got = drive(driven("QuarterCar", **NONLINEAR, **QUIET_FMU), road, h, OUT)
    assert np.all(peak_error(got, reference(road, h)[:, :6]) < 1e-3)
    # and it is not the linear plant
    lin = drive(driven("QuarterCar", **QUIET_FMU), road, h, OUT)
    assert np.max(np.abs(lin[:, 0] - got[:, 0])) > 0.05 * np.max(np.abs(lin[:, 0]))


def test_contact_loss_and_a_bump_stop_hit_stay_finite_and_flagged(driven):
    h = 0.001
    road = bump(h, 0.2, 1.5)  # 0.2 m in 0.1 s: the wheel is thrown off the road and the stop is hit
    p = driven("QuarterCar", **NONLINEAR)
    names = [*OUT, "tire_force", "acc_sprung", "susp_deflection"]
    out = np.empty((len(road), len(names) + 2))
    for k, r in enumerate(road):
        p.step(h, road_height=r)
        out[k] = [*(p.get(o) for o in names), p.get("tire_contact"), p.get("bump_stop")]
    assert np.all(np.isfinite(out))
    contact, stop = out[:, -2], out[:, -1]
    assert set(contact) == {0, 1} and 1 in stop
    load = (V.m_s + V.m_u) * G
    assert np.all(out[:, names.index("tire_force")] >= -load - 1e-9)
    # while off the road the wheel is in free fall under the suspension force only
    assert np.any(out[contact == 0, names.index("tire_force")] == -load)
    # the linear plant's tyre pulls on the road through the same bump, and says so
    lin = driven("QuarterCar")
    flags = [lin.step(h, road_height=r) or lin.get("tire_contact") for r in road]
    assert 0 in flags


def test_a_road_through_the_stops_is_refused_not_garbage(driven):
    """Without stops a 1 m road step drives the suspension to the end of the air spring's stroke
    (V_0/A_e = 0.34 m): the FMU stops with the reason, and never reports a non-finite output."""
    p = driven("QuarterCar", **NONLINEAR, bump_stop_stiffness=0.0)
    values = []
    with pytest.raises(FMICallException, match="discard"):
        for _ in range(300):
            p.step(0.001, road_height=1.0)
            values += [p.get(o) for o in [*OUT, "tire_force", "acc_sprung"]]
    assert any(st == 3 and "air_volume/air_area" in m for st, m in p.messages), p.messages
    assert len(values) > 0 and np.all(np.isfinite(values))


@pytest.mark.parametrize("params, name", [
    ({"air_area": 0.0}, "air_area"), ({"air_volume": -1e-3}, "air_volume"),
    ({"air_pressure_max": 0.0}, "air_pressure_max"), ({"air_kappa": 0.9}, "air_kappa"), ({"air_kappa": 1.5}, "air_kappa"),
    ({"damper_c_rebound": 0.0}, "damper_c_rebound"), ({"damper_c_compression_high": -100.0}, "damper_c_compression_high"),
    ({"damper_knee_rebound": 0.0}, "damper_knee_rebound"), ({"bump_stop_gap": float("nan")}, "bump_stop_gap"),
    ({"damper_model": 2}, "damper_model"),
])
def test_unphysical_parameter_is_refused_naming_it_and_its_range(driven, params, name):
    p = driven("QuarterCar", **{**NONLINEAR, **params})
    assert any(st == 3 and name in m and "allowed range" in m for st, m in p.messages), p.messages
    with pytest.raises(FMICallException, match="discard"):
        p.step(0.001)


def test_a_load_the_air_spring_cannot_carry_is_refused(driven):
    m_max = DEFAULT_AIR_SPRING.max_sprung_mass()
    p = driven("QuarterCar", spring_model=1, sprung_mass=1.1 * m_max)
    assert any(st == 3 and "sprung_mass" in m and "air_pressure_max" in m for st, m in p.messages), p.messages
    with pytest.raises(FMICallException, match="discard"):
        p.step(0.001)
    # and a payload beyond it during a run is refused at that step
    q = driven("QuarterCar", spring_model=1)
    q.step(0.001, sprung_mass=0.9 * m_max)
    with pytest.raises(FMICallException, match="discard"):
        q.step(0.001, sprung_mass=1.1 * m_max)
    assert any(st == 3 and "sprung_mass" in m for st, m in q.messages), q.messages


def test_fmu_state_of_the_nonlinear_plant_replays_bit_identically(driven):
    p = driven("QuarterCar", **NONLINEAR)
    road = bump(0.001, 0.15, 1.0)  # with contact loss and noise
    drive(p, road[:300], 0.001, OUT)
    state, t = p.fmu.getFMUstate(), p.t
    first = drive(p, road[300:], 0.001, [*OUT, "acc_sprung", "tire_contact"])
    p.fmu.setFMUstate(state)
    p.t = t
    assert np.array_equal(drive(p, road[300:], 0.001, [*OUT, "acc_sprung", "tire_contact"]), first)
