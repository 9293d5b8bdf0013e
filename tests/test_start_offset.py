"""The estimate of the road height the car started on (estimators/start_offset.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from suspension_estimation.estimators.model import iso_road_height_std, reference_step_response
from suspension_estimation.estimators.start_offset import SAMPLE_INTERVAL, StartOffset
from suspension_estimation.estimators.suspension import SuspensionEstimator
from suspension_estimation.harness.metrics import road_scores
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

F_REF, V = 0.01, 40 / 3.6


def _surrogate_draws(n_draws: int, n: int, s0: float, s: float, rng: np.random.Generator):
    """Samples of x = r + d - g b from the filter's own model: r OU with r(0) = b ~ N(0, s0^2),
    d stationary OU of variance s^2, at the filter's sample times."""
    dt = SAMPLE_INTERVAL
    t = dt * np.arange(1, n + 1)
    fr = math.exp(-dt * math.pi ** 2 * iso8608.N_MIN * V)
    fd = math.exp(-dt * 2 * math.pi * F_REF)
    b = s0 * rng.standard_normal(n_draws)
    r, d = b.copy(), s * rng.standard_normal(n_draws)
    x, dd = np.empty((n_draws, n)), np.empty((n_draws, n))
    for k in range(n):
        r = fr * r + s0 * math.sqrt(1 - fr * fr) * rng.standard_normal(n_draws)
        d = fd * d + s * math.sqrt(1 - fd * fd) * rng.standard_normal(n_draws)
        x[:, k] = r + d - reference_step_response(t[k]) * b
        dd[:, k] = d
    return t, x, b, dd


def test_start_offset_is_calibrated_on_its_own_model():
    """On data drawn from its own model the filter's P_bb is the variance of b - b^ and
    s^2 + g^2 P_bb - 2 g P_db that of the corrected error d - g (b - b^); after 20 s P_bb is
    well below the prior s0^2."""
    rng = np.random.default_rng(3)
    s0, s, n = 0.03, 0.006, 400  # ISO D height std, the filter's raw error, 20 s
    t, x, b, d = _surrogate_draws(600, n, s0, s, rng)
    g = reference_step_response(t[-1])
    est, err = np.empty(len(b)), np.empty(len(b))
    for i in range(len(b)):
        f = StartOffset(iso8608.N_MIN, F_REF, s0, d0_var=s * s)
        for k in range(n):
            f.add(t[k], x[i, k], V, s * s, reference_step_response(t[k]), s0)
        est[i] = f.b
        err[i] = d[i, -1] - g * (b[i] - f.b)
    assert np.var(b - est) == pytest.approx(f.P[2][2], rel=0.2)
    assert np.var(err) == pytest.approx(s * s + f.start_variance(g), rel=0.2)
    assert f.P[2][2] < 0.5 * s0 ** 2


def test_a_new_class_reruns_the_filter_from_the_start():
    """A change of sigma_0 (the assumed class) gives the estimate of a filter that had the new
    prior from the start, exactly."""
    rng = np.random.default_rng(5)
    t, x, _, _ = _surrogate_draws(1, 200, 0.03, 0.006, rng)
    a, b = StartOffset(iso8608.N_MIN, F_REF, 0.015), StartOffset(iso8608.N_MIN, F_REF, 0.03)
    for k in range(200):
        g, s2 = reference_step_response(t[k]), 0.006 ** 2 * min(1.0, t[k] / 5)
        a.add(t[k], x[0, k], V, s2, g, 0.015 if k < 120 else 0.03)
        b.add(t[k], x[0, k], V, s2, g, 0.03)
    # the filter itself is exact; the reported b^ blends the re-run's change in (test_continuity)
    assert a.x == b.x and a.P == b.P


def _run(seed: int, T: float, **kw):
    road = SyntheticRoad(iso8608.class_psd_n0(4), seed=seed)
    car = QuarterCar(DEFAULT_VEHICLE, SensorNoise(0.02, 0.2, 1e-4), noise_seed=1000 + seed)
    car.settle(road.height(0.0))
    est = SuspensionEstimator(mass_estimator=0, **kw)
    h = 1e-3
    n = int(round(T / h))
    out = np.empty((n, 6))
    for k in range(n):
        r = road.height(V * (k + 1) * h)
        car.step(r, h)
        o = est.step(*car.measured, V, h)
        out[k] = (o["road_height_est"], o["road_height_std"], r, o["z_u_est"], o["tire_deflection_est"],
                  o["z_s_est"] - o["susp_deflection_est"])
    return np.arange(1, n + 1) * h, out, est, road.height(0.0)


def test_the_start_height_is_found_and_the_raw_error_drops():
    """ISO D, a start 2.8 sigma_0 below the mean road (seed 8): the estimate of z_0 is within
    3 of its standard deviations of the truth, far inside the prior; the raw error over 10-40 s
    is well below that of the default estimate (relative to the start level, not the mean road),
    and road_height_std still covers it. The
    shift is common to body, wheel and road: the deflections are unchanged."""
    t, on, est, z0 = _run(8, 40.0, start_offset=True)
    _, off, _, _ = _run(8, 40.0)  # the default: relative to the start level
    s0 = iso_road_height_std(iso8608.class_psd_n0(4))
    assert z0 < -2.5 * s0
    f = est._offset
    assert abs(f.b - z0) < 3 * math.sqrt(f.P[2][2]) and f.P[2][2] < 0.5 * s0 ** 2
    a = road_scores(t, on[:, 0], on[:, 2], on[:, 1], reference=False)  # against the absolute road
    b = road_scores(t, off[:, 0], off[:, 2], off[:, 1], reference=False)
    assert a["rmse_raw_mm"] < 0.6 * b["rmse_raw_mm"], (a, b)
    assert a["coverage_2sigma"] > 0.9 > b["coverage_2sigma"], (a, b)
    assert abs(a["err_std_hp_pct"] - b["err_std_hp_pct"]) < 0.2  # the correction is slow
    np.testing.assert_allclose(on[:, 3] - on[:, 0], on[:, 4], atol=1e-12)  # tyre deflection
    np.testing.assert_allclose(on[:, 5], on[:, 3], atol=1e-12)  # z_s - suspension deflection


def test_calibration_script_refuses_bad_arguments(capsys):
    """benchmarks/std_calibration.py (run by hand): a one-line reason and exit status 2."""
    import importlib.util

    from conftest import ROOT
    spec = importlib.util.spec_from_file_location("std_calibration", ROOT / "benchmarks" / "std_calibration.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for argv in (["--classes", "9"], ["--seeds", "x"], ["--workers", "0"]):
        assert mod.main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--classes" in err
