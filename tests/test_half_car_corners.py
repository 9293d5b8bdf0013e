"""The quarter-car estimator on the corners of the half car (benchmarks/half_car_corners.py; the
60 s grid and its explanation: docs/half-car.md, "The quarter-car estimator on a corner")."""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from conftest import ROOT
from suspension_estimation.plant.half_car import DEFAULT_HALF_CAR, HalfCar
from suspension_estimation.plant.quarter_car import SensorNoise

spec = importlib.util.spec_from_file_location("half_car_corners", ROOT / "benchmarks" / "half_car_corners.py")
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)

SPEEDS = (40 / 3.6, 80 / 3.6)  # m/s
F = np.array([0.1, 0.5, 1.0, 1.3, 2.0, 5.0, 11.4, 30.0])  # Hz


@pytest.fixture(scope="module")
def iso_c_40():
    """Per corner (HP % half car, HP % quarter car, mass % half car, mass % quarter car, coverage
    half car, coverage quarter car): ISO C, 40 km/h, seed 1, 20 s (scored after 10 s)."""
    return bench.cell(DEFAULT_HALF_CAR, 3, SPEEDS[0], 20.0, range(1, 2))


@pytest.mark.parametrize("corner", bench.CORNERS)
def test_the_estimator_on_a_corner_is_near_its_quarter_car_figure(iso_c_40, corner):
    hp_half, hp_quarter, mass_half, mass_quarter = iso_c_40[corner][:4]
    assert np.isfinite([hp_half, hp_quarter, mass_half, mass_quarter]).all()
    # 60 s, 3 seeds: 1.7-1.8 % on the quarter car; on the half car 1.9x (front), 2.3x (rear)
    assert hp_quarter < 3.5
    assert hp_half < 3.5 * hp_quarter, iso_c_40
    assert abs(mass_quarter) < 1.0
    # the mass estimate is the apparent mass near the body modes, below the corner load
    assert -25.0 < mass_half < -2.0, iso_c_40


@pytest.mark.parametrize("corner", bench.CORNERS)
@pytest.mark.parametrize("speed", SPEEDS)
def test_the_apparent_mass_is_the_corner_load_at_dynamic_index_1(corner, speed):
    """I = m l_f l_r: the other axle's force does not reach the body point above this one."""
    p = DEFAULT_HALF_CAR.with_(pitch_inertia=DEFAULT_HALF_CAR.m_s * DEFAULT_HALF_CAR.l_f * DEFAULT_HALF_CAR.l_r)
    assert bench.dynamic_index(p) == pytest.approx(1.0, rel=1e-15)
    m = bench.apparent_mass(p, F, speed, corner)
    np.testing.assert_allclose(m, bench.corner_load(p, corner), rtol=1e-9)
    # the defaults (dynamic index 0.82): it moves with the frequency, by more than 5 %
    m = bench.apparent_mass(DEFAULT_HALF_CAR, F, speed, corner)
    assert np.ptp(np.abs(m)) > 0.05 * bench.corner_load(DEFAULT_HALF_CAR, corner)


def test_at_dynamic_index_1_each_corner_is_a_quarter_car_in_time():
    """The plant itself, on a road, with I = m l_f l_r: the suspension force at each axle is the
    corner load times the body acceleration above it (the accelerations as the plant outputs
    them, at the end of each step), to rounding; at the defaults it is not."""
    base = DEFAULT_HALF_CAR
    for p, coupled in ((base.with_(pitch_inertia=base.m_s * base.l_f * base.l_r), False), (base, True)):
        car = HalfCar(p, SensorNoise(0.0, 0.0, 0.0))
        t = np.arange(1, 3001) * 1e-3
        res = []
        for tk in t:
            car.step(0.01 * np.sin(2 * np.pi * 1.2 * tk), 0.01 * np.sin(2 * np.pi * 1.2 * (tk - 0.2)), 1e-3)
            z, th, zf, zr, vz, vth, vf, vr = car.x.tolist()
            f_front = p.k_f * (zf - z - p.l_f * th) + p.c_f * (vf - vz - p.l_f * vth)
            f_rear = p.k_r * (zr - z + p.l_r * th) + p.c_r * (vr - vz + p.l_r * vth)
            res.append((f_front, f_rear, *car.acc_true[:2]))
        f_front, f_rear, a_front, a_rear = np.array(res).T
        err = max(np.max(np.abs(f_front - bench.corner_load(p, "front") * a_front)) / np.max(np.abs(f_front)),
                  np.max(np.abs(f_rear - bench.corner_load(p, "rear") * a_rear)) / np.max(np.abs(f_rear)))
        assert (err > 0.05) if coupled else (err < 1e-9), (coupled, err)


@pytest.mark.parametrize("corner", bench.CORNERS)
def test_pitch_coupling_alone_puts_the_1_3x_target_out_of_reach_of_any_fixed_mass(iso_c_40, corner):
    """The issue's target (HP within 1.3x the quarter car's figure) leaves the coupling at most
    sqrt(1.3^2 - 1) = 0.83 of that figure, added in quadrature. On this car (dynamic index 0.82) the
    coupling's error at the best fixed mass exceeds it at both speeds: no quarter-car model of the
    corner can meet the target, however well tuned; at dynamic index 0.95 it stays below it."""
    hp_quarter = iso_c_40[corner][1]
    allowed = np.sqrt(1.3 ** 2 - 1) * hp_quarter
    P = DEFAULT_HALF_CAR
    for speed in SPEEDS:
        best = bench.coupling_error(P, speed, corner)[1]
        assert bench.coupling_error(P, speed, corner, best)[0] > allowed, (speed, allowed)
        p = P.with_(pitch_inertia=0.95 * P.m_s * P.l_f * P.l_r)
        best = bench.coupling_error(p, speed, corner)[1]
        assert bench.coupling_error(p, speed, corner, best)[0] < allowed, (speed, allowed)


@pytest.fixture(scope="module")
def iso_b_40():
    """As iso_c_40 on ISO B (half ISO C's amplitude, the same seed)."""
    return bench.cell(DEFAULT_HALF_CAR, 2, SPEEDS[0], 20.0, range(1, 2))


def test_the_corners_excess_on_iso_b_is_the_sensor_noise_against_a_smaller_road(iso_c_40, iso_b_40):
    """The plants are linear in the road and the sensor noise together: ISO B with HalfCar's noise
    is ISO C with twice that noise, scaled by 1/2. The corner's error on ISO B is that of ISO C seen
    through twice the noise (within 15 %; the estimator's class-scheduled road noise is not
    linear), several times ISO C's: the filter leans more on its model, which the pitch coupling
    makes wrong, when the road is small against the noise. The quarter car, whose model is right,
    loses little (measured, seed 1, 40 s: corner 15.3 / 21.6 % on B, 14.6 / 21.2 % on C with twice
    the noise, 4.0 / 4.6 % on C; quarter car 2.3 / 2.1 % on B)."""
    c2 = bench.cell(DEFAULT_HALF_CAR, 3, SPEEDS[0], 20.0, range(1, 2), noise=2.0)
    for corner in bench.CORNERS:
        assert c2[corner][0] == pytest.approx(iso_b_40[corner][0], rel=0.15), (c2, iso_b_40)
        assert iso_b_40[corner][0] > 2.0 * iso_c_40[corner][0]
        assert iso_b_40[corner][1] < 1.5 * iso_c_40[corner][1]


def test_told_half_the_noise_the_corner_on_iso_b_is_near_its_iso_c_figure(iso_b_40):
    """What a user of a coupled car can do: tell the estimator half its sensors' noise. On ISO B
    the corner's error falls several times and +-2 road_height_std still covers it; the quarter
    car's is not worse (measured, seed 1, 40 s: 15.3 / 21.6 -> 3.8 / 4.0 %, coverage 0.63 / 0.76
    -> 1.00; quarter car 2.3 / 2.1 -> 2.3 / 2.1 %)."""
    told = bench.cell(DEFAULT_HALF_CAR, 2, SPEEDS[0], 20.0, range(1, 2), told=0.5)
    for corner in bench.CORNERS:
        assert told[corner][0] < 0.5 * iso_b_40[corner][0], (told, iso_b_40)
        assert told[corner][1] < 1.2 * iso_b_40[corner][1]
        assert told[corner][4] > 0.9
