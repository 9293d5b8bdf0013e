"""The profile in a distance band (plant/profile_band.py, harness.metrics.reference_profile and
road_scores): the filter against an independent solver, its gains, its independence of the
sampling and of the speed, and a stop."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lsim

from suspension_estimation.harness.metrics import reference_profile, road_scores
from suspension_estimation.plant.profile_band import PROFILE_CUTOFF, DistanceHighpass, band_response, highpass_profile


def test_matches_an_independent_solver():
    """Uniform spacing: scipy's lsim of s^3 / ((s + w) (s^2 + w s + w^2)) with linear
    interpolation between samples, on a rough profile with a level and a grade."""
    rng = np.random.default_rng(3)
    s = np.arange(0.0, 1500.0, 0.25)
    z = 0.3 + 0.004 * s + np.cumsum(rng.standard_normal(len(s))) * 1e-3
    w = 2 * np.pi / PROFILE_CUTOFF
    _, ref, _ = lsim(([1.0, 0.0, 0.0, 0.0], [1.0, 2 * w, 2 * w * w, w ** 3]), z - z[0], s)
    assert np.abs(highpass_profile(s, z) - ref).max() < 1e-12


@pytest.mark.parametrize("wavelength, gain", [(PROFILE_CUTOFF, 1 / np.sqrt(2)), (10.0, 1.0),
                                              (1000.0, (PROFILE_CUTOFF / 1000.0) ** 3)])
def test_gain_of_a_sine(wavelength, gain):
    """Butterworth: 1/sqrt(2) at the cut-off, ~1 well inside the band, (cutoff / wavelength)^3 far below."""
    s = np.arange(0.0, 30 * max(wavelength, PROFILE_CUTOFF), min(wavelength / 50, 0.5))
    y = highpass_profile(s, np.sin(2 * np.pi * s / wavelength))
    late = s > 0.5 * s[-1]
    assert np.sqrt(2) * y[late].std() == pytest.approx(gain, rel=0.02, abs=1e-4)
    assert abs(band_response(1 / wavelength)) == pytest.approx(gain, rel=0.02, abs=1e-4)


def test_the_same_at_any_spacing_and_speed():
    """A profile linear between points 0.5 m apart gives the same band profile (to rounding)
    sampled at those points, 10x finer, or at the uneven points a car at a varying speed passes."""
    rng = np.random.default_rng(5)
    knots = np.arange(0.0, 600.0, 0.5)
    kz = np.cumsum(rng.standard_normal(len(knots))) * 2e-3
    coarse = highpass_profile(knots, kz)
    fine_s = np.arange(0.0, 600.0 - 0.5 + 1e-9, 0.05)
    fine = highpass_profile(fine_s, np.interp(fine_s, knots, kz))
    assert np.abs(fine[::10] - coarse[: len(fine[::10])]).max() < 1e-9
    speed = 5.0 + 4.0 * np.sin(np.arange(20000) * 1e-3)  # m/s, 1 ms steps
    car_s = np.concatenate(([0.0], np.cumsum(speed * 1e-3)))
    car_s = np.union1d(car_s[car_s < 590.0], knots[knots < 590.0])  # it passes every knot too
    car = highpass_profile(car_s, np.interp(car_s, knots, kz))
    at_knots = np.isin(car_s, knots)
    assert np.abs(car[at_knots] - coarse[: at_knots.sum()]).max() < 1e-9


def test_level_grade_and_vertical_curve_give_nothing():
    """A level, a 6 % grade and a sag curve of radius 2000 m: a transient from rest, then nothing
    (a second-order high-pass would leave the curve as a constant offset of cutoff^2 / (4 pi^2 R),
    106 mm here). Linear between points 0.1 m apart, the curve is off by its chord's k ds^2 / 12."""
    s = np.arange(0.0, 3000.0, 0.1)
    y = highpass_profile(s, 583.0 + 0.06 * s + 0.5 * s * s / 2000.0)
    assert np.abs(y).max() < 0.06 * PROFILE_CUTOFF
    assert np.abs(y[s > 1500]).max() < 1e-6


def test_a_stop_changes_nothing():
    """Standing (distance repeated, the same height) holds the output; the profile after the stop
    is the one without it."""
    s = np.arange(0.0, 400.0, 0.1)
    z = 0.01 * np.sin(2 * np.pi * s / 17.0)
    stop = 2000
    s_stop = np.concatenate((s[:stop], np.full(500, s[stop - 1]), s[stop:]))
    z_stop = np.concatenate((z[:stop], np.full(500, z[stop - 1]), z[stop:]))
    y, y_stop = highpass_profile(s, z), highpass_profile(s_stop, z_stop)
    assert np.all(y_stop[stop - 1:stop + 500] == y[stop - 1])
    assert np.abs(y_stop[stop + 500:] - y[stop:]).max() < 1e-12


def test_bad_input():
    with pytest.raises(ValueError, match="cutoff"):
        DistanceHighpass(0.5)
    with pytest.raises(ValueError, match="decrease"):
        highpass_profile(np.array([0.0, 1.0, 0.5]), np.zeros(3))


def test_road_scores_are_against_the_profile():
    """metrics.road_scores scores against reference_profile of the truth: the profile itself scores
    0; a level, a grade or a vertical curve added to the truth changes nothing; white noise on the
    estimate stays."""
    t = np.arange(1, 40001) * 1e-3
    d = 20.0 * t
    truth = 0.02 * np.sin(2 * np.pi * d / 30.0) + 0.005 * np.sin(2 * np.pi * d / 7.0)
    est = reference_profile(d, truth)
    assert road_scores(t, est, truth, distance=d)["rmse_raw_mm"] == 0.0
    curved = truth + 0.5 + 0.01 * d + 0.5 * d * d / 3000.0
    assert road_scores(t, est, curved, distance=d)["rmse_raw_mm"] < 0.05  # the transient from rest, decaying
    noise = 1e-3 * np.random.default_rng(1).standard_normal(len(t))
    assert road_scores(t, est + noise, truth, distance=d)["rmse_raw_mm"] == pytest.approx(1.0, rel=0.05)
    assert np.allclose(reference_profile(d, truth), highpass_profile(d, truth))


def test_a_vertical_curve_is_a_pair_of_accelerometer_biases():
    """Why the high-pass is of third order: on a sag curve of radius R at speed v the car
    accelerates at a = v^2 / R, body and wheel alike, and its spring holds the body with a
    deflection of -m_s a / k_s. Its noise-free measurements are those of the same car on a flat
    road with accelerometer biases of a and a deflection offset of -m_s a / k_s, once the start's
    transient has died out: no estimator can tell the two apart, so the profile must give the
    curve nothing (a second-order high-pass gives it a / (v w)^2, 172 mm at 40 km/h for 0.1 m/s^2)."""
    from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
    from suspension_estimation.plant.sensors import SensorErrors
    from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE as veh

    v, a, h = 40 / 3.6, 0.1, 1e-3
    quiet = SensorNoise(0.0, 0.0, 0.0)
    # accelerations averaged over the step (exact for the plant's held road; sampled at the end
    # of the step the wheel's would carry k_t / m_u times the held road's lag, v_r h / 2)
    curve = QuarterCar(veh, quiet, acc_sampling=1)
    flat = QuarterCar(veh, quiet, acc_sampling=1, errors=SensorErrors(acc_sprung_bias=a, acc_unsprung_bias=a,
                                                       deflection_offset=-veh.m_s * a / veh.k_s))
    curve.settle(0.0)
    flat.settle(0.0)
    gap = []
    for k in range(1, 15001):
        curve.step(0.5 * a * (k * h) ** 2, h)
        flat.step(0.0, h)
        gap.append(np.subtract(curve.measured, flat.measured))
    gap = np.abs(np.array(gap)[10000:]).max(axis=0)
    assert np.all(gap < [1e-6 * a, 1e-3 * a, 1e-9])
    s = np.arange(0.0, 3000.0, 0.1)
    y = highpass_profile(s, 0.5 * a * (s / v) ** 2)  # the curve, in distance
    assert np.abs(y[s > 1500]).max() < 1e-6